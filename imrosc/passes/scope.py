"""Scope resolution: every name global, every point's parameters attached once, in order.

Names in a configuration should be global (``imrosc check`` warns otherwise); this pass
resolves the rest against the root namespace, so later passes and backends compare names
as ROS does.

>>> from imrosc import ir
>>> point = ir.PublishPoint("a", "scan", ir.Span(3, 5), params=("rate", "/rate"))
>>> project = ir.Project("p", "p.xml", ir.Span(1, 1), points=(point,))
>>> resolved = resolve_scope(project, PassContext())
>>> resolved.points[0].topic, resolved.points[0].params
('/scan', ('/rate',))
"""

from __future__ import annotations

import dataclasses

from imrosc import ir
from imrosc.passes.context import PassContext
from imrosc.schema.names import resolve_name


def _names(names: tuple[str, ...]) -> tuple[str, ...]:
    return tuple(dict.fromkeys(resolve_name(name) for name in names))


def _point(point: ir.Point) -> ir.Point:
    if isinstance(point, ir.PublishPoint):
        return dataclasses.replace(
            point,
            topic=resolve_name(point.topic),
            explicit_topics=_names(point.explicit_topics),
            params=_names(point.params),
        )
    if isinstance(point, ir.CallPoint):
        return dataclasses.replace(
            point, service=resolve_name(point.service), params=_names(point.params)
        )
    if isinstance(point, ir.ParamPoint):
        return dataclasses.replace(point, name=resolve_name(point.name))
    return point


def _action(action: ir.Action) -> ir.Action:
    return dataclasses.replace(action, name=resolve_name(action.name))


def resolve_scope(project: ir.Project, context: PassContext) -> ir.Project:
    """Resolve every topic, service and parameter name of the project to a global name."""
    conditions = tuple(
        dataclasses.replace(c, topic=resolve_name(c.topic)) for c in project.conditions
    )
    monitor = project.monitor
    if monitor is not None:
        monitor = dataclasses.replace(
            monitor,
            block=_names(monitor.block),
            actions=tuple(_action(a) for a in monitor.actions),
        )
    return dataclasses.replace(
        project,
        points=tuple(_point(p) for p in project.points),
        conditions=conditions,
        monitor=monitor,
    )
