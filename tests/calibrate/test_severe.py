"""Severe violations: margins from the units' extremes, checked on held-out units."""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import numpy as np

from imrosc.calibrate.rule import HeldOut
from imrosc.calibrate.severe import check_severe, factor, scaled
from imrosc.replay import Replayer
from imrosc.runtime.alarms import AlarmRule, margins_of, severity
from tests.calibrate import learn_scalar
from tests.translate import msg, write_bag

FLOAT = "std_msgs/msg/Float64"


def walk(path: Path, seed: int, jump_at: float | None = None) -> Path:
    """A slow random walk on ``/a/x`` at 20 Hz for 20 s; from ``jump_at`` on, 0.1 higher."""
    rng = np.random.default_rng(seed)
    value, messages = 0.0, []
    for k in range(400):
        value += rng.uniform(-0.01, 0.01)  # bounded steps: every run reaches about 0.01
        jumped = 0.1 if jump_at is not None and k / 20 >= jump_at else 0.0
        messages.append(msg("/a/x", 100.0 + k / 20, FLOAT, data=value + jumped))
    return write_bag(path, messages)


def test_ranges_get_margins_beyond_their_limits_and_a_jump_alarms_at_once(tmp_path: Path) -> None:
    bags = [walk(tmp_path / f"good_{k}.bag", k) for k in range(6)]
    document = learn_scalar(tmp_path, bags)
    steps = [i for i in document["invariants"] if i["family"] == "step"]
    assert steps, "a walk's steps are far narrower than its range"
    (step,) = steps
    margin = step["params"]["margin"]
    # both limits share one margin: the same distance from the same centre either way
    assert margin["max"][0] == -margin["min"][0]
    assert math.isclose(margin["max"][1], -margin["min"][1])
    assert margin["max"][1] >= step["params"]["max"] and margin["min"][1] <= step["params"]["min"]
    rule = AlarmRule.from_json(document["alarms"])
    assert document["calibration"]["severe"]["families"] == list(rule.severe_families)
    assert "step" in rule.severe_families and rule.severe == 1.0
    # a jump of 0.1 (ten steps at once) alarms at the sample it comes, not after persisting
    jumped = Replayer(document).run(walk(tmp_path / "jump.bag", 9, jump_at=12.0))
    first = min(jumped.alarms, key=lambda a: a.time)
    assert (first.rule, first.violation.family) == ("severe", "step")
    assert math.isclose(first.time - 100.0, 12.0)
    quiet = Replayer(document).run(walk(tmp_path / "quiet.bag", 9))
    assert quiet.alarms == []


def test_segments_of_one_bag_give_no_margins(tmp_path: Path) -> None:
    document = learn_scalar(tmp_path, [walk(tmp_path / "only.bag", 1)])
    assert document["calibration"]["units"] == "segments"
    assert not any("margin" in i["params"] for i in document["invariants"])
    assert "severe" not in document["calibration"]
    assert AlarmRule.from_json(document["alarms"]).severe_families == ()


def held_out(fold: int, severities: dict[str, float]) -> HeldOut:
    trace = {ident: {"family": "bounds", "severity": s} for ident, s in severities.items()}
    return HeldOut("b.bag", None, fold, trace)


def bounds(ident: str) -> dict[str, Any]:
    return {"id": ident, "family": "bounds", "params": {"margin": {"max": [0.0, 1.0]}}}


def test_a_family_whose_held_out_units_go_far_out_gets_no_severe_alarm() -> None:
    """Three units of one fold: the other folds' units do not widen the margin for them."""
    invariants = [bounds("a"), bounds("b")]
    units = [held_out(0 if k < 3 else k, {"a": 3.0} if k < 3 else {}) for k in range(12)]
    found = check_severe(invariants, units, 0.05, 0.001)
    assert found.families == () and found.refused == {"bounds": 3}
    assert invariants[0]["params"]["margin"]["max"][1] > 3  # widened by their severities
    assert invariants[1]["params"]["margin"] == {"max": [0.0, 1.0]}  # untouched


def test_a_family_held_out_units_stay_within_keeps_its_severe_alarm() -> None:
    invariants = [bounds("a")]
    units = [held_out(k, {"a": 0.4}) for k in range(12)]
    found = check_severe(invariants, units, 0.05, 0.001)
    assert found.families == ("bounds",) and found.refused == {} and found.widened == 0


def test_one_unit_far_out_is_explained_by_the_other_folds_widening_only() -> None:
    """The unit's own severity would widen its margin past itself; the other folds' units
    (all within) do not widen it, so it counts as having reached 1."""
    invariants = [bounds("a")]
    units = [held_out(k, {"a": 2.0} if k == 0 else {}) for k in range(12)]
    found = check_severe(invariants, units, 0.05, 0.001)
    assert found.reached == {"bounds": 1} and found.widened == 1
    assert factor([0.0] * 11, 0.001) == 1.0
    assert [u.severe for u in units] == [["bounds"]] + [[]] * 11
    assert units[0].as_json()["severe"] == ["bounds"] and units[0].as_json()["fold"] == 0


def test_a_unit_within_the_margins_its_fold_did_not_set_reached_no_family() -> None:
    """Two units far out in two folds: each fold's margin is widened by the other's, so
    neither reaches 1 against the margins it did not set."""
    invariants = [bounds("a")]
    units = [held_out(k % 2, {"a": 2.0} if k < 2 else {"a": 0.1}) for k in range(12)]
    found = check_severe(invariants, units, 0.05, 0.001)
    assert found.reached == {} and all(u.severe == [] for u in units)


def test_severity_and_scaled_margins_agree() -> None:
    margins = margins_of([bounds("a")])
    wider = scaled([0.0, 1.0], 2.0, False)
    assert wider == [0.0, 2.0]
    assert severity(margins["a"], 2.0) == 2.0
    assert (
        severity(
            margins_of([{"id": "a", "family": "bounds", "params": {"margin": {"max": wider}}}])[
                "a"
            ],
            2.0,
        )
        == 1.0
    )


def test_a_variance_margin_widened_past_any_float_is_no_margin() -> None:
    """A variance's margin widens in the logarithm: held-out severities can take its limit
    past any float, and that side then has no margin (as one computed past any float)."""
    wide = {"max": [1.0, 1e300], "min": [1.0, 0.5]}
    params: dict[str, Any] = {"min": 0.1, "margin": wide}
    invariants: list[dict[str, Any]] = [{"id": "v", "family": "variance", "params": params}]
    units = [held_out(k, {"v": 2.0} if k == 0 else {}) for k in range(12)]
    for unit in units:
        for trace in unit.trace.values():
            trace["family"] = "variance"
    found = check_severe(invariants, units, 0.05, 0.001)
    assert found.widened == 1
    margin = invariants[0]["params"]["margin"]
    assert set(margin) == {"min"} and 0 < margin["min"][1] < 0.5
    invariants[0]["params"]["margin"] = {"max": [1.0, 1e300]}
    check_severe(invariants, units, 0.05, 0.001)
    assert "margin" not in invariants[0]["params"] and invariants[0]["params"]["min"] == 0.1
