"""Bag tasks for the cluster tests, imported by the Dask workers: they kill their worker
process before reading some bags."""

from __future__ import annotations

import os
import signal
from pathlib import Path

from imrosc.fleet.cluster import run_remote
from imrosc.infer.engine import BagJob, BagResult

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
