"""What monitors and recorders decide without ROS: the middleware-neutral robot-side code.

Both monitor backends copy this package, unchanged and under this name, into every package
they render, beside ``imrosc/runtime`` (the engine) and their middleware adapters, which
are its subpackages (``monitor_ros1``: rospy; ``monitor_ros2``: rclpy; ``record_ros1`` and
``record_ros2``: the recorders ``imrosc record`` runs, the ROS 2 one with its bag tap), so
relative imports (``from ..runtime import families``, in an adapter ``from .. import
monitor``) work alike in imrosc and in a generated package.

* :mod:`.monitor`: what a monitor node decides (alarms, actions, warnings, the graph with
  the relays folded back, filling an action's message) and the package's files;
* :mod:`.flat`: the helpers of the generated flatteners;
* :mod:`.records`: the record format's encoder (``docs/record-format.md``), the one both
  recorders and :mod:`imrosc.records` write with.
* :mod:`.service_pool`: pooled persistent connections to a ROS 1 service (rospy passed
  in), through which the ROS 1 recorder and monitor both forward the calls they relay.

Python 3.8 syntax, numpy and the standard library only (and ``..runtime``; the adapters
besides rospy or rclpy): a ROS Noetic robot runs it unchanged.
"""
