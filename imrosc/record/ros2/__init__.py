"""The ROS 2 side of ``imrosc record``: what runs under the robot's ROS 2 Python.

* :mod:`.wire`: the frames the tap sends imrosc over a pipe (events and messages), and the
  message definitions of a type with everything it uses (plain Python, read by both sides);
* :mod:`.tap`: the bag tap, an rclpy node (hidden: ``/_imrosc_bag_<pid>``) that subscribes
  to the scope's topics and the three record topics with serialized (``raw``) subscriptions
  and sends every message to imrosc as received, CDR bytes and receive time;
* :mod:`.recorder`: runs the recorder node of :mod:`imrosc.onboard.record_ros2` with the scope
  imrosc gives it.

imrosc writes the bag itself (:mod:`imrosc.record.mcap`, rosbags' ``rosbag2.Writer`` with
MCAP storage), so the ROS 2 Python needs rclpy and the message packages only. Python 3.8
syntax, the standard library and rclpy.
"""
