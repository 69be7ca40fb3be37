#!/usr/bin/python3
"""The platform of the landing example: ``geometry_msgs/PoseStamped`` on ``/a/car_pose``.

Started as ``/a/car`` it publishes at ``--rate`` (20 Hz) a pose that cycles through a small
grid (x among 7 values, y among 3, z among 5, orientation the identity), so the values learnt
from a few seconds of it are all a later run shows (statistics over time windows, rates
above all, move with the timing of the messages). Faults (see ``livenode``):
``out_of_range`` publishes z = 50 m, ``silent`` stops publishing. Started under another name
(``__name:=intruder``) it is a second publisher of the topic.
"""

from __future__ import annotations

import argparse
from typing import TYPE_CHECKING

import rospy  # type: ignore[import-not-found]
from geometry_msgs.msg import PoseStamped  # type: ignore[import-not-found]

if TYPE_CHECKING:  # mypy sees this folder as a namespace package
    from tests.live.nodes.livenode import Connections, Faults, init_node, parse
else:  # run as a script, the folder is on sys.path
    from livenode import Connections, Faults, init_node, parse

XS = (1.0, 1.25, 1.5, 1.75, 2.0, 2.25, 2.5)
YS = (2.0, 1.75, 1.5)
ZS = (0.1, 0.12, 0.14, 0.16, 0.18)
BAD_Z = 50.0


def options(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--topic", default="/a/car_pose")
    parser.add_argument("--rate", type=float, default=20.0)


def main() -> None:
    args = parse(__doc__ or "", options)
    init_node("car")
    faults = Faults(args)
    publisher = rospy.Publisher(
        args.topic, PoseStamped, subscriber_listener=Connections(), queue_size=10
    )
    rate = rospy.Rate(args.rate)
    k = 0
    while not rospy.is_shutdown():
        state = faults.next()
        if state != "silent":
            message = PoseStamped()
            message.header.stamp = rospy.Time.now()
            message.header.frame_id = "world"
            position = message.pose.position
            position.x, position.y, position.z = XS[k % 7], YS[k % 3], ZS[k % 5]
            if state == "bad":
                position.z = BAD_Z
            message.pose.orientation.w = 1.0
            publisher.publish(message)
            k += 1
        try:
            rate.sleep()
        except rospy.ROSInterruptException:
            break


if __name__ == "__main__":
    main()
