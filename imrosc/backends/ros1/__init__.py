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
  (``imrosc/monitor_ros1``), so the robot needs no pip install;
* ``config/invariants.json``: a copy of the ``<monitor>``'s invariants file;
* ``launch/<project>_monitor.launch`` and, with ``<monitor launch="...">``,
  ``launch/system_monitored.launch``: the system's launch file rewritten
  (:mod:`imrosc.backends.launch`).

Every file names the generator, its version and the source config. The templates
(``templates/*.j2``) only format a :class:`~imrosc.backends.monitor.MonitorSpec`; each name or
literal from the configuration or the invariants file is rendered through a quoting filter
(``py``: a Python literal, JSON for a string and ``repr`` for a number; ``hash_comment``
and ``xml_comment``: escaped comment text that cannot end its comment; XML text and
attributes autoescaped), and field paths, the only text that becomes code, are checked to
be field names first (:mod:`imrosc.backends.monitor`). ``docs/monitor.md`` describes the
package and the node.
"""

from __future__ import annotations

import re
import textwrap
from typing import Any

from jinja2 import Environment

from imrosc import __version__
from imrosc.backends import quoting
from imrosc.backends.monitor import (
    MonitorSpec,
    dumps,
    flattener_helpers,
    invariants_copy,
    monitor_spec,
    system_launch,
)
from imrosc.backends.quoting import hash_comment, py_literal, xml_comment_filter
from imrosc.backends.registry import BuildInputs, Executable, register
from imrosc.backends.vendor import vendored
from imrosc.onboard.monitor import WARM

BACKEND = "ros1"
SYSTEM_LAUNCH = "launch/system_monitored.launch"
PACKAGE_DIR = "scripts/imrosc_monitor"
"""The Python package of the node scripts (the folder ``scripts/`` is on their path)."""
ADAPTERS = ("monitor_ros1",)
"""The middleware adapters the package carries besides :data:`~imrosc.backends.vendor.ONBOARD`."""
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
__all__ = ["hash_comment", "py_literal", "render_package", "xml_comment_filter"]

_CMAKE_NAME = re.compile(r"[A-Za-z_][A-Za-z0-9_]*")
_VERSION = re.compile(r"[0-9]+\.[0-9]+\.[0-9]+")


def cmake_name(text: Any) -> str:
    """A CMake word that needs no quoting (package and script names are checked before)."""
    if not isinstance(text, str) or not _CMAKE_NAME.fullmatch(text):
        raise ValueError(f"{text!r} is not a plain CMake name")
    return text


def environment() -> Environment:
    """The template environment: strict, XML autoescaped, with the quoting filters."""
    env = quoting.environment("imrosc.backends.ros1", ("xml.j2", "launch.j2"))
    env.filters["cmake_name"] = cmake_name
    return env


def render_package(spec: MonitorSpec, banner: str) -> dict[str, bytes]:
    """The files of the package (paths relative to the package folder)."""
    env = environment()
    version = __version__ if _VERSION.fullmatch(__version__) else "0.0.0"
    flattened = [t for t in spec.topics if t.flattener is not None]
    docstring = textwrap.fill(PACKAGE_DOCSTRING.format(package=spec.package), 92)

    def render(template: str, **extra: Any) -> bytes:
        context = {"spec": spec, "banner": banner, **extra}
        return env.get_template(template).render(**context).encode("utf-8")

    files: dict[str, bytes] = {
        "package.xml": render(
            "package.xml.j2", version=version, depends=sorted({*EXEC_DEPENDS, *spec.depends})
        ),
        "CMakeLists.txt": render("CMakeLists.txt.j2"),
        f"scripts/{spec.node}": Executable(render("node.py.j2")),
        f"scripts/{spec.watchdog}": Executable(render("watchdog.py.j2")),
        f"{PACKAGE_DIR}/__init__.py": render("init.py.j2", docstring=docstring),
        f"{PACKAGE_DIR}/flatteners.py": render(
            "flatteners.py.j2", topics=flattened, helpers=flattener_helpers(spec)
        ),
        f"{PACKAGE_DIR}/spec.json": dumps(spec.runtime_document(banner)),
        spec.invariants_path: invariants_copy(spec, banner),
        f"launch/{spec.package}.launch": render("monitor.launch.j2", warm=WARM),
    }
    files.update(vendored(PACKAGE_DIR, BACKEND, ADAPTERS))
    return dict(sorted(files.items()))


def rewrite_system_launch(inputs: BuildInputs, spec: MonitorSpec, banner: str) -> dict[str, bytes]:
    """``launch/system_monitored.launch`` when the ``<monitor>`` names a launch file."""
    if spec.launch is None or inputs.project.monitor is None:
        return {}
    return system_launch(
        inputs,
        spec,
        banner,
        flavour=BACKEND,
        source=spec.launch,
        included=f"{spec.package}.launch",
        target=SYSTEM_LAUNCH,
    )


@register(BACKEND, monitor=True)
def render(inputs: BuildInputs) -> dict[str, bytes]:
    """The monitor package, each path under ``<package>/``."""
    spec = monitor_spec(inputs)
    if spec is None:
        return {}
    banner = inputs.banner(BACKEND)
    files = render_package(spec, banner)
    files.update(rewrite_system_launch(inputs, spec, banner))
    return {f"{spec.package}/{name}": content for name, content in sorted(files.items())}
