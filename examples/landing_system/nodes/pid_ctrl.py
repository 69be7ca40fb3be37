#!/usr/bin/python3
"""``/a/pid_ctrl``: the UAV's position loop (:class:`landing_core.Attitude`). From the waypoint
(``/a/task_waypose``), the UAV's pose (``/a/subject_pose``) and the control state
(``/a/subject_ctrl_state``) it commands roll, pitch and thrust on ``/a/cmd_attitude``
(``geometry_msgs/Twist``, 50 Hz; motors off in startup and shutdown). The waypoint's velocity
is fed forward while waypoints come; without one for 0.3 s (none sent, or a monitor withholds
them) the held waypoint is a point at rest, and after 0.5 s the loop holds the UAV where it
is."""

from __future__ import annotations

import threading

import landing_core as core
import landing_node as node
import rospy  # type: ignore[import-not-found]
from geometry_msgs.msg import PoseStamped, Twist  # type: ignore[import-not-found]
from std_msgs.msg import UInt8  # type: ignore[import-not-found]


def main() -> None:
    node.init_node("pid_ctrl")
    loop = core.Attitude()
    lock = threading.Lock()
    held: dict[str, object] = {"state": core.STARTUP}
    out = rospy.Publisher("/a/cmd_attitude", Twist, queue_size=1)

    def on_waypoint(msg: PoseStamped) -> None:
        p = msg.pose.position
        with lock:
            loop.see_waypoint(rospy.get_time(), p.x, p.y, p.z)
            held["waypoint"] = (p.x, p.y, p.z, rospy.get_time())

    def on_pose(msg: PoseStamped) -> None:
        p = msg.pose.position
        now = rospy.get_time()
        with lock:
            last = held.get("pose")
            velocity = held.get("velocity", (0.0, 0.0, 0.0))
            if isinstance(last, tuple) and now > last[3]:
                dt = now - last[3]
                raw = ((p.x - last[0]) / dt, (p.y - last[1]) / dt, (p.z - last[2]) / dt)
                velocity = tuple(0.6 * v + 0.4 * r for v, r in zip(velocity, raw, strict=False))  # type: ignore[arg-type]
            held["pose"] = (p.x, p.y, p.z, now)
            held["velocity"] = velocity

    rospy.Subscriber("/a/task_waypose", PoseStamped, on_waypoint, queue_size=1)
    rospy.Subscriber("/a/subject_pose", PoseStamped, on_pose, queue_size=1)
    rospy.Subscriber("/a/subject_ctrl_state", UInt8, lambda m: held.update(state=m.data))

    def control(now: float) -> None:
        with lock:
            pose = held.get("pose")
            point = held.get("waypoint")
            goal = None
            if isinstance(point, tuple) and now - point[3] < 0.5:
                goal = point[:3]
            elif isinstance(pose, tuple):
                goal = pose[:3]  # no fresh waypoint: hold where it is
            cmd = core.Command()
            if isinstance(pose, tuple):
                cmd = loop.command(
                    int(held["state"]),
                    goal,
                    pose[:3],
                    held["velocity"],
                    now,  # type: ignore[arg-type]
                )
        msg = Twist()
        msg.angular.x, msg.angular.y = cmd.roll, cmd.pitch
        msg.linear.z, msg.linear.x = cmd.thrust, 1.0 if cmd.motors else 0.0
        out.publish(msg)

    node.every(50.0, control)


if __name__ == "__main__":
    node.run(main)
