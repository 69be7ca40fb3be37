"""The example packages the backend tests build once per module, as fixtures."""

from tests.backends.example_ros2_support import landing_example
from tests.backends.monitor_support import landing_sim
from tests.backends.ros2_build import landing_ros2

__all__ = ["landing_example", "landing_ros2", "landing_sim"]
