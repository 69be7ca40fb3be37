"""The pass order, as data (as sqlglot's optimizer keeps its rules)."""

from __future__ import annotations

import dataclasses
from collections.abc import Callable

from imrosc import ir
from imrosc.passes.conditions import expand_conditions
from imrosc.passes.context import PassContext
from imrosc.passes.relative import group_relative
from imrosc.passes.scope import resolve_scope
from imrosc.passes.temporal import label_events

Pass = Callable[[ir.Project, PassContext], ir.Project]

PASSES: tuple[Pass, ...] = (resolve_scope, group_relative, expand_conditions, label_events)


def run_passes(
    project: ir.Project, context: PassContext, passes: tuple[Pass, ...] = PASSES
) -> ir.Project:
    """Apply ``passes`` in order, recording their names in the project."""
    for run in passes:
        project = run(project, context)
        project = dataclasses.replace(project, passes=(*project.passes, run.__name__))
    return project
