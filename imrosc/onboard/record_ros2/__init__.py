"""imrosc's ROS 2 recorder: an rclpy node that publishes the record topics.

``logic`` holds what it decides without rclpy (record encoding, change detection, pairing
service introspection events into call records); ``node`` is the rclpy node. Both are
copied into the ROS 2 package the ``ros2`` backend renders (Python 3.8 syntax).
"""
