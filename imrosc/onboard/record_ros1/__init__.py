"""imrosc's ROS 1 recorder: a rospy node that relays the scope's services and publishes the
record topics (``node``; ``imrosc record`` runs ``python -m imrosc.onboard.record_ros1.node
SPEC`` under the robot's Python, beside ``rosbag record``). Python 3.8 syntax, the standard
library and rospy.
"""
