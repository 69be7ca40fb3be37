"""imrosc: infer likely invariants of a ROS robot from bags and synthesize a monitor node."""

__version__ = "0.1.0"
