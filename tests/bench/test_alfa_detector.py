"""bench/alfa_detector.py's pieces: the window statistics its variants add (the base ones as
the runtime computes them), the CUSUM, the residual model, the runs a fold learns from and
the fit cut at a horizon. The bench itself is not run (it reads the ALFA flights)."""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from bench import alfa_detector as a
from imrosc import detectors
from imrosc.runtime.detector import features


def test_window_stats_are_the_runtime_statistics() -> None:
    rng = np.random.default_rng(3)
    times = np.cumsum(rng.uniform(0.02, 0.09, 200))
    values = rng.normal(size=(200, 3))
    found = a.window_stats(times, values, 1.0)
    assert np.allclose(found, features(times, values, 1.0))


def test_slope_of_a_ramp_is_its_gradient() -> None:
    times = np.arange(0.0, 5.0, 0.05)
    values = np.column_stack([3.0 * times + 1.0, np.full(len(times), 2.0)])
    slope = a.window_stats(times, values, 1.0, slope=True)[:, 6:]
    assert np.allclose(slope[30:, 0], 3.0)
    assert np.allclose(slope[:, 1], 0.0)


def test_cusum_accumulates_the_score_above_its_drift_in_seconds() -> None:
    times = np.arange(0.0, 4.0, 0.5)
    found = a.cusum(times, np.full(len(times), 3.0), 1.0, 1.0)
    assert all(math.isnan(v) for v in found[:2])
    assert np.allclose(found[2:], 2.0 * (times[2:] - 1.0))
    assert np.allclose(a.cusum(times, np.full(len(times), -3.0), 1.0, 0.0)[2:], 0.0)


def test_residuals_show_a_broken_relation() -> None:
    rng = np.random.default_rng(5)
    x = rng.normal(size=(500, 2))
    kept = np.column_stack([x[:, 0], 2.0 * x[:, 0] + 0.01 * x[:, 1]])
    model = a.Residuals([kept])
    broken = kept.copy()
    broken[:, 1] += 1.0
    assert np.abs(model.of(kept)[:, 1]).mean() < 0.05
    assert np.abs(model.of(broken)[:, 1]).mean() > 0.5


def test_a_fault_flight_gives_its_part_before_the_onset_and_itself_whole() -> None:
    times = np.arange(100.0, 110.0, 0.5)
    info: dict[str, Any] = {"start_ns": 99_000_000_000, "onset_ns": 105_000_000_000, "onset_s": 6.0}
    good: dict[str, Any] = {"start_ns": 99_000_000_000, "onset_ns": None}
    flights = {"f": (info, times, np.ones((20, 1))), "g": (good, times, np.ones((20, 1)))}
    runs = a.runs_of(["f", "g"], flights, lambda t, v: v)
    assert [(r.name, r.onset, len(r.times)) for r in runs] == [
        ("f (before)", None, 10),
        ("f", 6.0, 20),
        ("g", None, 20),
    ]
    assert runs[1].faulty.sum() == 10 and not runs[0].faulty.any()


def test_the_horizon_leaves_the_later_faulty_samples_out_of_the_fit() -> None:
    rng = np.random.default_rng(7)
    times = np.arange(0.0, 20.0, 0.1)
    stats = rng.normal(size=(len(times), 2))
    stats[100:, 0] += 1.0
    stats[130:, 1] += 5.0  # only after the horizon
    runs = [
        detectors.Run("f", 0.0, 10.0, times, stats),
        detectors.Run("g", 0.0, None, times[:100], stats[:100]),
    ]
    cut = a.with_horizon(2.0)(runs, 1.0)
    keep = times < 12.0
    alone = detectors.fit([detectors.Run("f", 0.0, 10.0, times[keep], stats[keep]), runs[1]], 1.0)
    assert np.allclose(cut.weights, alone.weights)
    assert not np.allclose(a.with_horizon(None)(runs, 1.0).weights, cut.weights)
