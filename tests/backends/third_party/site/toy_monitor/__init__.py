"""Backend ``toy_monitor``: a monitor backend as another package would add one.

Its whole addition is this package (the module, its ``templates/``) and one entry point in
the distribution's metadata (``[imrosc.backends] toy_monitor = toy_monitor``; from a
pyproject.toml: ``[project.entry-points."imrosc.backends"]``). The base class gives it the
spec, the shared flatteners template, the vendored copies of imrosc and the launch
rewriting; it names its templates, its adapter and its launch dialect, and lists its files.
"""

from __future__ import annotations

from imrosc.backends import launch
from imrosc.backends.monitor import MonitorSpec, dumps, invariants_copy
from imrosc.backends.monitor_backend import MonitorBackend
from imrosc.backends.registry import BuildInputs, register


class ToyMonitor(MonitorBackend):
    """A folder with the rclpy adapter's monitor data and a notes file, no build files."""

    name = "toy_monitor"
    templates = "toy_monitor"
    autoescaped = ("xml.j2",)
    adapters = ("onboard.monitor_ros2",)
    launch_dialect = launch.ROS2_LAUNCH
    launch_extension = ".launch.xml"
    message_type = "ros2_type"

    def package_files(
        self, inputs: BuildInputs, spec: MonitorSpec, banner: str, system_launch: tuple[str, ...]
    ) -> dict[str, bytes]:
        render = self.renderer(spec, banner)
        files = {
            "NOTES.txt": render("notes.txt.j2"),
            "toy/flatteners.py": self.flatteners(render, spec),
            "toy/spec.json": dumps(spec.runtime_document(banner)),
            spec.invariants_path: invariants_copy(spec, banner),
        }
        files.update(self.vendored("toy"))
        return files


register(ToyMonitor.name, monitor=True)(ToyMonitor())
