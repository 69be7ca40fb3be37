"""``imrosc record``: trace generation on ROS 1 and ROS 2 (thesis section 3.2).

rosbag records topics only. ``imrosc record`` runs ``rosbag record`` on the topics of a
configuration's scope together with imrosc's recording node (:mod:`imrosc.onboard.record_ros1`,
a rospy node run under the robot's Python), which adds what rosbag misses, as the records of
``docs/record-format.md``: the node graph (``/imrosc/arch``), the parameters
(``/imrosc/params``) and every call of the scope's services (``/imrosc/srvs``), relayed
through the recorder from servers remapped to ``/rec/<srv>`` (Figure 3.4).

* :mod:`imrosc.record.scope`: what a configuration needs recorded;
* :mod:`imrosc.record.master`: the master over XML-RPC (is there one, what is its graph);
* :mod:`imrosc.record.launch`: the launch-file copy with the servers remapped;
* :mod:`imrosc.record.session`: starting and stopping rosbag and the node in order;
* :mod:`imrosc.record.command`: the command line.

On ROS 2 (``--ros2``) rosbag2 is not needed: the bag tap (:mod:`imrosc.onboard.record_ros2.tap`,
an rclpy node under the ROS 2 Python) sends every message of the scope's topics to imrosc,
which writes the MCAP bag as they come (:mod:`imrosc.record.mcap`), while the ROS 2
recorder node (:mod:`imrosc.onboard.record_ros2`) publishes the records, service calls from service
introspection:

* :mod:`imrosc.record.session_ros2`: starting and stopping the tap and the recorder, the
  bag written from the tap's frames;
* :mod:`imrosc.record.command_ros2`: the command line's ROS 2 half.
"""
