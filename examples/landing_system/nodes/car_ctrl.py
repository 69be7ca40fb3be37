#!/usr/bin/python3
"""``/a/car_ctrl``: the landing controller of Figure 3.6 (:class:`landing_core.LandingController`).

Runs at 20 Hz on ``/a/car_pose``, ``/a/subject_pose`` and ``/a/subject_ctrl_state``;
publishes the state command on ``/a/cmd_subject_ctrl_state`` (``std_msgs/UInt8``, on a change
and at 5 Hz) and the waypoint on ``/a/task_waypose`` (``geometry_msgs/PoseStamped``, 20 Hz),
calls ``/a/execute_task`` when the task changes, and serves ``/a/poll_status``. Its
parameters: ``~landing_radius`` (0.15 m), ``~landing_time`` (1.5 s), ``~poll_rate`` (2 Hz).
A state reported by the state machine that it did not command (the monitor's task command
during a landing) calls the landing off: it tells the platform it tracks it again
(``/a/execute_task``, task 1: a platform stopped at the touchdown drives on) and pursues it;
called off low (on a surface or within 0.3 m of the platform's markers) it first goes
around, climbing straight up to its pursuit height, and tells the platform only then.
"""

from __future__ import annotations

import threading

import landing_core as core
import landing_node as node
import rospy  # type: ignore[import-not-found]
from geometry_msgs.msg import PoseStamped  # type: ignore[import-not-found]
from landing_system.srv import (  # type: ignore[import-not-found]
    ExecuteTask,
    PollStatus,
    PollStatusResponse,
)
from std_msgs.msg import UInt8  # type: ignore[import-not-found]

DEFAULTS = {"landing_radius": 0.15, "landing_time": 1.5, "poll_rate": 2.0}


def main() -> None:
    node.init_node("car_ctrl")
    for name, value in DEFAULTS.items():
        if not rospy.has_param("~" + name):
            rospy.set_param("~" + name, value)
    control = core.LandingController(
        landing_radius=float(rospy.get_param("~landing_radius")),
        landing_time=float(rospy.get_param("~landing_time")),
    )
    lock = threading.Lock()
    seen: dict[str, float] = {"state": core.STARTUP}
    uav: dict[str, tuple[float, float, float, float]] = {}
    command = rospy.Publisher("/a/cmd_subject_ctrl_state", UInt8, queue_size=10)
    waypoint = rospy.Publisher("/a/task_waypose", PoseStamped, queue_size=10)

    def on_car(msg: PoseStamped) -> None:
        p = msg.pose.position
        yaw = node.euler(msg.pose.orientation)[2]
        with lock:
            control.see_car(rospy.get_time(), p.x, p.y, p.z, yaw)

    def on_uav(msg: PoseStamped) -> None:
        # the climb rate from the poses' own stamps: /a/uav forwards the latest motion-capture
        # pose at its rate, so a pose may come again (a busy graph): no new measurement, and
        # taking it for one would read a standstill, a touchdown, in mid-air
        p = msg.pose.position
        now = msg.header.stamp.to_sec()
        with lock:
            last = uav.get("pose")
            if last is not None and now <= last[3]:
                return
            vz = uav.get("vz", (0.0,))[0]
            if last is not None:
                vz = 0.7 * vz + 0.3 * (p.z - last[2]) / (now - last[3])
            uav["pose"] = (p.x, p.y, p.z, now)
            uav["vz"] = (vz, 0.0, 0.0, 0.0)

    def on_state(msg: UInt8) -> None:
        seen["state"] = msg.data

    def on_poll(_request: object) -> PollStatusResponse:
        return PollStatusResponse(control.commanded, "ok")

    rospy.Subscriber("/a/car_pose", PoseStamped, on_car, queue_size=10)
    rospy.Subscriber("/a/subject_pose", PoseStamped, on_uav, queue_size=1)
    rospy.Subscriber("/a/subject_ctrl_state", UInt8, on_state, queue_size=10)
    rospy.Service("/a/poll_status", PollStatus, on_poll)
    execute = rospy.ServiceProxy("/a/execute_task", ExecuteTask)
    sent = {"cycle": 0, "state": -1}

    def cycle(now: float) -> None:
        with lock:
            pose = uav.get("pose")
            if pose is not None:
                state, goal, task = control.step(now, int(seen["state"]), pose[:3], uav["vz"][0])
            else:
                state, goal, task = control.commanded, None, None
        if state != sent["state"] or sent["cycle"] % 4 == 0:
            command.publish(UInt8(state))
            sent["state"] = state
        if goal is not None:
            waypoint.publish(node.pose_message(rospy.Time.from_sec(now), *goal))
        if task is not None:
            try:
                execute.call(task)
            except (rospy.ServiceException, rospy.ROSException) as error:
                rospy.logwarn("execute_task %d failed: %s", task, error)
        sent["cycle"] += 1

    node.every(20.0, cycle)


if __name__ == "__main__":
    node.run(main)
