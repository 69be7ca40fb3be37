#!/usr/bin/python3
"""``/a/robot_monitor``: the UAV's battery (``/a/subject_status``,
``sensor_msgs/BatteryState``, 10 Hz): the voltage sags with the thrust the UAV is asked for
(``/a/cmd_attitude``) and drains slowly, with a little noise."""

from __future__ import annotations

import random

import landing_core as core
import landing_node as node
import rospy  # type: ignore[import-not-found]
from geometry_msgs.msg import Twist  # type: ignore[import-not-found]
from sensor_msgs.msg import BatteryState  # type: ignore[import-not-found]


def main() -> None:
    node.init_node("robot_monitor")
    status = rospy.Publisher("/a/subject_status", BatteryState, queue_size=10)
    thrust = [0.0]
    rng = random.Random(node.seed() + 5)
    rospy.Subscriber(
        "/a/cmd_attitude",
        Twist,
        lambda m: thrust.__setitem__(0, m.linear.z if m.linear.x > 0.5 else 0.0),
        queue_size=1,
    )

    def report(now: float) -> None:
        msg = BatteryState()
        msg.header.stamp = rospy.Time.from_sec(now)
        load = thrust[0] / core.GRAVITY
        msg.voltage = 12.4 - 0.002 * now - 0.35 * load + rng.gauss(0.0, 0.01)
        msg.current = 6.0 * load + rng.gauss(0.0, 0.05)
        msg.percentage = max(0.0, 1.0 - now / 1200.0)
        msg.present = True
        status.publish(msg)

    node.every(10.0, report)


if __name__ == "__main__":
    node.run(main)
