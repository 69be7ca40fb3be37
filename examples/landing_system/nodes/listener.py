#!/usr/bin/python3
"""A node of Figure 3.6 whose work is outside the simulation (``/a/launch_ctrl``,
``/a/ctrl_input_arb``): it subscribes to ``/a/subject_ctrl_state`` and keeps its last value."""

from __future__ import annotations

import rospy  # type: ignore[import-not-found]
from std_msgs.msg import UInt8  # type: ignore[import-not-found]


def main() -> None:
    rospy.init_node("listener")
    rospy.Subscriber("/a/subject_ctrl_state", UInt8, lambda m: None, queue_size=1)
    rospy.spin()


if __name__ == "__main__":
    main()
