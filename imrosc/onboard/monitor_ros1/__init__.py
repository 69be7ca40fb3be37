"""The ROS 1 monitor adapter: the rospy half of a generated ``ros1`` monitor package.

The ``ros1`` backend copies this package, beside ``imrosc/onboard`` (every decision the node
takes, as plain functions tested without ROS; the flattener helpers) and ``imrosc/runtime``
(the engine), into ``scripts/imrosc_monitor/imrosc/`` of the package it renders, next to
the generated ``flatteners.py`` and ``spec.json``. ``node.py`` is the monitor node,
``watchdog.py`` the fail-open watchdog, ``wire.py`` reads blocked messages from their bytes
and ``interpreter.py`` re-executes a script under ROS 1's Python. Python 3.8 syntax, numpy
and the standard library besides rospy: a ROS Noetic robot runs it unchanged.
"""
