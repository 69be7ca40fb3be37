"""Envelopes and margins learnt from the units: how a step's margin models the units'
largest steps (``<detect step_tail>``)."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from imrosc.calibrate.extremes import gumbel_bound
from imrosc.replay import Replayer
from tests.calibrate import learn_scalar
from tests.translate import msg, write_bag

FLOAT = "std_msgs/msg/Float64"
LARGEST = [0.0253, 0.0455, 0.0298, 0.0073, 0.024, 0.0332]
"""Each run's one larger step: alike from run to run (the largest steps of Crazyflie's
position log in six segments of two flights)."""


def spiky(path: Path, seed: int, spike: float) -> Path:
    """``/a/x`` at 20 Hz for 20 s: a ramp of a millimetre a sample with noise of a
    hundredth of one, and at 10 s one sample ``spike`` higher (a step up, then down)."""
    rng = np.random.default_rng(seed)
    messages = []
    for k in range(400):
        value = k * 1e-3 + float(rng.uniform(-1e-5, 1e-5)) + (spike if k == 200 else 0.0)
        messages.append(msg("/a/x", 100.0 + k / 20, FLOAT, data=value))
    return write_bag(path, messages)


def learn(folder: Path, bags: list[Path], tail: str) -> dict[str, Any]:
    return learn_scalar(folder, bags, tail, f' step_tail="{tail}"')


def step_of(document: dict[str, Any]) -> dict[str, Any]:
    steps: list[dict[str, Any]] = [i for i in document["invariants"] if i["family"] == "step"]
    assert len(steps) == 1
    return steps[0]


def severe_steps(document: dict[str, Any], bag: Path) -> list[Any]:
    alarms = Replayer(document).run(bag).alarms
    return [a for a in alarms if a.rule == "severe" and a.violation.family == "step"]


def test_select_narrows_a_step_margin_to_the_gumbel_bound_where_steps_are_alike(
    tmp_path: Path,
) -> None:
    bags = [spiky(tmp_path / f"good_{k}.bag", k, spike) for k, spike in enumerate(LARGEST)]
    larger, select = learn(tmp_path, bags, "larger"), learn(tmp_path, bags, "select")
    wide, narrow = step_of(larger)["params"]["margin"], step_of(select)["params"]["margin"]
    assert narrow["max"][0] == wide["max"][0]  # one centre: the mean of the largest steps
    # the units' largest steps (each run's spike up, on top of the ramp) are alike: the
    # Gumbel model predicts them better, at the level of one of the file's few margins
    supports = [spike + 1e-3 for spike in LARGEST]
    budget = select["calibration"]["budget"]
    one, twenty = gumbel_bound(supports, budget / 4), gumbel_bound(supports, budget / 80)
    assert one is not None and twenty is not None
    assert one < narrow["max"][1] < twenty
    assert narrow["max"][1] < wide["max"][1] / 4  # the log-normal tail reaches far further
    # a spike five times the largest seen: beyond the Gumbel margin, inside the log-normal
    jump = tmp_path / "jump.bag"
    spiky(jump, 9, 5 * max(LARGEST))
    assert severe_steps(select, jump) and not severe_steps(larger, jump)
    quiet = tmp_path / "quiet.bag"
    spiky(quiet, 9, float(np.mean(LARGEST)))
    assert Replayer(select).run(quiet).alarms == []
