#!/usr/bin/python3
"""``/a/thief``: the stealing vehicle of Table 5.1 (s6). While the iRobot is in the upper
half of the room (y > 0) it publishes fake platform poses on ``/a/car_pose`` (20 Hz): the
iRobot mirrored into the lower half, to lure the UAV away and land it on the floor."""

from __future__ import annotations

import contextlib

import landing_core as core
import landing_node as node
import rospy  # type: ignore[import-not-found]
from geometry_msgs.msg import PoseStamped, TransformStamped  # type: ignore[import-not-found]


def main() -> None:
    rospy.init_node("thief")
    pose = rospy.Publisher("/a/car_pose", PoseStamped, queue_size=10)
    latest: dict[str, TransformStamped] = {}
    rospy.Subscriber("/vicon/car", TransformStamped, lambda m: latest.update(pose=m), queue_size=1)
    node.wait_for_clock()
    rate = rospy.Rate(20.0)
    while not rospy.is_shutdown():
        if "pose" in latest:
            t = latest["pose"].transform.translation
            if t.y > 0.0:
                pose.publish(
                    node.pose_message(
                        rospy.Time.from_sec(rospy.get_time()), t.x, -t.y, core.PLATFORM_TOP
                    )
                )
        with contextlib.suppress(rospy.ROSTimeMovedBackwardsException):
            rate.sleep()


if __name__ == "__main__":
    with contextlib.suppress(rospy.ROSInterruptException):
        main()
