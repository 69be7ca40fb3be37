"""bench/alfa_detector.py's pieces: the window statistics its variants add (the base ones as
the runtime computes them), the CUSUM, the residual model, the runs a fold learns from and
the fit cut at a horizon. The bench itself is not run (it reads the ALFA flights)."""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from bench import alfa_detector as a
from bench.alfa_detector import products
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


def test_relations_show_a_variable_leaving_what_the_others_say_it_is() -> None:
    rng = np.random.default_rng(11)
    x = rng.normal(size=(800, 3))
    kept = np.column_stack([x[:, 0], 3.0 * x[:, 0] + 0.1 * x[:, 1], x[:, 2]])
    relations = a.Relations(kept)
    assert np.allclose(relations.of(kept).std(axis=0), 1.0)
    broken = kept.copy()
    broken[:, 1] += 1.0  # ten nominal spreads of its relation to the first
    assert np.abs(relations.of(kept)[:, 1]).mean() < 1.0
    assert np.abs(relations.of(broken)[:, 1]).mean() > 5.0
    assert np.abs(relations.of(broken)[:, 2]).mean() < 1.5  # unrelated to the others


def test_products_are_every_pair_once_squares_included() -> None:
    z = np.array([[1.0, 2.0, 3.0]])
    assert products(z).tolist() == [[1.0, 2.0, 3.0, 4.0, 6.0, 9.0]]


def test_squashed_is_odd_about_the_nominal_median_in_its_deviation_units() -> None:
    nominal = np.array([[0.0, 5.0], [1.0, 5.0], [2.0, 5.0], [3.0, 5.0], [4.0, 5.0]])
    rows = np.array([[2.0, 5.0], [3.0, 6.0], [1.0, 4.0], [1002.0, 5.0]])
    found = a.squashed(rows, nominal)
    assert found[0].tolist() == [0.0, 0.0]
    assert math.isclose(found[1, 0], math.asinh(1.0)) and math.isclose(found[1, 1], math.asinh(1.0))
    assert math.isclose(found[2, 0], -found[1, 0])
    assert found[3, 0] < 8.0  # a thousand units away: logarithmic, not linear


def test_probability_evidence_is_the_mean_probability() -> None:
    times = np.arange(0.0, 4.0, 0.5)
    scores = np.array([0.0, 0.0, 0.0, 0.0, math.inf, -math.inf, 0.0, 0.0])
    found = a.probability(times, scores, 1.0, 1.0)
    assert all(math.isnan(v) for v in found[:4])
    assert np.allclose(found[4:], [0.75, 0.5, 0.25, 0.5])


def test_the_mean_of_fold_models_scores_their_mean() -> None:
    rng = np.random.default_rng(13)
    times = np.arange(0.0, 30.0, 0.1)
    stats = rng.normal(size=(len(times), 3)) * [1.0, 5.0, 0.1] + [0.0, 2.0, -1.0]
    stats[200:, 0] += 2.0
    run = detectors.Run("f", 0.0, 20.0, times, stats)
    other = detectors.Run("g", 0.0, 20.0, times, stats[::-1].copy())
    recorded = a.Recorded(detectors.fit)
    models = [recorded([run], 1.0), recorded([run, other], 1.0), recorded([other], 10.0)]
    assert [len(v) for v in recorded.models.values()] == [2, 1]
    mean = a.Linear.mean_of(recorded.models[1.0])
    assert np.allclose(mean.scores(run), (models[0].scores(run) + models[1].scores(run)) / 2)
    recorded.forget()
    assert not recorded.models
