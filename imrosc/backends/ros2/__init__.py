"""Backend ``ros2``: a native ament_python package that monitors the invariants live.

The package ``<project>_monitor`` (under ``-o DIR``) holds

* ``package.xml`` (format 3, ``ament_python``), ``setup.py`` (the Python packages,
  ``spec.json`` as package data, the ament index marker, ``package.xml``, ``config/`` and
  ``launch/`` as data files, console scripts for the node and the watchdog) and
  ``setup.cfg`` (scripts into ``lib/<package>``, where ``ros2 run`` looks);
* ``resource/<package>``: the ament index marker (its content, the generated-file banner,
  is ignored: the index reads only its name);
* ``<package>/``: the Python package: ``main.py`` (the entry points), the generated
  ``flatteners.py`` and ``spec.json`` (what the node watches and does, as data), and under
  ``imrosc/`` the parts of imrosc it carries, in imrosc's own layout, each copied unchanged
  below a banner (:func:`imrosc.backends.vendor.vendored`, as the ``ros1`` backend does):
  the runtime engine (``imrosc/runtime``), the onboard logic (``imrosc/onboard``) and the
  rclpy adapter (``imrosc/onboard/monitor_ros2``);
* ``config/invariants.json``: a copy of the ``<monitor>``'s invariants file;
* ``launch/<package>.launch.xml`` and, with ``<monitor launch="....launch.xml">`` (or
  ``launch_ros2="....launch.xml"`` beside a roslaunch ``launch``),
  ``launch/system_monitored.launch.xml``: the system's ROS 2 launch XML rewritten
  (:func:`imrosc.backends.launch.rewrite_ros2`).

The spec is :mod:`imrosc.backends.monitor`'s and what every monitor package does alike (the
shared ``flatteners.py`` template, the vendored copies, the launch rewriting) is
:class:`~imrosc.backends.monitor_backend.MonitorBackend`'s, as for ``ros1``; so are the
quoting filters (:mod:`imrosc.backends.quoting`): every name or literal from the
configuration or the invariants file reaches Python as a JSON/``repr`` literal or a ``#``
comment, XML through autoescaping, and field paths, the only text that becomes code, are
checked to be field names first. ``docs/monitor.md`` describes the package and the node.

With a :class:`RecorderScope` (:data:`RENDER_RECORDER`), the package also holds the ROS 2
recorder (``docs/record.md``, "ROS 2"): ``<package>/recorder.py`` (entry point
``<package>_recorder``), ``<package>/recorder.json`` (the scope's services and parameters),
the rclpy adapter ``imrosc/onboard/record_ros2`` (copied unchanged, like ``monitor_ros2``, which
it imports; it writes records with ``imrosc/onboard/records.py``) and
``launch/<package>_recorder.launch.xml``.
"""

from __future__ import annotations

import textwrap
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

from imrosc.backends import launch
from imrosc.backends.monitor import MonitorSpec, dumps, invariants_copy
from imrosc.backends.monitor_backend import MonitorBackend, package_version
from imrosc.backends.registry import BuildInputs, register
from imrosc.backends.vendor import ONBOARD, VENDOR
from imrosc.diagnostics import make
from imrosc.onboard.monitor import WARM

if TYPE_CHECKING:
    from imrosc import ir

ADAPTERS = ("onboard.monitor_ros2",)
"""The middleware adapters the package carries besides :data:`~imrosc.backends.vendor.ONBOARD`
(and ``onboard.record_ros2`` with the recorder)."""
RECORDER_ADAPTERS = ("onboard.record_ros2",)
EXEC_DEPENDS = (
    "ament_index_python",
    "builtin_interfaces",
    "python3-numpy",
    "rcl_interfaces",
    "rclpy",
    "ros2launch",
    "std_msgs",
)
RECORDER_SPEC = "recorder.json"
RECORDER_FORMAT = "imrosc-recorder"
RENDER_RECORDER = True
"""Whether ``imrosc build --backend ros2`` puts the recorder into the package. Off until
``tests/backends/test_ros2.py`` expects the recorder's files (it checks the package's file
list, its launch ``data_files`` and its console scripts exactly); ``render_package`` with
a :class:`RecorderScope` renders it already (``tests/backends/test_ros2_recorder.py``)."""
LAUNCH_SUFFIXES = (".launch.xml", ".xml")
"""Launch files the ``ros2`` backend rewrites (ROS 2 launch XML); Python and YAML launch
files are code or a format it does not read."""

PACKAGE_DOCSTRING = (
    "The imrosc monitor package {package}: ``main`` holds its entry points, "
    "``flatteners`` and ``spec.json`` what it watches, ``imrosc/`` the parts of imrosc "
    "it runs."
)


@dataclass(frozen=True)
class RecorderScope:
    """What the package's recorder records besides the graph: the services of the
    ``<call>`` points (through service introspection) and the parameters, sorted."""

    services: tuple[str, ...] = ()
    params: tuple[str, ...] = ()

    def document(self, spec: MonitorSpec, banner: str) -> dict[str, Any]:
        """``recorder.json``: what the recorder node reads at start."""
        return {
            "$comment": banner,
            "format": RECORDER_FORMAT,
            "version": 1,
            "services": list(self.services),
            "params": list(self.params),
            "period": spec.period,
        }


def recorder_scope(project: ir.Project) -> RecorderScope:
    """The recorder's scope of a configuration (that of ``imrosc record``)."""
    from imrosc.record.scope import scope_of  # record imports the compiler, which imports us

    scope = scope_of(project)
    return RecorderScope(tuple(scope.services), tuple(scope.params))


def chunks(text: str, width: int = 72) -> list[str]:
    """``text`` cut at spaces into pieces of about ``width`` characters (each but the last
    keeps its trailing space), for implicitly concatenated literals.

    >>> chunks("a bb ccc", 4)
    ['a bb ', 'ccc']
    """
    pieces: list[str] = []
    for word in text.split(" "):
        if pieces and len(pieces[-1]) + len(word) <= width:
            pieces[-1] += " " + word
        else:
            pieces.append(word)
    return [piece + " " for piece in pieces[:-1]] + pieces[-1:]


def python_packages(spec: MonitorSpec, recorder: bool = False) -> list[str]:
    """The Python packages ``setup.py`` installs (dotted names)."""
    root = spec.package
    vendor = f"{root}.{VENDOR}"
    adapters = ADAPTERS + (RECORDER_ADAPTERS if recorder else ())
    return [root, vendor, *sorted(f"{vendor}.{name}" for name in (*ONBOARD, *adapters))]


def recorder_script(spec: MonitorSpec) -> str:
    """The recorder's console script."""
    return f"{spec.package}_recorder = {spec.package}.recorder:main"


def recorder_launch(spec: MonitorSpec) -> str:
    """The recorder's launch file."""
    return f"launch/{spec.package}_recorder.launch.xml"


def data_files(spec: MonitorSpec, launch_files: list[str]) -> list[tuple[str, list[str]]]:
    """``setup.py``'s ``data_files``: the ament index marker, ``package.xml``, the config
    and the launch files, under ``share/``."""
    share = f"share/{spec.package}"
    return [
        ("share/ament_index/resource_index/packages", [f"resource/{spec.package}"]),
        (share, ["package.xml"]),
        (f"{share}/config", [spec.invariants_path]),
        (f"{share}/launch", sorted(launch_files)),
    ]


class Ros2Monitor(MonitorBackend):
    """The ament_python package of the monitor, with the rclpy adapter (and the recorder)."""

    name = "ros2"
    templates = "imrosc.backends.ros2"
    autoescaped = ("xml.j2",)
    adapters = ADAPTERS
    launch_dialect = launch.ROS2_LAUNCH
    launch_extension = ".launch.xml"
    message_type = "ros2_type"
    field_note = "(rclpy messages have the field names of the message definition)"

    def package_files(
        self, inputs: BuildInputs, spec: MonitorSpec, banner: str, system_launch: tuple[str, ...]
    ) -> dict[str, bytes]:
        """The files of the package (the recorder's with :data:`RENDER_RECORDER`)."""
        recorder = recorder_scope(inputs.project) if RENDER_RECORDER else None
        return self.render_package(spec, banner, system_launch, recorder)

    def render_package(
        self,
        spec: MonitorSpec,
        banner: str,
        extra_launch: tuple[str, ...] = (),
        recorder: RecorderScope | None = None,
    ) -> dict[str, bytes]:
        """The files of the package (paths relative to the package folder); ``extra_launch``
        names launch files written beside the monitor's own (the rewritten system launch);
        with ``recorder`` the package holds the recorder too."""
        render = self.renderer(spec, banner)
        version = package_version()
        root = spec.package
        description = (
            f"Monitor of the invariants of {spec.project}: checks them live and warns, blocks, "
            "publishes or calls a service when one breaks."
        )
        monitor_launch = self.monitor_launch(spec)
        launch_files = [monitor_launch, *extra_launch]
        scripts = [f"{spec.node} = {root}.main:monitor", f"{spec.watchdog} = {root}.main:watchdog"]
        package_data = ["spec.json"]
        if recorder is not None:
            launch_files.append(recorder_launch(spec))
            scripts.append(recorder_script(spec))
            package_data.append(RECORDER_SPEC)
        files: dict[str, bytes] = {
            "package.xml": render(
                "package.xml.j2", version=version, depends=sorted({*EXEC_DEPENDS, *spec.depends})
            ),
            "setup.py": render(
                "setup.py.j2",
                version=version,
                packages=python_packages(spec, recorder is not None),
                package_data=package_data,
                data_files=data_files(spec, launch_files),
                description=chunks(description),
                scripts=scripts,
            ),
            "setup.cfg": render("setup.cfg.j2"),
            f"resource/{root}": f"{banner}\n".encode(),
            f"{root}/__init__.py": render(
                "init.py.j2", docstring=textwrap.fill(PACKAGE_DOCSTRING.format(package=root), 92)
            ),
            f"{root}/main.py": render("main.py.j2"),
            f"{root}/flatteners.py": self.flatteners(render, spec),
            f"{root}/spec.json": dumps(spec.runtime_document(banner)),
            spec.invariants_path: invariants_copy(spec, banner),
            monitor_launch: render("monitor.launch.xml.j2", warm=WARM),
        }
        files.update(self.vendored(root, () if recorder is None else RECORDER_ADAPTERS))
        if recorder is not None:
            files[f"{root}/recorder.py"] = render("recorder.py.j2")
            files[f"{root}/{RECORDER_SPEC}"] = dumps(recorder.document(spec, banner))
            files[recorder_launch(spec)] = render("recorder.launch.xml.j2")
        return dict(sorted(files.items()))

    def launch_source(self, inputs: BuildInputs, spec: MonitorSpec) -> str | None:
        """The ``<monitor>``'s ``launch_ros2`` when given (a configuration shared with ROS 1,
        whose ``launch`` is a roslaunch file), else its ``launch``; ``None`` with a
        ``launch-error`` when that is not ROS 2 launch XML."""
        project = inputs.project
        monitor = project.monitor
        source = spec.launch_ros2 or spec.launch
        if source is None or monitor is None or source.endswith(LAUNCH_SUFFIXES):
            return source
        attribute = "launch_ros2" if spec.launch_ros2 else "launch"
        hint = (
            ""
            if spec.launch_ros2
            else "; name the ROS 2 launch XML of the system in <monitor launch_ros2=...>, or"
        )
        inputs.diagnostics.append(
            make(
                project.source,
                monitor.span.line,
                monitor.span.column,
                "launch-error",
                f"the ros2 backend rewrites ROS 2 launch XML (*.launch.xml), not "
                f"{attribute}={source!r}{hint}: include launch/{spec.package}.launch.xml from "
                "your launch file and remap the subscribers of the blocked topics to "
                "/m/<topic> yourself (see docs/monitor.md)",
            )
        )
        return None


BACKEND = Ros2Monitor()
register(BACKEND.name, monitor=True)(BACKEND)
