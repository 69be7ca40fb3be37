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


def test_rounded_supports_carry_their_rounding_s_variance() -> None:
    """Six units that all counted 50 messages: without the correction a new run counts 50
    for certain; with it, the spread is that of a value rounded to one message."""
    counts = [50.0] * 6
    assert prediction_bound(counts, 0.01) == 50.0
    bound = prediction_bound(counts, 0.01, resolution=1.0)
    # sd = sqrt(1/12); t_5(0.99) = 3.364930
    expected = 50.0 + 3.364930 * math.sqrt(1 / 12) * math.sqrt(1 + 1 / 6)
    assert bound == pytest.approx(expected, rel=1e-6)
    spread = [49.0, 50.0, 51.0, 50.0]
    plain, rounded = prediction_bound(spread, 0.05), prediction_bound(spread, 0.05, 1.0)
    assert plain is not None and rounded is not None and rounded > plain
    widened = tolerance(counts, 50.0, 0.01, resolution=1.0)
    assert widened == pytest.approx(expected - 50.0, rel=1e-6)


def test_rounded_counts_of_a_steady_rate_are_covered_at_their_level() -> None:
    """Counts of a steady rate (about 50 in a window, a third of a message of spread),
    rounded: the uncorrected bound, often from six equal counts, is exceeded by a new count
    more often than its level says; the corrected one is not."""
    rng = np.random.default_rng(5)
    plain = corrected = 0
    trials = 4000
    for _ in range(trials):
        counts = np.round(rng.normal(50.0, 0.3, size=7))
        seen = list(counts[:6])
        plain += counts[6] > (prediction_bound(seen, 0.01) or math.inf)
        corrected += counts[6] > (prediction_bound(seen, 0.01, resolution=1.0) or math.inf)
    assert plain / trials > 0.02
    assert corrected / trials <= 0.01
