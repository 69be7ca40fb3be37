#!/usr/bin/python3
"""``/a/uav``: the UAV's pose as its onboard side sees it: ``/vicon/uav`` forwarded as
``/a/subject_pose`` (``geometry_msgs/PoseStamped``, 50 Hz)."""

from __future__ import annotations

import landing_node as node
import rospy  # type: ignore[import-not-found]
from geometry_msgs.msg import PoseStamped, TransformStamped  # type: ignore[import-not-found]


def main() -> None:
    node.init_node("uav")
    pose = rospy.Publisher("/a/subject_pose", PoseStamped, queue_size=10)
    vicon = node.latest("/vicon/uav", TransformStamped)

    def forward(_now: float) -> None:
        if "msg" in vicon:
            pose.publish(node.pose_of_transform(vicon["msg"]))

    node.every(50.0, forward)


if __name__ == "__main__":
    node.run(main)
