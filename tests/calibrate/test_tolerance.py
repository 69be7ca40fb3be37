"""Prediction bounds and conformal ranks."""

from __future__ import annotations

import math

import numpy as np
import pytest

from imrosc.calibrate.tolerance import conformal, prediction_bound, tolerance


def test_the_prediction_bound_is_the_t_interval_of_one_new_value() -> None:
    values = [1.0, 2.0, 4.0, 7.0]
    mean, sd = float(np.mean(values)), float(np.std(values, ddof=1))
    # t_{3}(0.95) = 2.353363
    expected = mean + 2.353363 * sd * math.sqrt(1 + 1 / 4)
    assert prediction_bound(values, 0.05) == pytest.approx(expected, rel=1e-6)
    assert prediction_bound([3.0], 0.05) is None


def test_the_bound_covers_new_draws_at_its_level() -> None:
    rng = np.random.default_rng(3)
    misses = 0
    trials = 4000
    for _ in range(trials):
        draws = rng.normal(10.0, 2.0, size=9)
        bound = prediction_bound(list(draws[:8]), 0.1)
        assert bound is not None
        misses += draws[8] > bound
    assert 0.08 < misses / trials < 0.12


def test_tolerance_is_how_far_past_the_envelope() -> None:
    assert tolerance([1.0, 1.0, 1.0], 1.0, 0.05) == 0.0
    widened = tolerance([1.0, 2.0, 3.0], 3.0, 0.05)
    assert widened is not None and widened > 0
    assert tolerance([1.0, 2.0, 3.0], 100.0, 0.05) == 0.0  # the envelope reaches further
    assert tolerance([2.0], 2.0, 0.05) is None
    assert tolerance([math.inf, 1.0], math.inf, 0.05) == 0.0


def test_conformal_rank_and_when_it_certifies() -> None:
    assert conformal(list(range(1, 100)), 0.1) == (90, True)
    assert conformal([5, 1, 9], 0.05) == (9, False)
    assert conformal([], 0.05) == (0, False)
