"""What a configuration needs recorded: topics, services, parameters, architecture kinds.

The configuration is checked and compiled as for ``imrosc build`` (:mod:`imrosc.frontend`:
lowering and the passes, relative grouping included, with the graph the caller has: usually
the live master's), and the scope is read off the compiled points:

* **topics**: the topic of every ``<publish>``, its declared and grouped input topics, and
  the topic of every ``<condition>`` a point uses;
* **services**: the service of every ``<call>`` (``imrosc record`` relays them);
* **parameters**: the ``<param>`` of every point and every scope-level ``<param>``;
* **architecture kinds**: the kinds of every ``<arch>`` (the recorder always publishes full
  snapshots: the graph reader uses them for relative grouping too).

Relative grouping that the graph cannot do yet (the topic has no publisher: the system is
not running) is not an error here, as the inputs can still be named by hand; it comes back
as a warning saying which inputs will be missing.

>>> from imrosc import ir
>>> span = ir.Span(1, 1)
>>> project = ir.Project("p", "p.xml", span, points=(
...     ir.PublishPoint("a", "/cmd", span, inputs=(ir.InputTopic("/pose", 1),),
...                     params=("/rate",), conds=("1",)),
...     ir.CallPoint("c", "/task", span, params=("/rate",)),
...     ir.ParamPoint(None, "/gain", span),
...     ir.ArchPoint("d", ("pub", "sub"), span)),
...     conditions=(ir.Condition("1", "/state", "state == 1", {}, span),))
>>> scope = scope_of(project)
>>> scope.topics, scope.services, scope.params, scope.arch
(('/cmd', '/pose', '/state'), ('/task',), ('/gain', '/rate'), ('pub', 'sub'))
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

from imrosc import ir
from imrosc.diagnostics import Diagnostic, finalize, has_errors
from imrosc.frontend import compile_config
from imrosc.graph.model import Graph

__all__ = ["ARCH_KINDS", "CompiledScope", "Scope", "compile_scope", "scope_of"]

ARCH_KINDS = ("pub", "sub", "srv")
_GRAPH_CODES = frozenset({"relative-without-graph", "unknown-topic"})
"""Pass diagnostics about relative grouping the graph could not do: warnings when recording."""


@dataclass(frozen=True)
class Scope:
    """The names a recording must capture, each tuple sorted."""

    topics: tuple[str, ...] = ()
    services: tuple[str, ...] = ()
    params: tuple[str, ...] = ()
    arch: tuple[str, ...] = ()

    @property
    def empty(self) -> bool:
        """Whether there is nothing to record."""
        return not (self.topics or self.services or self.params or self.arch)

    def describe(self) -> str:
        """``3 topics, 1 service, 2 parameters, architecture (pub, sub)``."""
        parts = [
            _count(len(self.topics), "topic"),
            _count(len(self.services), "service"),
            _count(len(self.params), "parameter"),
        ]
        if self.arch:
            parts.append(f"architecture ({', '.join(self.arch)})")
        return ", ".join(parts)


def _count(number: int, noun: str) -> str:
    return f"{number} {noun}{'s' * (number != 1)}"


def scope_of(project: ir.Project) -> Scope:
    """The scope of a compiled project (after the passes)."""
    used = {ident for point in project.points for ident in point.conds}
    topics: set[str] = {c.topic for c in project.conditions if c.id in used}
    services: set[str] = set()
    params: set[str] = set()
    kinds: set[str] = set()
    for point in project.points:
        if isinstance(point, ir.PublishPoint):
            topics |= {point.topic, *point.explicit_topics, *(i.name for i in point.inputs)}
            params |= set(point.params)
        elif isinstance(point, ir.CallPoint):
            services.add(point.service)
            params |= set(point.params)
        elif isinstance(point, ir.ParamPoint):
            params.add(point.name)
        elif isinstance(point, ir.ArchPoint):
            kinds |= set(point.kinds or ARCH_KINDS)
    return Scope(
        tuple(sorted(topics)),
        tuple(sorted(services)),
        tuple(sorted(params)),
        tuple(k for k in ARCH_KINDS if k in kinds),
    )


@dataclass
class CompiledScope:
    """The outcome of :func:`compile_scope`."""

    scope: Scope | None = None
    project: ir.Project | None = None
    diagnostics: list[Diagnostic] = field(default_factory=list)
    """Problems of the configuration (errors stop the recording)."""
    warnings: list[str] = field(default_factory=list)
    """Relative grouping the graph could not do: inputs that will not be recorded."""


def compile_scope(config_path: Path, graph: Graph | None) -> CompiledScope:
    """Check and compile the configuration with ``graph``; its scope if it has no errors."""
    out = CompiledScope()
    project, problems, found = compile_config(config_path, graph)
    if project is None:
        out.diagnostics = finalize(problems)
        return out
    for diagnostic in found:
        if diagnostic.code in _GRAPH_CODES:
            out.warnings.append(_graph_warning(diagnostic, project))
        else:
            problems.append(diagnostic)
    out.diagnostics = finalize(problems)
    if not has_errors(out.diagnostics):
        out.project = project
        out.scope = scope_of(project)
    return out


def _graph_warning(diagnostic: Diagnostic, project: ir.Project) -> str:
    """Why a relative point's inputs are unknown, and what to do about it."""
    points = [
        p
        for p in project.points
        if isinstance(p, ir.PublishPoint) and (p.span.line, p.span.column) == _at(diagnostic)
    ]
    what = f"relative={points[0].relative} on {points[0].topic}" if points else "a relative point"
    return (
        f"{diagnostic.path}:{diagnostic.line}:{diagnostic.column}: {what}: the graph does not "
        f"know who publishes it yet, so its input topics are not recorded; start the system "
        f"before 'imrosc record', pass --graph FILE, or record every topic with --all"
    )


def _at(diagnostic: Diagnostic) -> tuple[int, int]:
    return diagnostic.line, diagnostic.column
