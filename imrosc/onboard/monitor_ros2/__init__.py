"""The ROS 2 monitor adapter: the rclpy code a generated ``ros2`` monitor package carries.

The ``ros2`` backend copies these modules into ``<pkg>/imrosc/onboard/monitor_ros2/`` of the
ament_python package it renders, beside the middleware-neutral logic both monitor nodes
share (``imrosc/onboard``, copied to ``<pkg>/imrosc/onboard/``), a copy of the runtime
engine (``<pkg>/imrosc/runtime/``) and the generated ``flatteners.py`` and ``spec.json``.
The package mirrors imrosc's own layout, so the relative imports (``from .. import
monitor``) work both here and in the generated package.

``logic.py`` holds what the ROS 2 node decides as plain functions (tested without ROS:
QoS matching, the graph from rclpy's graph API, parameters from ``GetParameters``,
messages as values, filling an action's message), ``plumbing.py`` the rclpy helpers shared
by the node (``node.py``) and the fail-open watchdog (``watchdog.py``). Python 3.8 syntax,
numpy and the standard library besides rclpy: ROS 2 Foxy (Ubuntu 20.04) and later run it.
"""
