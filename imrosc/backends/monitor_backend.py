"""The base of the backends that render the configuration's ``<monitor>`` as a ROS package.

A monitor backend (``ros1``, ``ros2``, or another package's) is a subclass of
:class:`MonitorBackend` that says what differs between middlewares: its templates (a
package with a ``templates/`` folder), the middleware adapters its package carries, its
launch dialect (:mod:`imrosc.backends.launch`) and the launch file extension, the message
type names its flatteners are commented with, and the files of its package
(:meth:`MonitorBackend.package_files`). The base class holds what every monitor package
does alike: the spec (:func:`imrosc.backends.monitor.monitor_spec`), one template
environment with the quoting filters over the backend's templates and the shared ones
(``imrosc/backends/templates/``: the flatteners), the vendored copies of imrosc
(:func:`imrosc.backends.vendor.vendored`), the system's launch file rewritten by the
backend's launch dialect, and every path under ``<package>/``.

An instance is the backend's renderer: ``register(NAME, monitor=True)(Backend())``.
"""

from __future__ import annotations

import os
import re
from abc import ABC, abstractmethod
from collections.abc import Callable
from pathlib import Path
from typing import Any, ClassVar

from jinja2 import Environment

from imrosc import __version__
from imrosc.backends import launch, quoting
from imrosc.backends.monitor import MonitorSpec, flattener_helpers, monitor_spec
from imrosc.backends.registry import BuildInputs
from imrosc.backends.vendor import vendored
from imrosc.diagnostics import make

SHARED_TEMPLATES = "imrosc.backends"
"""The package whose ``templates/`` every monitor backend renders from besides its own."""
_VERSION = re.compile(r"[0-9]+\.[0-9]+\.[0-9]+")

Render = Callable[..., bytes]
"""A template's name and its extra context to the rendered file."""


def package_version() -> str:
    """The version a generated package declares: imrosc's when it is ``X.Y.Z``."""
    return __version__ if _VERSION.fullmatch(__version__) else "0.0.0"


class MonitorBackend(ABC):
    """A backend rendering the monitor package; an instance is its renderer."""

    name: ClassVar[str]
    """The backend's name (``--backend NAME``, the banner's ``(backend NAME)``)."""
    templates: ClassVar[str]
    """The package whose ``templates/`` folder holds the backend's own templates."""
    autoescaped: ClassVar[tuple[str, ...]]
    """Endings of the template names rendered with XML autoescaping."""
    adapters: ClassVar[tuple[str, ...]]
    """The middleware adapters (imrosc packages) the package carries besides the onboard
    ones (:data:`imrosc.backends.vendor.ONBOARD`)."""
    launch_dialect: ClassVar[launch.LaunchDialect]
    """The format of the system's launch file the backend rewrites
    (:data:`~imrosc.backends.launch.ROSLAUNCH`, :data:`~imrosc.backends.launch.ROS2_LAUNCH`)."""
    launch_extension: ClassVar[str]
    """The extension of the package's launch files (``.launch``, ``.launch.xml``)."""
    message_type: ClassVar[str]
    """The :class:`~imrosc.backends.monitor.TopicSpec` attribute naming a topic's type as the
    middleware spells it (``ros1_type``, ``ros2_type``)."""
    field_note: ClassVar[str] = ""
    """What the flatteners' docstring says about the middleware's message fields."""

    def __call__(self, inputs: BuildInputs) -> dict[str, bytes]:
        """The monitor package, each path under ``<package>/``."""
        spec = monitor_spec(inputs)
        if spec is None:
            return {}
        banner = inputs.banner(self.name)
        system = self.rewrite_system_launch(inputs, spec, banner)
        files = self.package_files(inputs, spec, banner, tuple(system))
        files.update(system)
        return {f"{spec.package}/{name}": content for name, content in sorted(files.items())}

    @abstractmethod
    def package_files(
        self, inputs: BuildInputs, spec: MonitorSpec, banner: str, system_launch: tuple[str, ...]
    ) -> dict[str, bytes]:
        """The files of the package but the rewritten system launch file (paths relative to
        the package folder); ``system_launch`` names that file when there is one."""

    def environment(self) -> Environment:
        """The template environment: the backend's templates over the shared ones, strict,
        with the quoting filters."""
        return quoting.environment((self.templates, SHARED_TEMPLATES), self.autoescaped)

    def renderer(self, spec: MonitorSpec, banner: str) -> Render:
        """Renders a template with the spec and the banner in its context."""
        env = self.environment()

        def render(template: str, **extra: Any) -> bytes:
            context = {"spec": spec, "banner": banner, **extra}
            return env.get_template(template).render(**context).encode("utf-8")

        return render

    def flatteners(self, render: Render, spec: MonitorSpec) -> bytes:
        """``flatteners.py``: one function per flattened topic (the shared template)."""
        return render(
            "flatteners.py.j2",
            topics=[t for t in spec.topics if t.flattener is not None],
            helpers=flattener_helpers(spec),
            message_type=self.message_type,
            field_note=self.field_note,
        )

    def vendored(self, root: str, extra: tuple[str, ...] = ()) -> dict[str, bytes]:
        """The copies of imrosc the Python package at ``root`` carries: the onboard packages,
        the backend's adapters and ``extra`` ones."""
        return vendored(root, self.name, (*self.adapters, *extra))

    def monitor_launch(self, spec: MonitorSpec) -> str:
        """The package's launch file of the monitor (relative to the package)."""
        return f"launch/{spec.package}{self.launch_extension}"

    def system_launch_target(self) -> str:
        """Where the rewritten system launch file goes (relative to the package)."""
        return f"launch/system_monitored{self.launch_extension}"

    def launch_source(self, inputs: BuildInputs, spec: MonitorSpec) -> str | None:
        """The system's launch file to rewrite (relative to the configuration), if any; a
        backend that cannot rewrite it appends a diagnostic and returns ``None``."""
        return spec.launch

    def rewrite_system_launch(
        self, inputs: BuildInputs, spec: MonitorSpec, banner: str
    ) -> dict[str, bytes]:
        """``{target: content}``: the system's launch file rewritten in the backend's
        launch dialect to start the monitor and remap the subscribers of the blocked topics; nothing
        when the ``<monitor>`` names none, and nothing with a diagnostic when it cannot be."""
        project = inputs.project
        monitor = project.monitor
        source = self.launch_source(inputs, spec)
        if source is None or monitor is None:
            return {}
        interception = launch.Interception(spec.topic_relays, spec.service_relays)
        graph = inputs.graph
        if interception and (graph is None or not graph.knows_subscriptions):
            inputs.diagnostics.append(
                make(
                    project.source,
                    monitor.span.line,
                    monitor.span.column,
                    "launch-without-graph",
                    "rewriting the launch file needs to know who subscribes to the blocked "
                    "topics and who serves the relayed services: pass --graph FILE or --bags "
                    "with architecture records",
                )
            )
            return {}
        rewritten = self.launch_dialect.rewrite(
            Path(project.source).parent / source,
            interception=interception,
            graph=graph,
            monitor=launch.MonitorLaunch(spec.package, os.path.basename(self.monitor_launch(spec))),
            banner=banner,
        )
        inputs.diagnostics.extend(rewritten.diagnostics)
        return {} if rewritten.content is None else {self.system_launch_target(): rewritten.content}
