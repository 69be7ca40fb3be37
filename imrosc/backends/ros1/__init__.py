"""Backend ``ros1``: a native catkin package that monitors the invariants live (thesis 4.3).

The package ``<project>_monitor`` (under ``-o DIR``) holds

* ``package.xml`` (format 2) and ``CMakeLists.txt`` (catkin, ``catkin_install_python``);
* ``scripts/<project>_monitor``, the node, and ``scripts/<project>_monitor_watchdog``, the
  fail-open watchdog: executable, ``#!/usr/bin/env python3``, runnable with ``rosrun`` and
  ``roslaunch`` straight from the source package;
* ``scripts/imrosc_monitor/``: the Python package of the scripts: the generated
  ``flatteners.py`` and ``spec.json`` (what the node watches and does, as data), and under
  ``imrosc/`` the parts of imrosc it carries, in imrosc's own layout, each copied unchanged
  below a banner (:func:`imrosc.backends.vendor.vendored`): the runtime engine
  (``imrosc/runtime``), the onboard logic (``imrosc/onboard``) and the rospy adapter
  (``imrosc/onboard/monitor_ros1``), so the robot needs no pip install;
* ``config/invariants.json``: a copy of the ``<monitor>``'s invariants file;
* ``launch/<project>_monitor.launch`` and, with ``<monitor launch="...">``,
  ``launch/system_monitored.launch``: the system's launch file rewritten
  (:mod:`imrosc.backends.launch`).

Every file names the generator, its version and the source config. What every monitor
package does alike (the spec, the shared ``flatteners.py`` template, the vendored copies,
the launch rewriting with :func:`imrosc.backends.launch.rewrite_ros1`) is
:class:`~imrosc.backends.monitor_backend.MonitorBackend`'s. The templates
(``templates/*.j2``) only format a :class:`~imrosc.backends.monitor.MonitorSpec`; each name
or literal from the configuration or the invariants file is rendered through a quoting
filter (:mod:`imrosc.backends.quoting`: ``py``, a Python literal, JSON for a string and
``repr`` for a number; ``hash_comment`` and ``xml_comment``, escaped comment text that
cannot end its comment; ``cmake_name``; XML text and attributes autoescaped), and field
paths, the only text that becomes code, are checked to be field names first
(:mod:`imrosc.backends.monitor`). ``docs/monitor.md`` describes the package and the node.
"""

from __future__ import annotations

import textwrap

from imrosc.backends import launch
from imrosc.backends.monitor import MonitorSpec, dumps, invariants_copy
from imrosc.backends.monitor_backend import MonitorBackend, package_version
from imrosc.backends.registry import BuildInputs, Executable, register
from imrosc.onboard.monitor import WARM

PACKAGE_DIR = "scripts/imrosc_monitor"
"""The Python package of the node scripts (the folder ``scripts/`` is on their path)."""
PACKAGE_DOCSTRING = (
    "The Python package of the imrosc monitor package {package}'s scripts: ``flatteners`` and "
    "``spec.json`` say what it watches, ``imrosc/`` holds the parts of imrosc it runs."
)
EXEC_DEPENDS = (
    "python3-numba",
    "python3-numpy",
    "rosgraph",
    "roslib",
    "rospy",
    "rosservice",
    "std_msgs",
)
"""The node's run-time dependencies (rosdep keys). ``python3-numba`` compiles the checks
(``imrosc/runtime/compiled.py``; the node runs without it, slower): its rosdep key resolves on
Debian and on Noetic's Ubuntu (focal)."""


class Ros1Monitor(MonitorBackend):
    """The catkin package of the monitor, with the rospy adapter."""

    name = "ros1"
    templates = "imrosc.backends.ros1"
    autoescaped = ("xml.j2", "launch.j2")
    adapters = ("onboard.monitor_ros1",)
    launch_dialect = launch.ROSLAUNCH
    launch_extension = ".launch"
    message_type = "ros1_type"

    def package_files(
        self, inputs: BuildInputs, spec: MonitorSpec, banner: str, system_launch: tuple[str, ...]
    ) -> dict[str, bytes]:
        """The files of the package (paths relative to the package folder)."""
        render = self.renderer(spec, banner)
        docstring = textwrap.fill(PACKAGE_DOCSTRING.format(package=spec.package), 92)
        files: dict[str, bytes] = {
            "package.xml": render(
                "package.xml.j2",
                version=package_version(),
                depends=sorted({*EXEC_DEPENDS, *spec.depends}),
            ),
            "CMakeLists.txt": render("CMakeLists.txt.j2"),
            f"scripts/{spec.node}": Executable(render("node.py.j2")),
            f"scripts/{spec.watchdog}": Executable(render("watchdog.py.j2")),
            f"{PACKAGE_DIR}/__init__.py": render("init.py.j2", docstring=docstring),
            f"{PACKAGE_DIR}/flatteners.py": self.flatteners(render, spec),
            f"{PACKAGE_DIR}/spec.json": dumps(spec.runtime_document(banner)),
            spec.invariants_path: invariants_copy(spec, banner),
            self.monitor_launch(spec): render("monitor.launch.j2", warm=WARM),
        }
        files.update(self.vendored(PACKAGE_DIR))
        return dict(sorted(files.items()))


BACKEND = Ros1Monitor()
register(BACKEND.name, monitor=True)(BACKEND)
