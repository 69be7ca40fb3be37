"""Backends render the IR: the translator plan and inference job, and the ROS 1 / ROS 2 monitors."""
