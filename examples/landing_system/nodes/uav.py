#!/usr/bin/python3
"""``/a/uav``: the UAV's pose as its onboard side sees it: ``/vicon/uav`` forwarded as
``/a/subject_pose`` (``geometry_msgs/PoseStamped``, 50 Hz)."""

from __future__ import annotations

import contextlib

import landing_node as node
import rospy  # type: ignore[import-not-found]
from geometry_msgs.msg import PoseStamped, TransformStamped  # type: ignore[import-not-found]


def main() -> None:
    rospy.init_node("uav")
    pose = rospy.Publisher("/a/subject_pose", PoseStamped, queue_size=10)
    latest: dict[str, TransformStamped] = {}
    rospy.Subscriber("/vicon/uav", TransformStamped, lambda m: latest.update(pose=m), queue_size=1)
    node.wait_for_clock()
    rate = rospy.Rate(50.0)
    while not rospy.is_shutdown():
        if "pose" in latest:
            pose.publish(node.pose_of_transform(latest["pose"]))
        with contextlib.suppress(rospy.ROSTimeMovedBackwardsException):
            rate.sleep()


if __name__ == "__main__":
    with contextlib.suppress(rospy.ROSInterruptException):
        main()
