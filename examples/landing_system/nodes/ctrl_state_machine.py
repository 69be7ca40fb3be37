#!/usr/bin/python3
"""``/a/ctrl_state_machine``: the UAV's control state. Takes the state commands of
``/a/cmd_subject_ctrl_state`` (``std_msgs/UInt8``, 0-5; others are ignored) and reports the
current state on ``/a/subject_ctrl_state`` at 10 Hz and at once on a change."""

from __future__ import annotations

import landing_core as core
import landing_node as node
import rospy  # type: ignore[import-not-found]
from sensor_msgs.msg import BatteryState  # type: ignore[import-not-found]
from std_msgs.msg import UInt8  # type: ignore[import-not-found]


def main() -> None:
    node.init_node("ctrl_state_machine")
    state = rospy.Publisher("/a/subject_ctrl_state", UInt8, queue_size=10)
    current = [core.STARTUP]

    def on_command(msg: UInt8) -> None:
        if 0 <= msg.data < len(core.STATES) and msg.data != current[0]:
            current[0] = msg.data
            state.publish(UInt8(current[0]))

    rospy.Subscriber("/a/cmd_subject_ctrl_state", UInt8, on_command, queue_size=10)
    rospy.Subscriber("/a/subject_status", BatteryState, lambda m: None, queue_size=1)
    node.every(10.0, lambda _now: state.publish(UInt8(current[0])))


if __name__ == "__main__":
    node.run(main)
