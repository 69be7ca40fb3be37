#!/usr/bin/python3
"""``/a/thief``: the stealing vehicle of Table 5.1 (s6). While the iRobot is in the upper
half of the room (y > 0) it publishes fake platform poses on ``/a/car_pose``: the iRobot
mirrored into the lower half, to lure the UAV away and land it on the floor. It publishes at
50 Hz, faster than the driver's 20 Hz, so that most poses the controller hears are its own.
It joins the graph as a publisher of ``/a/car_pose`` when it first lures (a vehicle that comes
along, not a node the system was launched with): its registration is the fault's onset."""

from __future__ import annotations

import landing_core as core
import landing_node as node
import rospy  # type: ignore[import-not-found]
from geometry_msgs.msg import PoseStamped, TransformStamped  # type: ignore[import-not-found]

RATE = 50.0


def main() -> None:
    node.init_node("thief")
    pose: list[rospy.Publisher] = []
    vicon = node.latest("/vicon/car", TransformStamped)

    def lure(now: float) -> None:
        if "msg" in vicon:
            t = vicon["msg"].transform.translation
            if t.y > 0.0:  # its position mirrored, its heading as it is
                if not pose:
                    pose.append(rospy.Publisher("/a/car_pose", PoseStamped, queue_size=10))
                stamp = rospy.Time.from_sec(now)
                yaw = node.euler(vicon["msg"].transform.rotation)[2]
                pose[0].publish(node.pose_message(stamp, t.x, -t.y, core.PLATFORM_TOP, yaw))

    node.every(RATE, lure)


if __name__ == "__main__":
    node.run(main)
