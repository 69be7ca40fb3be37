#!/usr/bin/python3
"""``/a/car``: the iRobot's driver. Forwards its motion-capture pose (``/vicon/car``) as
``/a/car_pose`` (``geometry_msgs/PoseStamped``, 20 Hz) and serves ``/a/execute_task``
(``landing_system/ExecuteTask``), passing the task to the platform (``/a/car_drive``).

Faults of Table 5.1 that live here:

* ``slowed`` (s5): for 5 s in every 10 s the pose goes out at 0.5 Hz;
* ``false_airport`` (s7): there is no vehicle, and the pose it sends is a fixed, wrong one
  (seeded, in the room).
"""

from __future__ import annotations

import random

import landing_core as core
import landing_node as node
import rospy  # type: ignore[import-not-found]
from geometry_msgs.msg import PoseStamped, TransformStamped  # type: ignore[import-not-found]
from landing_system.srv import ExecuteTask, ExecuteTaskResponse  # type: ignore[import-not-found]
from std_msgs.msg import UInt8  # type: ignore[import-not-found]

RATE = 20.0


def main() -> None:
    node.init_node("car")
    name = node.scenario()
    rng = random.Random(node.seed() + 17)
    fake = (rng.uniform(-2.5, 2.5), rng.uniform(-2.5, 2.5))
    pose = rospy.Publisher("/a/car_pose", PoseStamped, queue_size=10)
    drive = rospy.Publisher("/a/car_drive", UInt8, queue_size=10)
    vicon = node.latest("/vicon/car", TransformStamped)
    slow_last = [-1e9]

    def on_task(request: ExecuteTask) -> ExecuteTaskResponse:
        drive.publish(UInt8(request.task_id))
        return ExecuteTaskResponse("ok")

    def send(now: float) -> None:
        if name == "false_airport":
            pose.publish(node.pose_message(rospy.Time.from_sec(now), *fake, core.PLATFORM_TOP))
        elif "msg" in vicon:
            slowed = name == "slowed" and (now % 10.0) >= 5.0
            if not slowed or now - slow_last[0] >= 2.0:
                slow_last[0] = now
                pose.publish(node.pose_of_transform(vicon["msg"]))

    rospy.Service("/a/execute_task", ExecuteTask, on_task)
    node.every(RATE, send)


if __name__ == "__main__":
    node.run(main)
