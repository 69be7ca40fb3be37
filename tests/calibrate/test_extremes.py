"""The Gumbel model of a run's largest value: its predictive law, bound and held-out score."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy import integrate, stats

from imrosc.calibrate.extremes import GumbelFit, gumbel_bound, gumbel_score
from imrosc.calibrate.tolerance import prediction_bound


def fit_of(values: list[float]) -> GumbelFit:
    found = GumbelFit.of(values)
    assert found is not None
    return found


def brute_survival(values: list[float], x: float) -> float:
    """``P(new > x)`` by integrating the Gumbel likelihood times ``1 / sigma`` over both the
    location and the scale on a plain grid (no closed form)."""
    data = np.asarray(values)
    mus = np.linspace(data.min() - 6, data.max() + 6, 1201)
    sigmas = np.exp(np.linspace(-4, 4, 801))
    mu, sigma = np.meshgrid(mus, sigmas, indexing="ij")
    z = (data[None, None, :] - mu[..., None]) / sigma[..., None]
    loglik = np.sum(-z - np.exp(-z), axis=2) - len(values) * np.log(sigma)
    # the prior 1/sigma times d sigma = sigma d log(sigma): the grid's even steps in log(sigma)
    weight = np.exp(loglik - loglik.max())
    tail = stats.gumbel_r.sf(x, loc=mu, scale=sigma)
    return float(np.sum(weight * tail) / np.sum(weight))


def test_the_location_integrates_out_in_closed_form() -> None:
    values = [0.3, 1.1, 0.7, 2.4, 0.9]
    fit = fit_of(values)
    for x in (1.0, 3.0, 6.0):
        assert math.exp(fit.log_survival(x)) == pytest.approx(brute_survival(values, x), rel=1e-3)


def test_the_predictive_density_is_the_survival_s_derivative() -> None:
    fit = fit_of([0.0253, 0.0455, 0.0298, 0.0073, 0.024, 0.0332])

    def density(x: float) -> float:
        return math.exp(float(fit.log_density(np.array([x]))[0]))

    total, _ = integrate.quad(density, -1.0, 5.0, limit=400)
    assert total == pytest.approx(1.0, abs=1e-6)
    beyond, _ = integrate.quad(density, 0.05, 5.0, limit=400)
    assert beyond == pytest.approx(math.exp(fit.log_survival(0.05)), rel=1e-5)


def test_the_bound_covers_new_gumbel_draws_at_its_level() -> None:
    """Exact coverage whatever the location and scale (the prior is the right Haar one)."""
    rng = np.random.default_rng(11)
    trials = 2000
    for n, level in ((4, 0.05), (16, 0.02)):
        misses = 0
        for _ in range(trials):
            draws = rng.gumbel(rng.uniform(-5.0, 5.0), rng.uniform(0.01, 10.0), size=n + 1)
            bound = gumbel_bound(list(draws[:n]), level)
            assert bound is not None
            misses += draws[n] > bound
        assert abs(misses / trials - level) < 4 * math.sqrt(level * (1 - level) / trials)


def test_the_normal_bound_of_gumbel_maxima_is_passed_more_often_than_its_level() -> None:
    """Far in the tail a normal model of maxima puts its bound too close: at 1e-3, sixteen
    Gumbel draws' normal bound is passed about four times as often."""
    rng = np.random.default_rng(13)
    trials = 20000
    draws = rng.gumbel(0.0, 1.0, size=(trials, 17))
    misses = sum(row[16] > (prediction_bound(list(row[:16]), 1e-3) or math.inf) for row in draws)
    assert misses / trials > 3 * 1e-3


def test_the_bound_moves_with_the_values_location_and_scale() -> None:
    values = [0.0253, 0.0455, 0.0298, 0.0073, 0.024, 0.0332]
    bound = gumbel_bound(values, 1e-4)
    moved = gumbel_bound([7.0 + 1000 * v for v in values], 1e-4)
    assert bound is not None and moved is not None
    assert moved == pytest.approx(7.0 + 1000 * bound, rel=1e-9)
    assert max(values) < bound < (prediction_bound(values, 1e-6) or 0.0)
    assert gumbel_bound([0.5], 0.01) is None
    assert gumbel_bound([0.5, 0.5, 0.5], 0.01) == 0.5


def test_the_score_is_the_sum_of_the_held_out_log_densities() -> None:
    values = [1.0, 2.0, 4.0, 7.0, 3.5]
    expected = sum(
        float(fit_of(values[:k] + values[k + 1 :]).log_density(np.array([value]))[0])
        for k, value in enumerate(values)
    )
    assert gumbel_score(values) == pytest.approx(expected, rel=1e-12)
    # a density of the values themselves: a change of unit shifts it by n log(scale)
    scaled = gumbel_score([1000 * v for v in values])
    assert scaled == pytest.approx(expected - 5 * math.log(1000), rel=1e-9)
    assert gumbel_score([1.0, 2.0]) is None
    assert gumbel_score([3.0, 3.0, 5.0]) is None
