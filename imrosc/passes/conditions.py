"""Condition expansion (thesis 3.6): one conditional program point per condition of a point.

A point with ``conds="1,2"`` keeps its unconditional form and gains the points ``a?1`` and
``a?2``, whose samples are those taken while the condition holds. Conditions found during
inference (discrete variables) join through :func:`join_discovered` and expand the same way.

>>> from imrosc import ir
>>> point = ir.PublishPoint("a", "/x", ir.Span(3, 5), conds=("1",))
>>> project = ir.Project("p", "p.xml", ir.Span(1, 1), points=(point,))
>>> [ir.point_key(p) for p in expand_conditions(project, PassContext()).points]
['a', 'a?1']
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping, Sequence

from imrosc import ir
from imrosc.passes.context import PassContext


def expand_conditions(project: ir.Project, context: PassContext) -> ir.Project:
    """Add the conditional copy of each point for each of its conditions (idempotent)."""
    existing = {ir.point_key(p) for p in project.points}
    points: list[ir.Point] = []
    for point in project.points:
        points.append(point)
        if point.condition is not None:
            continue
        for condition in point.conds:
            copy = dataclasses.replace(point, condition=condition)
            if ir.point_key(copy) not in existing:
                points.append(copy)
    return dataclasses.replace(project, points=tuple(points))


def join_discovered(
    project: ir.Project, discovered: Mapping[str, Sequence[ir.Condition]]
) -> ir.Project:
    """Attach conditions found by inference (by point key) and mark them ``discovered``."""
    known = {c.id for c in project.conditions}
    conditions = list(project.conditions)
    points: list[ir.Point] = []
    for point in project.points:
        found = discovered.get(ir.point_key(point), ()) if point.condition is None else ()
        for condition in found:
            if condition.id not in known:
                conditions.append(dataclasses.replace(condition, discovered=True))
                known.add(condition.id)
        conds = tuple(dict.fromkeys((*point.conds, *(c.id for c in found))))
        points.append(dataclasses.replace(point, conds=conds))
    return dataclasses.replace(project, points=tuple(points), conditions=tuple(conditions))
