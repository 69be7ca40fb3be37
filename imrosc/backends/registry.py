"""Backends by name: each renders the passed IR into files (name -> bytes).

``plan``, ``ros1`` and ``ros2`` are registered here (each module registers itself when
imported), so adding a backend never touches the passes. A renderer reports problems it
finds (a bad invariants file, a launch file it cannot rewrite) by appending diagnostics to
:attr:`BuildInputs.diagnostics`; with an error among them nothing it returns is written. A
file whose content is :class:`Executable` is written with its execute bits set.
"""

from __future__ import annotations

import importlib
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field

from imrosc import __version__, ir
from imrosc.diagnostics import Diagnostic
from imrosc.graph.model import Graph
from imrosc.msgtypes import FieldSpec
from imrosc.outputs import GENERATED_MARK

__all__ = [
    "BACKENDS",
    "GENERATED_MARK",
    "BuildInputs",
    "Executable",
    "Renderer",
    "TopicType",
    "available",
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


def register(name: str) -> Callable[[Renderer], Renderer]:
    """Register a renderer under ``name``."""

    def add(renderer: Renderer) -> Renderer:
        BACKENDS[name] = renderer
        return renderer

    return add


_BUILTIN_MODULES = ("imrosc.backends.plan", "imrosc.backends.ros1", "imrosc.backends.ros2")


def available() -> dict[str, Renderer]:
    """Every backend, the built-in ones imported (and so registered) first."""
    for module in _BUILTIN_MODULES:
        importlib.import_module(module)
    return dict(sorted(BACKENDS.items()))
