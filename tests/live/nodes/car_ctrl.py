#!/usr/bin/python3
"""The controller of the landing example: reads ``/a/car_pose``, commands a state.

Started as ``/a/car_ctrl`` it publishes ``std_msgs/UInt8`` on ``/a/cmd_subject_ctrl_state`` at
``--rate`` (5 Hz): 3 (task) in nominal operation. It sets its parameters
(``~landing_radius``, ``~landing_time``, ``~poll_rate``) when the launch file did not. Faults
(see ``livenode``): ``out_of_range`` commands state 9 (there are six states, 0-5), ``silent``
stops publishing.
"""

from __future__ import annotations

import argparse
from typing import TYPE_CHECKING, Any

import rospy  # type: ignore[import-not-found]
from geometry_msgs.msg import PoseStamped  # type: ignore[import-not-found]

if TYPE_CHECKING:  # mypy sees this folder as a namespace package
    from tests.live.nodes.livenode import Connections, Faults, init_node, parse
else:  # run as a script, the folder is on sys.path
    from livenode import Connections, Faults, init_node, parse
from std_msgs.msg import UInt8  # type: ignore[import-not-found]

TASK = 3
BAD_STATE = 9
DEFAULTS = {"landing_radius": 0.5, "landing_time": 1.5, "poll_rate": 2.0}


def options(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--rate", type=float, default=5.0)


def main() -> None:
    args = parse(__doc__ or "", options)
    init_node("car_ctrl")
    for name, value in DEFAULTS.items():
        if not rospy.has_param("~" + name):
            rospy.set_param("~" + name, value)
    poses = {"count": 0}

    def on_pose(_message: Any) -> None:
        poses["count"] += 1

    rospy.Subscriber("/a/car_pose", PoseStamped, on_pose, queue_size=10)
    faults = Faults(args)
    publisher = rospy.Publisher(
        "/a/cmd_subject_ctrl_state", UInt8, subscriber_listener=Connections(), queue_size=10
    )
    rate = rospy.Rate(args.rate)
    while not rospy.is_shutdown():
        state = faults.next()
        if state != "silent":
            publisher.publish(UInt8(data=BAD_STATE if state == "bad" else TASK))
        try:
            rate.sleep()
        except rospy.ROSInterruptException:
            break


if __name__ == "__main__":
    main()
