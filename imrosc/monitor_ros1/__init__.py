"""The ROS 1 monitor adapter: the rospy code a generated monitor package carries.

The ``ros1`` backend copies these modules into ``scripts/imrosc_monitor/`` of the package it
renders, beside its generated ``flatteners.py`` and ``spec.json`` and a copy of the runtime
engine (``scripts/imrosc_runtime/``). ``logic.py`` holds every decision as plain functions
(tested without ROS), ``flat.py`` the helpers of the generated flatteners, ``node.py`` the
monitor node and ``watchdog.py`` the fail-open watchdog (both rospy). Python 3.8 syntax,
numpy and the standard library besides rospy: a ROS Noetic robot runs it unchanged.
"""
