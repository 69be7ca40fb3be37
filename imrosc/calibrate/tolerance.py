"""How far beyond the runs seen a new run may go: prediction bounds and conformal ranks.

A limit's supports ``h_1..h_n`` (how far each unit went, in the limit's scale) are taken
as draws from the distribution of a run's extreme. The next run's extreme stays below

    mean(h) + t_{n-1}(1 - alpha) * sd(h) * sqrt(1 + 1/n)

with probability ``1 - alpha`` when the extremes are normal (the classical prediction
interval for one new observation with unknown mean and variance). The tolerance is how
far that bound lies beyond the envelope; it is 0 when the envelope already reaches it.

Supports known only to a resolution ``q`` (whole messages in a window for a frequency,
whole events for an ordered pair) are rounded values: their spread is estimated with
Sheppard's correction, ``sd^2 + q^2 / 12``, the variance a value rounded to ``q`` carries.
Without it a handful of units that all counted 50 messages would say a new run counts 50
for certain, and one message less would break the limit.

Counts that decide an alarm rule use the distribution-free conformal rank instead: with
``n`` held-out units, the ``ceil((1 - alpha) (n + 1))``-th smallest value is exceeded by a
new exchangeable unit with probability at most ``alpha``. With too few units for the
budget the rank is past ``n`` and the budget is not certified (:func:`conformal` says
so); the rule then takes the prediction bound above, or the same bound in ``log(1 + x)``
when it reaches further (:func:`skewed_bound`: such counts are non-negative and skewed;
``imrosc.calibrate.rule.threshold``).
"""

from __future__ import annotations

import functools
import math
from collections.abc import Sequence

import numpy as np
from scipy import stats

from imrosc.calibrate.extremes import gumbel_bound, gumbel_score


def prediction_bound(
    values: Sequence[float], alpha: float, resolution: float = 0.0
) -> float | None:
    """The one-sided ``1 - alpha`` normal prediction bound of one more value (``None``
    with fewer than two values); ``resolution``: the values are rounded to it (Sheppard's
    correction, see the module's docstring).

    >>> round(prediction_bound([1.0, 2.0, 3.0], 0.05), 3)
    5.372
    >>> prediction_bound([4.0, 4.0], 0.05)
    4.0
    >>> round(prediction_bound([4.0, 4.0, 4.0], 0.05, resolution=1.0), 3)
    4.973
    """
    n = len(values)
    if n < 2:
        return None
    mean = math.fsum(values) / n
    variance = math.fsum([(v - mean) ** 2 for v in values]) / (n - 1)
    sd = math.sqrt(variance + resolution * resolution / 12.0)
    if sd == 0:
        return mean
    return mean + _t_quantile(1 - alpha, n - 1) * sd * math.sqrt(1 + 1 / n)


def skewed_bound(values: Sequence[float], alpha: float, resolution: float = 0.0) -> float | None:
    """The larger of :func:`prediction_bound` and the same bound taken in ``log(1 + v)``
    (a log-normal model) of non-negative ``values`` (``None`` with fewer than two).

    A held-out unit's longest episode or largest agreement is a non-negative count whose
    spread spans orders of magnitude (ALFA's flights: 0 to 1,170 samples); a normal model
    of such maxima puts its tail too close, and a new run beyond every held-out unit
    then comes far more often than the budget says. The logarithm's bound reaches as far
    as such a tail does; the normal one (with the counts' Sheppard correction) still
    rules when the values are alike.

    >>> round(skewed_bound([9, 1, 22, 4, 3, 2, 2, 8, 4, 1, 3, 1, 3, 7, 9, 5], 0.05 / 3, 1.0), 1)
    24.8
    >>> round(skewed_bound([4.0, 4.0, 4.0], 0.05, resolution=1.0), 3)
    4.973
    """
    bound = prediction_bound(values, alpha, resolution)
    if bound is None or min(values) < 0:
        return bound
    logged = prediction_bound([math.log1p(v) for v in values], alpha)
    return bound if logged is None else max(bound, math.expm1(logged))


def exponential_bound(values: Sequence[float], alpha: float) -> float | None:
    """The ``1 - alpha`` prediction bound of one more of the non-negative ``values`` under an
    exponential model whose scale is unknown: a new value over the mean of ``n`` is
    F(2, 2n)-distributed, whose ``1 - alpha`` quantile is ``n (alpha^(-1/n) - 1)`` (``None``
    without values). Exact for exponential values, whatever their scale.

    >>> round(exponential_bound([1.0, 2.0, 3.0], 0.05), 3)
    10.287
    >>> exponential_bound([0.0, 0.0], 0.05), exponential_bound([], 0.05)
    (0.0, None)
    """
    n = len(values)
    if n == 0:
        return None
    return math.fsum(values) * (math.pow(alpha, -1.0 / n) - 1.0)


def held_out_score(values: Sequence[float], logarithmic: bool = False) -> float | None:
    """How well a normal model of the values predicts each of them from the others: the sum,
    over the values, of the log density of the value under the prediction the others give
    (Student's t with ``n - 2`` degrees of freedom about their mean, scaled by their
    standard deviation times ``sqrt(1 + 1/(n - 1))``: the law of one new value whose mean
    and variance are unknown). ``logarithmic``: the model is normal in ``log(v)`` (a
    log-normal model of positive values), and each density is that of ``v`` (divided by
    ``v``), so the two scores compare. ``None`` with fewer than three values, or when some
    value's others are all alike (no density to score).

    Two models' scores compare as a leave-one-out pseudo-likelihood (Geisser and Eddy,
    1979): the higher is the model under which the values held out in turn were likelier.

    >>> spread = [0.0253, 0.0455, 0.0298, 0.0073, 0.024, 0.0332]
    >>> held_out_score(spread) > held_out_score(spread, logarithmic=True)
    True
    >>> tail = [0.5, 0.7, 1.0, 2.0, 6.0, 40.0]
    >>> held_out_score(tail) < held_out_score(tail, logarithmic=True)
    True
    >>> held_out_score([1.0, 2.0]), held_out_score([1.0, 1.0, 2.0])
    (None, None)
    """
    n = len(values)
    if n < 3 or (logarithmic and min(values) <= 0):
        return None
    scale = np.log(values) if logarithmic else np.asarray(values, dtype=np.float64)
    # each value's others: their mean and (unbiased) variance, all at once
    means = (scale.sum() - scale) / (n - 1)
    squares = np.array([np.sum((np.delete(scale, k) - means[k]) ** 2) for k in range(n)])
    sds = np.sqrt(squares / (n - 2))
    if not np.all(sds > 0):
        return None
    spreads = sds * math.sqrt(1 + 1 / (n - 1))
    densities = stats.t.logpdf((scale - means) / spreads, n - 2) - np.log(spreads)
    if logarithmic:
        densities = densities - scale  # the density of v = exp(value): divided by v
    return float(np.sum(densities))


def exp_or_inf(logged: float) -> float:
    """``exp(logged)``, or ``inf`` past the largest float (a bound taken in the logarithm).

    >>> exp_or_inf(0.0), exp_or_inf(1000.0)
    (1.0, inf)
    """
    return math.exp(logged) if logged < 700 else math.inf


def lognormal_bound(values: Sequence[float], alpha: float) -> float:
    """The ``1 - alpha`` prediction bound of one more of the positive ``values`` taken in the
    logarithm (``inf`` past any float; the values' smallest when they are too few).

    >>> round(lognormal_bound([1.0, 10.0, 100.0], 0.05), 1) > 100
    True
    """
    logged = prediction_bound([math.log(v) for v in values], alpha)
    return min(values) if logged is None else exp_or_inf(logged)


def maxima_bound(values: Sequence[float], alpha: float, select: bool = True) -> float | None:
    """The ``1 - alpha`` prediction bound of one more of the ``values`` (units' largest
    steps), ``None`` with fewer than two values.

    ``select``: the bound of the model, Gumbel (:func:`.extremes.gumbel_bound`) or
    log-normal, that predicts the values held out in turn the better (:func:`held_out_score`,
    :func:`.extremes.gumbel_score`); the larger of the two bounds when the scores cannot tell
    (fewer than three values, or values alike); the Gumbel bound when some value is not
    positive (no logarithm). Without ``select``: the larger of the normal and the
    log-normal bounds (the normal one alone when some value is not positive).

    The largest step of a run is a maximum of many steps. Where steps are sensor noise, the
    runs' largest steps are alike and their law is the extreme-value limit of such maxima,
    the Gumbel law, whose exponential tail lies beyond the normal model's: far in the tail,
    where the margins' levels are, the normal bound of a dozen runs' largest steps is passed
    by a run of a new day. Where jumps are part of normal operation (a waypoint switch moves
    a track error by whatever the geometry gives), their spread is multiplicative and only
    the logarithm's tail reaches as far as the next run goes. Taking the larger bound always
    keeps the log-normal tail even where the units say their steps are alike: with six
    units its bound at the margins' level lies orders of magnitude beyond every step seen.

    >>> alike = [0.0253, 0.0455, 0.0298, 0.0073, 0.024, 0.0332]
    >>> maxima_bound(alike, 1e-4) == gumbel_bound(alike, 1e-4)
    True
    >>> round(maxima_bound(alike, 1e-4), 3), round(maxima_bound(alike, 1e-4, select=False), 1)
    (0.275, 17.4)
    >>> tail = [0.5, 0.7, 1.0, 2.0, 6.0, 40.0]
    >>> maxima_bound(tail, 1e-4) == lognormal_bound(tail, 1e-4)
    True
    """
    positive = bool(values) and min(values) > 0
    if not select:
        normal = prediction_bound(values, alpha)
        if normal is None or not positive:
            return normal
        return max(normal, lognormal_bound(values, alpha))
    gumbel = gumbel_bound(values, alpha)
    if gumbel is None or not positive:
        return gumbel
    lognormal = lognormal_bound(values, alpha)
    light, heavy = gumbel_score(values), held_out_score(values, logarithmic=True)
    if light is None or heavy is None:
        return max(gumbel, lognormal)
    return lognormal if heavy > light else gumbel


@functools.lru_cache(maxsize=4096)
def _t_quantile(level: float, freedom: int) -> float:
    return float(stats.t.ppf(level, freedom))


def tolerance(
    supports: Sequence[float], base: float, alpha: float, resolution: float = 0.0
) -> float | None:
    """How far to move a limit at ``base`` so that a new run's extreme stays inside with
    probability ``1 - alpha`` (``None``: too few supports to tell); ``resolution``: the
    supports are whole multiples of it (counts).

    >>> tolerance([1.0, 2.0, 3.0], 3.0, 0.05) > 2
    True
    >>> tolerance([1.0, 1.0, 1.0], 1.0, 0.05)
    0.0
    >>> tolerance([1.0, 1.0, 1.0], 1.0, 0.05, resolution=1.0) > 0.5
    True
    """
    finite = list(filter(math.isfinite, supports))
    if not math.isfinite(base) or len(finite) < len(supports):
        return 0.0  # the envelope already reaches its end (a zero variance, say)
    bound = prediction_bound(finite, alpha, resolution)
    if bound is None:
        return None
    return max(0.0, bound - max(base, *finite))


def tolerances(
    rows: Sequence[Sequence[float]],
    bases: Sequence[float | None],
    alpha: float,
    resolutions: Sequence[float],
) -> list[float | None]:
    """:func:`tolerance` of each limit: its units' supports (a row), its base and its
    resolution (a ``None`` base gives ``None``).

    >>> rows = [[1.0, 2.0, 3.0], [1.0, 1.0, 1.0], [1.0, math.inf, 1.0]]
    >>> tolerances(rows, [3.0, 1.0, None], 0.05, [0.0, 1.0, 0.0]) == [
    ...     tolerance([1.0, 2.0, 3.0], 3.0, 0.05), tolerance([1.0, 1.0, 1.0], 1.0, 0.05, 1.0), None]
    True
    """
    return [
        None if base is None else tolerance(row, base, alpha, resolution)
        for row, base, resolution in zip(rows, bases, resolutions, strict=True)
    ]


def too_many(breaks: int, units: int, alpha: float) -> bool:
    """Whether ``breaks`` of ``units`` held-out units breaking an invariant are more than a
    per-run break probability of ``alpha`` explains (a one-sided binomial test at level
    ``alpha``).

    >>> [too_many(b, 6, 0.05) for b in (1, 2)]
    [False, True]
    >>> [too_many(b, 17, 0.05) for b in (3, 4)]
    [False, True]
    """
    return breaks > int(stats.binom.ppf(1 - alpha, units, alpha))


def conformal(values: Sequence[float], alpha: float) -> tuple[float, bool]:
    """The conformal ``1 - alpha`` rank of ``values`` and whether ``len(values)`` units are
    enough to certify ``alpha`` (else the largest value).

    >>> conformal(list(range(1, 40)), 0.05)
    (38, True)
    >>> conformal([3, 1, 2], 0.05)
    (3, False)
    """
    ordered = sorted(values)
    rank = math.ceil((1 - alpha) * (len(ordered) + 1))
    if rank > len(ordered):
        return (ordered[-1] if ordered else 0), False
    return ordered[rank - 1], True
