"""Tests of ``imrosc record`` that need no ROS (the live ones are tests/live/test_record.py;
the recorder nodes' own tests are under tests/onboard/record_ros1 and record_ros2)."""
