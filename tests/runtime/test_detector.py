"""The learnt fault detector at run time: its window statistics and its alarms."""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from imrosc.runtime import Engine
from imrosc.runtime.detector import Detector, TrailingMean, bounded, evidence, features
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
    for k in range(5):
        engine.message("/x", 0.25 * k, [0.0])
    engine.reset()
    assert engine.message("/x", 1.25, [5.0]) == []  # a first sample again: no score yet
    assert engine.message("/x", 2.0, [5.0]) == []
    assert engine.message("/x", 2.25, [10.0]) != []  # spans 1 s: the change is 5
    assert engine.clear("idet")
    assert engine.message("/x", 2.5, [20.0]) == []


def test_no_score_before_the_samples_span_the_window() -> None:
    detector = Detector(_invariant(-5.0), {"x.data": 0})  # any score is above -5
    found = [detector.sample(0.25 * k, np.array([0.0])) is not None for k in range(6)]
    assert found == [False] * 4 + [True] * 2


def test_the_evidence_of_a_run_matches_the_detector_s_sample_by_sample() -> None:
    rng = np.random.default_rng(11)
    times = np.cumsum(rng.uniform(0.01, 0.4, 500))
    scores = rng.normal(0.0, 3.0, 500)
    scores[17], scores[90], scores[91] = math.nan, math.inf, -math.inf
    for window, smooth in ((0.0, 0.0), (0.0, 1.0), (1.0, 0.0), (1.0, 0.5), (0.5, 2.0)):
        weighed = TrailingMean(smooth)
        spans = times - times[0] >= window
        one_by_one = [
            weighed.add(t, s) if spanning else None
            for t, s, spanning in zip(times, scores, spans, strict=True)
        ]
        whole = evidence(times, scores, window, smooth)
        assert [v is None for v in one_by_one] == list(np.isnan(whole))
        assert np.allclose(
            [v for v in one_by_one if v is not None], whole[~np.isnan(whole)], atol=1e-6
        )
    first = int(np.argmax(times - times[0] >= 0.5))
    direct = [  # from scratch: the scores later than t - 2, NaN as 0, infinities clipped
        np.mean([bounded(scores[j]) for j in range(first, k + 1) if times[j] > t - 2.0])
        for k, t in enumerate(times)
        if k >= first and t - times[first] >= 2.0
    ]
    whole = evidence(times, scores, 0.5, 2.0)
    assert np.allclose(whole[~np.isnan(whole)], direct, atol=1e-6)


def test_a_silence_longer_than_the_window_begins_a_stretch() -> None:
    """After a pause the detector scores again once the samples since span the window, and
    weighs once those scores span ``smooth``, as at a run's start; what classification
    computes for a whole run (``features``, ``evidence``) is what the monitor computes."""
    rng = np.random.default_rng(5)
    gaps = rng.uniform(0.05, 0.3, 400)
    gaps[[60, 61, 200, 330]] = [2.5, 0.1, 1.25, 7.0]  # silences longer than the window
    times = np.cumsum(gaps)
    rows = rng.normal(0.0, 1.0, (400, 1))
    invariant = _invariant(0.5)
    invariant["params"]["smooth"] = 0.5
    detector = Detector(invariant, {"x.data": 0})
    live = [detector.sample(t, row) is not None for t, row in zip(times, rows, strict=True)]
    params = invariant["params"]
    scores = features(times, rows, 1.0) @ (np.asarray(params["weights"]) / params["scale"])
    whole = evidence(times, scores + params["bias"], 1.0, 0.5)
    assert live == list(whole > 0.5)
    for silence in (60, 200, 330):  # the sample after the silence begins a stretch
        after = times[silence:] - times[silence]
        scored = silence + int(np.searchsorted(after, 1.0, side="left"))  # spans 1 s
        weighed = scored + int(np.searchsorted(times[scored:] - times[scored], 0.5, "left"))
        assert np.isnan(whole[silence:weighed]).all()
        assert not np.isnan(whole[weighed])
        assert not np.isnan(whole[silence - 1])  # the stretch before was weighed


def test_a_smoothed_detector_alarms_on_a_lasting_score_not_a_passing_one() -> None:
    invariant = _invariant(1.5)
    invariant["params"]["smooth"] = 1.0
    detector = Detector(invariant, {"x.data": 0})
    assert "mean score over 1 s" in detector.expected
    # a spike: the change is 4 for one window (score 3, then -1, -1, -5), the value comes back
    spike = [0.0] * 10 + [4.0] + [0.0] * 9
    assert all(detector.sample(0.25 * k, np.array([v])) is None for k, v in enumerate(spike))
    instant = Detector(_invariant(1.5), {"x.data": 0})  # each sample's own score
    assert [k for k, v in enumerate(spike) if instant.sample(0.25 * k, np.array([v]))] == [10]
    detector.reset()
    ramp = [float(k) for k in range(12)]  # a lasting change: score 2 once the window spans
    alarms = [detector.sample(0.25 * k, np.array([v])) is not None for k, v in enumerate(ramp)]
    assert alarms == [False] * 8 + [True] * 4  # scored from 1 s, weighed from 2 s
