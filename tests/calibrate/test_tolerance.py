"""Prediction bounds and conformal ranks."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy import stats

from imrosc.calibrate.extremes import gumbel_bound
from imrosc.calibrate.tolerance import (
    conformal,
    exponential_bound,
    held_out_score,
    maxima_bound,
    prediction_bound,
    tolerance,
)


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


def score(values: list[float], logarithmic: bool = False) -> float:
    found = held_out_score(values, logarithmic)
    assert found is not None
    return found


def bound(values: list[float], level: float, logarithmic: bool = False) -> float:
    """The normal prediction bound of ``values``, or (``logarithmic``) the log-normal one."""
    found = prediction_bound([math.log(v) for v in values] if logarithmic else values, level)
    assert found is not None
    return math.exp(found) if logarithmic else found


def gumbel(values: list[float], level: float) -> float:
    found = gumbel_bound(values, level)
    assert found is not None
    return found


def maxima(values: list[float], level: float) -> float:
    found = maxima_bound(values, level)
    assert found is not None
    return found


def test_the_held_out_score_is_the_leave_one_out_t_log_density() -> None:
    values = [1.0, 2.0, 4.0, 7.0]
    expected = 0.0
    for k, value in enumerate(values):
        others = values[:k] + values[k + 1 :]
        spread = float(np.std(others, ddof=1)) * math.sqrt(1 + 1 / 3)
        expected += stats.t.logpdf((value - np.mean(others)) / spread, 2) - math.log(spread)
    assert score(values) == pytest.approx(expected, rel=1e-9)
    logged = [math.log(v) for v in values]
    assert score(values, logarithmic=True) == pytest.approx(score(logged) - sum(logged), rel=1e-9)
    assert held_out_score([1.0, 2.0]) is None
    assert held_out_score([0.0, 1.0, 2.0], logarithmic=True) is None


def test_the_choice_of_model_does_not_depend_on_the_unit() -> None:
    """Both scores are densities of the values themselves: a change of unit shifts both by
    the same amount, so metres and millimetres choose alike."""
    values = [0.0253, 0.0455, 0.0298, 0.0073, 0.024, 0.0332]
    scaled_values = [1000 * v for v in values]
    gap = score(values) - score(values, logarithmic=True)
    scaled_gap = score(scaled_values) - score(scaled_values, logarithmic=True)
    assert gap == pytest.approx(scaled_gap, rel=1e-9)
    assert maxima(scaled_values, 1e-4) == pytest.approx(1000 * maxima(values, 1e-4))


def test_the_exponential_bound_is_the_f_quantile_of_one_new_value_over_the_mean() -> None:
    """For exponential draws, a new one over the mean of ``n`` is F(2, 2n)-distributed."""
    values = [0.0, 0.0, 11.2, 0.0, 5.9, 5.4]
    expected = float(np.mean(values)) * float(stats.f.ppf(1 - 0.00625, 2, 12))
    assert exponential_bound(values, 0.00625) == pytest.approx(expected, rel=1e-9)
    assert exponential_bound([2.0], 0.05) == pytest.approx(2.0 * stats.f.ppf(0.95, 2, 2))
    assert exponential_bound([], 0.05) is None
    assert exponential_bound([0.0, 0.0], 0.05) == 0.0


def test_the_exponential_bound_covers_new_exponential_draws_at_its_level() -> None:
    """Exact for exponential draws, whatever their scale; a normal bound of the same draws
    is passed far more often than its level says."""
    rng = np.random.default_rng(7)
    trials, misses, normal_misses = 4000, 0, 0
    for _ in range(trials):
        draws = rng.exponential(rng.uniform(0.1, 50.0), size=7)
        bound = exponential_bound(list(draws[:6]), 0.05)
        assert bound is not None
        misses += draws[6] > bound
        normal_misses += draws[6] > (prediction_bound(list(draws[:6]), 0.01) or 0.0)
    assert 0.04 < misses / trials < 0.06
    assert normal_misses / trials > 0.02


def test_maxima_bound_takes_the_model_that_predicts_held_out_units_better() -> None:
    """Sixteen units' positive maxima drawn Gumbel (alike from run to run: the maxima of
    sensor noise, as spread as they are far from 0) or log-normal: each model is chosen for
    its own draws far more often than not. (Gumbel draws far from 0 against their spread
    look log-normal as well, and the log-normal bound, the further one, is then taken.)"""
    rng = np.random.default_rng(5)
    level = 1e-4
    gumbel_picked = lognormal_picked = drawn = 0
    while drawn < 100:
        alike = list(rng.gumbel(1.0, 1.0, size=16))
        if min(alike) <= 0:
            continue  # no logarithm: the Gumbel model alone (the next test)
        drawn += 1
        spread = list(rng.lognormal(0.0, 1.5, size=16))
        gumbel_picked += maxima(alike, level) == gumbel_bound(alike, level)
        lognormal_picked += maxima(spread, level) == pytest.approx(bound(spread, level, True))
    assert gumbel_picked > 60 and lognormal_picked > 90


def test_maxima_bound_keeps_the_larger_bound_when_the_units_cannot_tell() -> None:
    few = [0.02, 0.03]  # too few to hold one out and predict it from the rest
    larger = max(gumbel(few, 0.01), bound(few, 0.01, True))
    assert maxima(few, 0.01) == pytest.approx(larger)
    alike = [0.02, 0.02, 0.03]  # held out, the 0.03's others are all alike
    assert maxima(alike, 0.01) == pytest.approx(bound(alike, 0.01, True))
    # a unit whose largest step is 0 has no logarithm: the Gumbel model alone
    assert maxima([0.0, 0.1, 0.2], 0.01) == gumbel([0.0, 0.1, 0.2], 0.01)
    assert maxima_bound([0.1], 0.01) is None


def test_the_larger_bound_is_the_normal_or_log_normal_one() -> None:
    """Without ``select`` (``step_tail="larger"``): the larger of the normal and log-normal
    bounds, the normal one alone where some value is not positive."""
    values = [0.0253, 0.0455, 0.0298, 0.0073, 0.024, 0.0332]
    assert maxima_bound(values, 1e-4, select=False) == pytest.approx(bound(values, 1e-4, True))
    assert maxima_bound([0.0, 0.1, 0.2], 0.01, select=False) == bound([0.0, 0.1, 0.2], 0.01)
