"""The learnt fault detector at run time: its window statistics and its alarms."""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from imrosc.runtime import Engine
from imrosc.runtime.detector import Detector, features
from imrosc.runtime.families import DETECTOR


def _direct(times: Any, rows: Any, window: float) -> Any:
    """Each sample's statistics computed from scratch: NaN or inf is the last finite value
    (0 first)."""
    filled = np.array(rows, dtype=np.float64)
    last = np.zeros(filled.shape[1])
    for k in range(len(filled)):
        missing = ~np.isfinite(filled[k])
        filled[k][missing] = last[missing]
        last = filled[k]
    found = []
    for k, t in enumerate(times):
        inside = [j for j in range(k + 1) if times[j] > t - window]
        block = filled[inside]
        found.append(np.concatenate([block.mean(axis=0), block.std(axis=0), filled[k] - block[0]]))
    return np.array(found)


def test_window_statistics_match_a_direct_computation() -> None:
    rng = np.random.default_rng(7)
    times = np.cumsum(rng.uniform(0.01, 0.3, 300))
    rows = rng.normal(3.0, 2.0, (300, 4))
    rows[rng.random((300, 4)) < 0.05] = math.nan
    rows[0, 1] = math.nan  # before any value: 0
    rows[40, 2], rows[41, 3] = math.inf, -math.inf  # would poison the running sums
    assert np.allclose(features(times, rows, 1.0), _direct(times, rows, 1.0), atol=1e-9)


def _invariant(threshold: float) -> dict[str, Any]:
    """A detector on x alone that scores the change across the window."""
    return {
        "id": "idet",
        "point": "a",
        "family": DETECTOR,
        "kind": "logistic",
        "variables": ["x.data"],
        "text": f"detector score of 1 variables of a <= {threshold}",
        "params": {
            "window": 1.0,
            "center": [0.0, 0.0, 0.0],
            "scale": [1.0, 1.0, 2.0],
            "weights": [0.0, 0.0, 2.0],
            "bias": -1.0,
            "threshold": threshold,
        },
    }


def test_the_score_is_the_weighed_standardised_statistics() -> None:
    detector = Detector(_invariant(0.5), {"x.data": 0})
    scores = [detector.score(0.25 * k, np.array([float(k)])) for k in range(6)]
    changes = [0, 1, 2, 3, 3, 3]  # the oldest sample of the window is 1 s back
    assert scores == [2.0 * c / 2.0 - 1.0 for c in changes]


def _document(invariants: list[dict[str, Any]]) -> dict[str, Any]:
    variable = {"name": "x.data", "type": "float", "topic": "/x", "path": "data"}
    return {
        "topics": {"/x": {"variables": [variable]}},
        "points": {"a": {"kind": "publish", "trigger": "/x", "variables": [variable]}},
        "invariants": invariants,
        "alarms": {"persist": 100, "seconds": 100.0, "distinct": 0, "window": 1.0},
    }


def test_the_engine_raises_an_alarm_at_the_first_score_above_the_threshold() -> None:
    engine = Engine(_document([_invariant(1.5)]))
    assert not engine.points["a"].plain  # the detector keeps a window
    found = []
    for k in range(8):
        found += engine.message("/x", 10.0 + 0.25 * k, [0.0 if k < 4 else 5.0])
    assert [v.family for v in found] == [DETECTOR] * len(found) and found
    assert found[0].time == 11.0  # the jump's own sample: change 5, score 4
    alarms = engine.take_alarms()
    assert alarms and alarms[0].rule == "event" and alarms[0].time == 11.0


def test_reset_forgets_the_window_and_clear_stops_the_detector() -> None:
    engine = Engine(_document([_invariant(1.5)]))
    engine.message("/x", 0.0, [0.0])
    engine.reset()
    assert engine.message("/x", 0.5, [5.0]) == []  # a first sample changes nothing
    assert engine.message("/x", 0.75, [10.0]) != []
    assert engine.clear("idet")
    assert engine.message("/x", 1.0, [20.0]) == []
