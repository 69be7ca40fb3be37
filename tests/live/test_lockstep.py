"""The landing system in lockstep (``examples/landing_system/lockstep``): a trial's every
step (the command the simulator applies, the UAV it moves) is the same whether the machine
is idle or two busy processes compete for its cores, because ``/clock`` advances only once
every node has reacted to the last step."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

from tests.live.harness import Ros
from tests.live.landing_system import prepare, trial

pytestmark = pytest.mark.live

TIMEOUT = 8.0
"""Simulated seconds: take-off, climb and the pursuit's first turns."""


def busy_loops(count: int) -> list[subprocess.Popen[bytes]]:
    return [subprocess.Popen([sys.executable, "-c", "while 1: pass"]) for _ in range(count)]


def test_a_trial_is_the_same_on_a_loaded_machine(ros: Ros, tmp_path: Path) -> None:
    prepare(ros)
    quiet, loaded = tmp_path / "quiet.trace", tmp_path / "loaded.trace"
    first = trial(ros, "wind", 3, speed=0.0, timeout=TIMEOUT, trace=str(quiet))
    loops = busy_loops(2)
    try:
        second = trial(ros, "wind", 3, speed=0.0, timeout=TIMEOUT, trace=str(loaded))
    finally:
        for loop in loops:
            loop.kill()
            loop.wait()
    assert (first.outcome, first.time, first.stalls) == (second.outcome, second.time, 0)
    steps = quiet.read_text().splitlines()
    assert len(steps) >= TIMEOUT * 100 - 1
    assert loaded.read_text().splitlines() == steps
