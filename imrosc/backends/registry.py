"""Backends by name: each renders the passed IR into files (name -> bytes).

A backend is a module found by its entry point (group :data:`GROUP`; imrosc's own are
``plan``, ``ros1`` and ``ros2``) that registers its renderer when imported
(:func:`register`), so adding a backend touches neither the passes nor the command line.
A renderer reports problems it finds (a bad invariants file, a launch file it cannot
rewrite) by appending diagnostics to :attr:`BuildInputs.diagnostics`; with an error among
them nothing it returns is written. A file whose content is :class:`Executable` is written
with its execute bits set.
"""

from __future__ import annotations

import importlib
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from importlib import metadata

from imrosc import __version__, ir
from imrosc.diagnostics import Diagnostic
from imrosc.graph.model import Graph
from imrosc.msgtypes import FieldSpec
from imrosc.outputs import GENERATED_MARK

__all__ = [
    "BACKENDS",
    "GENERATED_MARK",
    "BackendError",
    "BuildInputs",
    "Executable",
    "Renderer",
    "TopicType",
    "available",
    "is_monitor",
    "load",
    "names",
    "register",
]


@dataclass(frozen=True)
class TopicType:
    """The message type of a topic as bags recorded it, and its flat variables."""

    msgtype: str
    fields: tuple[FieldSpec, ...]


class Executable(bytes):
    """The content of a file to be written executable (a node script)."""

    __slots__ = ()


@dataclass(frozen=True)
class BuildInputs:
    """What a backend renders from: the passed IR, what bags told about topic types, the
    node graph (``--graph``, ``--bags``) if any, and a list the renderer appends its
    diagnostics to."""

    project: ir.Project
    bags: tuple[str, ...] = ()
    topic_types: Mapping[str, TopicType] = field(default_factory=dict)
    graph: Graph | None = None
    diagnostics: list[Diagnostic] = field(default_factory=list, compare=False)

    def banner(self, backend: str) -> str:
        """The line naming the generator, its version, the backend and the source config."""
        return (
            f"{GENERATED_MARK} {__version__} (backend {backend}) from {self.project.source}; "
            f"do not edit"
        )


Renderer = Callable[[BuildInputs], dict[str, bytes]]
BACKENDS: dict[str, Renderer] = {}
MONITORS: set[str] = set()
"""The backends that render a monitor package (of the configuration's ``<monitor>``)."""

GROUP = "imrosc.backends"
"""The entry-point group a backend's module is found by (``pyproject.toml``:
``[project.entry-points."imrosc.backends"] NAME = "package.module"``); importing the module
registers its renderer."""
_BUILTIN = {name: f"imrosc.backends.{name}" for name in ("plan", "ros1", "ros2")}
"""imrosc's own backends, also found when imrosc runs from a source tree (no metadata)."""


def register(name: str, *, monitor: bool = False) -> Callable[[Renderer], Renderer]:
    """Register a renderer under ``name`` (``monitor``: it renders a monitor package)."""

    def add(renderer: Renderer) -> Renderer:
        BACKENDS[name] = renderer
        if monitor:
            MONITORS.add(name)
        return renderer

    return add


def _entry_points() -> dict[str, str]:
    """Backend name to module: the entry points of :data:`GROUP`, over the built-in ones."""
    found = dict(_BUILTIN)
    for point in metadata.entry_points(group=GROUP):
        found[point.name] = point.value
    return found


def names() -> list[str]:
    """The backends' names, without importing them (the command line's choices)."""
    return sorted(_entry_points())


class BackendError(Exception):
    """A backend's module that cannot be imported, or registers no renderer of its name."""


def _import(name: str, module: str) -> Renderer:
    try:
        importlib.import_module(module)
    except Exception as error:  # a third-party backend may raise anything
        raise BackendError(f"backend {name}: cannot import {module}: {error}") from error
    if name not in BACKENDS:
        raise BackendError(f"backend {name}: {module} registers no renderer named {name}")
    return BACKENDS[name]


def load(name: str) -> Renderer:
    """Backend ``name``'s renderer, its module imported (only its own: a broken backend
    of another package stops only builds that use it)."""
    modules = _entry_points()
    if name not in modules:
        raise BackendError(f"no backend {name} (backends: {', '.join(sorted(modules))})")
    return _import(name, modules[name])


def available() -> dict[str, Renderer]:
    """Every backend by name (:func:`names`), its module imported (and so its renderer
    registered)."""
    return {name: _import(name, module) for name, module in sorted(_entry_points().items())}


def is_monitor(name: str) -> bool:
    """Whether backend ``name`` renders a monitor package."""
    load(name)
    return name in MONITORS
