"""Tests of the ROS 2 side of ``imrosc record`` that need no ROS (live:
tests/backends/test_ros2_record_live.py)."""
