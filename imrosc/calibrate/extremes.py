"""The largest of a run's many values: a Gumbel model whose location and scale are unknown.

A run's largest step is the maximum of thousands of steps. Where the steps are sensor noise
(normal, or with any tail that falls off exponentially) their maximum is, after location
and scale, Gumbel-distributed: the extreme-value limit of such maxima (Fisher and Tippett
1928, Gnedenko 1943), ``F(x) = exp(-exp(-(x - mu) / sigma))``. Its upper tail is
exponential, heavier than the normal model's and far lighter than the log-normal one's.

One more unit's largest value is predicted from ``n`` units' by the Bayesian predictive
law under the prior ``1 / sigma``. For a location-scale family that prior is the right
Haar measure, and the predictive bound's frequentist coverage is then exact whatever
``mu`` and ``sigma`` are (the invariant prediction of Hora and Buehler 1967; Severini,
Mukerjee and Ghosh 2002): the Gumbel counterpart of the normal model's Student-t bound.

Given ``sigma`` the location integrates out in closed form. With ``A(sigma) = sum of
exp(-x_i / sigma)``, ``exp(mu / sigma)`` is Gamma(``n``, ``A``)-distributed a posteriori,
so a new value stays below ``x`` with probability ``(1 + exp(-x / sigma) / A)^(-n)``, and
``sigma``'s posterior is proportional to ``sigma^(-n) exp(-sum(x_i) / sigma) A^(-n)``: one
integral, over ``log(sigma)`` on a grid, of closed forms.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from scipy import optimize

_POINTS = 401
"""Grid points over ``log(sigma)`` (in units of the values' standard deviation): the
integrand is smooth and falls off at both ends, so the sum converges fast (401 and 8,001
points give bounds alike to 1e-14)."""
_LOWEST = -7.0
"""The grid's smallest ``log(sigma)``: below it the posterior is nil (its density falls
as ``exp(-c / sigma)``)."""


def _logsumexp(values: np.ndarray, axis: int = -1) -> np.ndarray:
    """``log(sum(exp(values)))`` along ``axis`` (finite values; scipy's checks cost more
    than the sum at this size)."""
    top = np.max(values, axis=axis, keepdims=True)
    summed = np.log(np.sum(np.exp(values - top), axis=axis, keepdims=True)) + top
    return np.asarray(np.squeeze(summed, axis=axis))


@dataclass(frozen=True)
class GumbelFit:
    """The posterior of ``sigma`` given ``n`` values, on a grid of ``log(sigma)``, the
    values standardised (``mean``, ``sd``: how to go back); a batch of such fits, one per
    row, for the held-out score (each value's others, :meth:`held_out`)."""

    count: int
    mean: np.ndarray
    """``(batch,)``: the values' mean per fit."""
    sd: np.ndarray
    """``(batch,)``: their standard deviation."""
    sigmas: np.ndarray
    """``(points,)``: the grid, in units of ``sd``."""
    log_weights: np.ndarray
    """``(batch, points)``: each grid point's posterior mass, logged (summing to 1)."""
    log_sums: np.ndarray
    """``(batch, points)``: ``log A(sigma)`` at each grid point."""

    @classmethod
    def of(cls, values: Sequence[float]) -> GumbelFit | None:
        """The fit of at least two ``values`` not all alike (``None`` otherwise)."""
        if len(values) < 2:
            return None
        return cls._batch(np.asarray(values, dtype=np.float64)[None, :])

    @classmethod
    def held_out(cls, values: Sequence[float]) -> GumbelFit | None:
        """Row ``k``: the fit of every value but the ``k``-th (``None`` with fewer than
        three values, or when some value's others are all alike)."""
        n = len(values)
        if n < 3:
            return None
        raw = np.asarray(values, dtype=np.float64)
        others = np.array([np.delete(raw, k) for k in range(n)])
        return cls._batch(others)

    @classmethod
    def _batch(cls, raw: np.ndarray) -> GumbelFit | None:
        n = raw.shape[1]
        mean, sd = raw.mean(axis=1), raw.std(axis=1, ddof=1)
        if not np.all(sd > 0) or not np.all(np.isfinite(sd)):
            return None
        scaled = (raw - mean[:, None]) / sd[:, None]
        # sigma's posterior falls as sigma^(1-n) in log(sigma) past the values' spread:
        # the grid ends where it has fallen by exp(-45)
        logs = np.linspace(_LOWEST, 1.0 + 45.0 / (n - 1), _POINTS)
        sigmas = np.exp(logs)
        sums = _logsumexp(-scaled[:, None, :] / sigmas[None, :, None])
        # the density in log(sigma): sigma^(-n) exp(-sum / sigma) A^(-n) times sigma
        logp = (1 - n) * logs[None, :] - scaled.sum(axis=1)[:, None] / sigmas[None, :] - n * sums
        logp = logp - _logsumexp(logp)[:, None]
        return cls(n, mean, sd, sigmas, logp, sums)

    def _exponents(self, x: np.ndarray) -> np.ndarray:
        """``log(exp(-z / sigma) / A)`` per fit and grid point, ``z`` the standardised ``x``
        (one per fit)."""
        z = (x - self.mean) / self.sd
        return np.asarray(-z[:, None] / self.sigmas[None, :] - self.log_sums)

    def log_survival(self, x: float) -> float:
        """``log P(new > x)`` (of the first fit)."""
        t = self._exponents(np.array([x]))[0]
        # P(new <= x | sigma) = exp(-s), s = n log(1 + e^t); log(1 - exp(-s)) kept exact
        # for tiny s, where the survival is about s
        log_soft = np.where(t < -30.0, t, np.log(np.logaddexp(0.0, np.maximum(t, -30.0))))
        log_s = math.log(self.count) + log_soft
        s = np.exp(log_s)
        small = s < 1e-8
        logged = np.where(small, log_s - s / 2, np.log(-np.expm1(-np.where(small, 1.0, s))))
        return float(_logsumexp(self.log_weights[0] + logged))

    def log_density(self, x: np.ndarray) -> np.ndarray:
        """The log predictive density of a new value at ``x``, one per fit."""
        t = self._exponents(np.asarray(x, dtype=np.float64))
        n = self.count
        # d/dx (1 + e^t)^(-n) = n (1 + e^t)^(-n-1) e^t / (sigma sd)
        each = math.log(n) - (n + 1) * np.logaddexp(0.0, t) + t - np.log(self.sigmas)[None, :]
        return np.asarray(_logsumexp(self.log_weights + each) - np.log(self.sd))

    def bound(self, alpha: float) -> float:
        """The ``1 - alpha`` predictive bound of a new value (of the first fit; ``inf`` past
        any float)."""
        target = math.log(alpha)
        mean, sd = float(self.mean[0]), float(self.sd[0])

        def excess(z: float) -> float:
            return self.log_survival(mean + sd * z) - target

        low, high = -1.0, 1.0
        while excess(low) < 0:
            low *= 2
        while excess(high) > 0:
            high *= 2
            if high > 1e300 / max(1.0, sd):
                return math.inf
        return mean + sd * float(optimize.brentq(excess, low, high, xtol=1e-12))


def gumbel_bound(values: Sequence[float], alpha: float) -> float | None:
    """The ``1 - alpha`` prediction bound of one more of ``values`` under a Gumbel model
    whose location and scale are unknown (the module's docstring): exact coverage for
    Gumbel values. ``None`` with fewer than two values; their value when all alike.

    >>> round(gumbel_bound([1.0, 2.0, 3.0], 0.05), 3)  # the normal bound: 5.372
    6.693
    >>> gumbel_bound([4.0, 4.0], 0.05), gumbel_bound([4.0], 0.05)
    (4.0, None)
    """
    if len(values) < 2:
        return None
    fit = GumbelFit.of(values)
    return float(values[0]) if fit is None else fit.bound(alpha)


def gumbel_score(values: Sequence[float]) -> float | None:
    """How well the Gumbel model predicts each of the values from the others: the sum of
    the log predictive density of each value given the others (the leave-one-out
    pseudo-likelihood of :func:`.tolerance.held_out_score`). ``None`` with fewer than three
    values, or when some value's others are all alike.

    >>> round(gumbel_score([1.0, 2.0, 4.0, 7.0]), 3)
    -11.155
    >>> gumbel_score([1.0, 2.0]), gumbel_score([1.0, 1.0, 2.0])
    (None, None)
    """
    fits = GumbelFit.held_out(values)
    if fits is None:
        return None
    return float(np.sum(fits.log_density(np.asarray(values, dtype=np.float64))))
