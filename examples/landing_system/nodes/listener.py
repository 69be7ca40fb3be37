#!/usr/bin/python3
"""A node of Figure 3.6 whose work is outside the simulation (``/a/launch_ctrl``,
``/a/ctrl_input_arb``): it subscribes to ``/a/subject_ctrl_state``. With ``~poll`` true it
also polls the controller's status (``/a/poll_status``) at ``/a/car_ctrl/poll_rate``."""

from __future__ import annotations

import landing_node as node
import rospy  # type: ignore[import-not-found]
from landing_system.srv import PollStatus  # type: ignore[import-not-found]
from std_msgs.msg import UInt8  # type: ignore[import-not-found]


def main() -> None:
    node.init_node("listener")
    rospy.Subscriber("/a/subject_ctrl_state", UInt8, lambda m: None, queue_size=1)
    if not rospy.get_param("~poll", False):
        rospy.spin()
        return
    poll = rospy.ServiceProxy("/a/poll_status", PollStatus)

    def ask(_now: float) -> None:
        try:
            poll.call()
        except (rospy.ServiceException, rospy.ROSException) as error:
            rospy.logdebug("poll_status: %s", error)

    node.every(float(rospy.get_param("/a/car_ctrl/poll_rate", 2.0)), ask)


if __name__ == "__main__":
    node.run(main)
