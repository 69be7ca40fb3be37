"""The front door of every command that compiles a configuration: load, check, lower, passes.

:func:`lowered` reads and checks a configuration and lowers it to the IR (the points and
stages as written: what ``imrosc classify`` and ``imrosc stability`` need); :func:`passed`
runs the passes over a lowered project with the graph the command knows;
:func:`compile_config` does both at once. A command that learns its graph from the lowered
project (``imrosc infer`` reads the bags its ``<detect>`` names) or reads it only once the
configuration is known to be good (``imrosc build``) calls the two steps itself:

========================  ================================================================
command                   graph of the passes
========================  ================================================================
``imrosc build``          its graph files and bags (:mod:`imrosc.build`)
``imrosc infer``          the catalogued ``<detect>`` bags and graph files (:mod:`imrosc.detect`)
``imrosc record``         the live master's (:mod:`imrosc.record.scope`)
========================  ================================================================

Diagnostics come back unsorted: each command adds its own, then finalizes them.
"""

from __future__ import annotations

from pathlib import Path
from typing import NamedTuple

from imrosc import ir
from imrosc.check import load_checked
from imrosc.diagnostics import Diagnostic
from imrosc.graph.model import Graph
from imrosc.lower import lower
from imrosc.passes.context import PassContext
from imrosc.passes.pipeline import run_passes


class Compiled(NamedTuple):
    """A configuration through the front end."""

    project: ir.Project | None
    """After the passes; ``None`` when loading or checking found errors."""
    problems: list[Diagnostic]
    """Loading and checking the configuration."""
    pass_problems: list[Diagnostic]
    """What the passes reported (a command may weigh graph problems its own way)."""


def lowered(config_path: Path) -> tuple[ir.Project | None, list[Diagnostic]]:
    """Read, check and lower a configuration: the lowered project (``None`` when it has
    errors) and the diagnostics of loading and checking it."""
    config, problems = load_checked(config_path)
    if config is None:
        return None, problems
    return lower(config), problems


def passed(project: ir.Project, graph: Graph | None) -> tuple[ir.Project, list[Diagnostic]]:
    """Run the passes over a lowered project with ``graph`` (``None``: no graph known); the
    passed project and what the passes reported."""
    context = PassContext(path=project.source, graph=graph)
    return run_passes(project, context), context.diagnostics


def compile_config(config_path: Path, graph: Graph | None) -> Compiled:
    """Read, check, lower and run the passes with ``graph``."""
    project, problems = lowered(config_path)
    if project is None:
        return Compiled(None, problems, [])
    project, found = passed(project, graph)
    return Compiled(project, problems, found)
