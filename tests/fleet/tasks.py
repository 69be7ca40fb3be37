"""Bag tasks for the cluster tests, imported by the Dask workers: they kill their worker
process before reading some bags."""

from __future__ import annotations

import os
import signal
from collections.abc import Mapping
from pathlib import Path
from typing import Any

from imrosc.classify import RunOutcome, RunTask
from imrosc.fleet.cluster import _observe_run, run_remote
from imrosc.infer.engine import BagJob, BagResult

VICTIM = "victim"
"""A run whose name holds this kills the first worker that observes it."""
POISON = "poison"
"""A bag whose name holds this kills every worker that reads it."""


def marker(bag: Path) -> Path:
    """The file that says a worker was killed reading ``bag`` once."""
    return bag.with_name("killed-" + bag.name)


def kill_once(template: BagJob, bag: Path, run: int) -> BagResult:
    """Kill the worker the first time it reads a bag of run 1 (midway: the scheduler has
    handed it the task), and read it normally the next time."""
    if run == 1 and not marker(bag).exists():
        marker(bag).touch()
        os.kill(os.getpid(), signal.SIGKILL)
    return run_remote(template, bag, run)


def kill_always(template: BagJob, bag: Path, run: int) -> BagResult:
    """Kill every worker that reads a poisoned bag."""
    if POISON in bag.name:
        os.kill(os.getpid(), signal.SIGKILL)
    return run_remote(template, bag, run)


def kill_once_observing(
    document: Mapping[str, Any],
    key: str,
    bag: Path,
    task: RunTask,
    name: Path,
    collect: bool = False,
) -> RunOutcome:
    """Kill the worker the first time it observes a run whose name holds ``victim``, and
    observe it the next time."""
    if VICTIM in bag.name and not marker(bag).exists():
        marker(bag).touch()
        os.kill(os.getpid(), signal.SIGKILL)
    return _observe_run(document, key, bag, task, name, collect)
