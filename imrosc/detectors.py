"""Fault detectors learnt by classification (``<check detector="logistic">``).

An invariant learnt from good runs alone says what the runs kept; it cannot say which of
the ways a new run differs matter. With failed runs whose faults have an onset,
classification can also learn that: per publish point, a *detector* (family ``detector``,
:mod:`imrosc.runtime.detector`) scores each sample from the mean, standard deviation and
change of each of the point's variables over the trailing window, and alarms above a
threshold. How it is learnt (``docs/families/detector.md``):

1. **Fit** an L2-regularised logistic regression (Newton's method on standardised
   statistics, the two classes weighted equally): every sample of a good run and the
   samples of a failed run before its onset are nominal, the samples from the onset on
   faulty.
2. **Evidence**: a sample's score is the log-odds that its run is faulty; the evidence is
   their mean over the trailing ``smooth`` seconds, from :data:`SMOOTHING`. A fault
   persists where a good run's odd moment passes, so a mean over a few seconds separates
   them better than one sample's score, at the cost of a delay of up to ``smooth``.
3. **Threshold, cross-fitted**: the runs are cut into blocked folds by their start (as
   calibration cuts its units); each fold's runs are scored by a model fitted without them.
   Each held-out run's largest evidence while nominal is a draw of a good run's extreme;
   the threshold is the largest of them, raised to their one-sided normal prediction bound
   at the detector's share ``alpha`` of the false-alarm budget when that lies higher
   (:func:`imrosc.calibrate.tolerance.prediction_bound`, as calibration bounds an
   envelope). With ``n`` held-out runs the largest alone is exceeded by a new good run
   with probability about ``1/(n+1)``; classification gives each of a document's ``m``
   detectors ``budget / m`` (Bonferroni), so that a monitor of several detectors keeps the
   budget per run, not each of them.
4. **Penalty and smoothing**, from :data:`PENALTIES` x :data:`SMOOTHING`: the pair whose
   cross-fitted evidence detects the most held-out failed runs (evidence above the
   threshold from the onset on), the smallest mean delay on ties, then the strongest
   penalty and the shortest smoothing. No detector is kept when none detects one.
5. **Refusal**: a detector blind to faults still "detects" a held-out failed run whose
   largest evidence soon after the onset (within the shortest held-out nominal
   stretch's length) lies above the ``n`` held-out nominal extremes, with probability at
   most ``1/(n+1)`` (exchangeable ranks). The best pair is kept only when the binomial
   probability of as many such detections among the held-out failed runs is within its
   share ``alpha`` (:attr:`Choice.separates`); otherwise :func:`learn` gives
   :class:`Refused`.

The runs it detected, held out, and its estimated false-alarm probability are what
classification's selection weighs it by, as it weighs every invariant.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any, NamedTuple

import numpy as np
from threadpoolctl import threadpool_limits

from imrosc.calibrate.tolerance import prediction_bound
from imrosc.folds import blocked
from imrosc.invariants import hashed_id
from imrosc.runtime.detector import evidence, features, spans
from imrosc.runtime.families import DETECTOR
from imrosc.runtime.points import Pairing

WINDOW = 1.0
"""Seconds of the trailing window of the statistics."""
PENALTIES = (1.0, 10.0, 100.0, 1e3, 1e4, 1e5)
"""The L2 penalties (on the standardised weights) the cross-fitting chooses from."""
SMOOTHING = (0.0, 0.5, 1.0, 2.0, 4.0)
"""Seconds of the trailing mean of the scores the cross-fitting chooses from (0: each
sample's own score), doubling up to a few seconds: the longest bounds the delay a persistent
fault is detected with."""
NEWTON_STEPS = 25
"""Newton steps at most (the regression's loss is convex: a few suffice)."""
CONVERGED = 1e-9
"""A Newton step this small, relative to the weights, ends the fit."""
FIT_SAMPLES = 200_000
"""The most samples a regression is fitted on (a compute bound: hours of bags are thinned
evenly; the thresholds are still set on every sample)."""
FOLDS = 4
"""Blocked folds of the cross-fitting (fewer with fewer runs)."""
_VALUE_TYPES = ("float", "int", "uint", "bool")


class Sampled(NamedTuple):
    """One point's checked samples in one run, as classification collects them: their
    times (s) and, one row per sample, the values of :func:`variables_of`."""

    times: Any
    rows: Any


@dataclass
class Run:
    """The samples of one point in one run: times (s), statistics, and the onset (s from the
    run's start; ``None`` for a good run)."""

    name: str
    start: float
    onset: float | None
    times: Any
    stats: Any
    faulty: Any = field(init=False)
    scored: Any = field(init=False)
    """Per sample: whether the samples so far span the window (only those are scored)."""

    def __post_init__(self) -> None:
        times = np.asarray(self.times, dtype=np.float64)
        if self.onset is None:
            self.faulty = np.zeros(len(times), dtype=bool)
        else:
            self.faulty = times - self.start >= self.onset
        self.scored = spans(times, WINDOW)


@dataclass(frozen=True)
class Model:
    center: Any
    scale: Any
    weights: Any
    """Per standardised statistic, then the bias last."""

    def scores(self, run: Run) -> Any:
        return ((run.stats - self.center) / self.scale) @ self.weights[:-1] + self.weights[-1]


def fit(runs: Sequence[Run], strength: float) -> Model:
    """The logistic regression of ``runs`` with the L2 penalty ``strength`` (on every
    ``k``-th sample of each run when they hold more than :data:`FIT_SAMPLES`)."""
    total = sum(int(r.scored.sum()) for r in runs)
    every = max(1, -(-total // FIT_SAMPLES))
    x = np.vstack([r.stats[r.scored][::every] for r in runs])
    y = np.concatenate([r.faulty[r.scored][::every] for r in runs]).astype(np.float64)
    finite = np.isfinite(x).all(axis=1)  # an infinite value: no statistic to weigh
    x, y = x[finite], y[finite]
    center, scale = x.mean(axis=0), x.std(axis=0)
    scale[scale == 0] = 1.0
    z = np.hstack([(x - center) / scale, np.ones((len(x), 1))])
    positives = max(1.0, float(y.sum()))
    negatives = max(1.0, len(y) - positives)
    weight = np.where(y > 0, len(y) / (2 * positives), len(y) / (2 * negatives))
    w = np.zeros(z.shape[1])
    penalty = np.full(z.shape[1], strength)
    penalty[-1] = 0.0
    # one BLAS thread: imrosc runs in parallel by processes, and BLAS threads fighting over
    # a busy machine's cores made each fit 10x slower
    with threadpool_limits(limits=1, user_api="blas"):
        for _ in range(NEWTON_STEPS):
            p = 1 / (1 + np.exp(-np.clip(z @ w, -30, 30)))
            gradient = z.T @ (weight * (p - y)) + penalty * w
            hessian = (z * (weight * p * (1 - p))[:, None]).T @ z + np.diag(penalty + 1e-9)
            step = np.linalg.solve(hessian, gradient)
            w -= step
            if float(np.abs(step).max()) <= CONVERGED * (1.0 + float(np.abs(w).max())):
                break  # Newton's method converges quadratically: the rest moves nothing
    return Model(center, scale, w)


@dataclass(frozen=True)
class Choice:
    """A penalty and smoothing, their cross-fitted threshold, and the failed runs their
    held-out evidence detected."""

    strength: float
    smooth: float
    threshold: float
    detected: frozenset[str]
    delays: Mapping[str, float]
    nominal: int
    """Held-out runs with nominal samples (the threshold's evidence)."""
    alpha: float = 1.0
    """The share of the false-alarm budget the threshold keeps (1: none asked)."""
    failed: int = 0
    """Held-out failed runs with evidence from their onset on (those it could detect)."""
    tried: int = 1
    """The penalty and smoothing pairs the choice was the best of."""
    horizon: float = math.inf
    """Seconds of the shortest held-out nominal stretch with evidence: a detection this
    soon after the onset is one a blind detector makes at most as often as it exceeds a
    nominal stretch's largest evidence."""

    @property
    def prompt(self) -> int:
        """The held-out failed runs detected within :attr:`horizon` of their onsets."""
        return sum(delay <= self.horizon for delay in self.delays.values())

    @property
    def chance(self) -> float:
        """The probability that a detector whose evidence does not respond to faults at all
        would have detected as many held-out failed runs within :attr:`horizon` of their
        onsets: a failed run's largest evidence over that stretch, no longer than any
        nominal one, is then at most one more draw beside the ``nominal`` held-out
        extremes, above them all with probability at most ``1/(n+1)`` (their ranks are
        exchangeable), and the threshold is at least the largest. Not corrected for the
        choice among the pairs (they are nested: one fit's scores under five smoothings,
        penalties a decade apart)."""
        return binomial_tail(self.prompt, self.failed, 1.0 / (self.nominal + 1))

    @property
    def separates(self) -> bool:
        """Whether its held-out detections are beyond chance: :attr:`chance` within its
        share of the budget (``alpha``). Only then is it kept (with no share asked, 0 or
        1, every choice that detects is kept)."""
        if not 0.0 < self.alpha < 1.0:
            return bool(self.detected)
        return bool(self.detected) and self.chance <= self.alpha

    @property
    def false_alarm(self) -> float:
        """The probability that a new good run alarms: at most ``1/(n+1)`` past the largest
        of ``n`` held-out runs, and at most ``alpha`` past their prediction bound."""
        return min(self.alpha, 1.0 / (self.nominal + 1))

    def rank(self) -> tuple[int, float, float, float]:
        """Larger is better: detections, then a short mean delay, a strong penalty and a
        short smoothing."""
        delay = sum(self.delays.values()) / len(self.delays) if self.delays else 0.0
        return (len(self.detected), -delay, self.strength, -self.smooth)


def binomial_tail(k: int, n: int, p: float) -> float:
    """``P(X >= k)`` for ``X`` binomial with ``n`` trials of probability ``p``.

    >>> round(binomial_tail(2, 7, 1 / 14), 4), binomial_tail(0, 3, 0.5), binomial_tail(4, 3, 0.5)
    (0.0842, 1.0, 0.0)
    """
    if k <= 0:
        return 1.0
    return math.fsum(math.comb(n, j) * p**j * (1.0 - p) ** (n - j) for j in range(k, n + 1))


def threshold_of(extremes: Sequence[float], alpha: float) -> float:
    """The threshold of held-out good runs' largest evidence (module docstring, step 3):
    the largest, or their normal prediction bound at ``alpha`` when that is higher (an
    ``alpha`` of 0, calibration off, or 1: the largest).

    >>> threshold_of([1.0, 2.0, 3.0], 0.05) > 3.0
    True
    >>> threshold_of([1.0, 2.0, 9.0], 0.5)
    9.0
    """
    bound = prediction_bound(extremes, alpha) if 0.0 < alpha < 1.0 else None
    return max(*extremes, bound if bound is not None else -math.inf)


def judged(
    held: Sequence[tuple[Run, Any]], strength: float, smooth: float, alpha: float = 1.0
) -> Choice | None:
    """The threshold of held-out scores evidenced over ``smooth`` seconds at the detector's
    share ``alpha`` of the budget, and what it detects (``None`` when no held-out run has a
    nominal sample)."""
    weighed = [(run, evidence(run.times, scored, WINDOW, smooth)) for run, scored in held]
    nominal, spans = [], []
    for run, found in weighed:
        seen = ~run.faulty & ~np.isnan(found)
        if seen.any():
            nominal.append(float(found[seen].max()))
            spans.append(float(run.times[seen].max() - run.times[seen].min()))
    if not nominal:
        return None
    threshold = threshold_of(nominal, alpha)
    delays = {}
    failed = 0
    for run, found in weighed:
        if run.onset is None or not (~np.isnan(found[run.faulty])).any():
            continue
        failed += 1
        over = np.flatnonzero(run.faulty & (found > threshold))
        if len(over):
            delays[run.name] = float(run.times[over[0]] - run.start - run.onset)
    return Choice(
        strength,
        smooth,
        threshold,
        frozenset(delays),
        delays,
        len(nominal),
        alpha,
        failed,
        horizon=min(spans),
    )


def choose(runs: Sequence[Run], alpha: float = 1.0) -> Choice | None:
    """The cross-fitted penalty, smoothing and threshold at ``alpha`` (module docstring,
    steps 2 to 4; 1: the largest held-out evidence); ``None`` with too few runs to hold any
    out or when no pair detects a held-out failed run."""
    folds = blocked(runs, lambda r: (r.start, r.name), FOLDS)
    if len(folds) < 2:
        return None
    best: Choice | None = None
    tried = 0
    for strength in PENALTIES:
        held: list[tuple[Run, Any]] = []
        for fold in folds:
            training = [r for k, r in enumerate(runs) if k not in fold]
            if not any(r.faulty.any() for r in training):
                continue
            model = fit(training, strength)
            held += [(runs[k], model.scores(runs[k])) for k in fold]
        for smooth in SMOOTHING:
            found = judged(held, strength, smooth, alpha)
            tried += found is not None
            if found is not None and (best is None or found.rank() > best.rank()):
                best = found
    if best is None or not best.detected:
        return None
    return dataclasses.replace(best, tried=tried)


def variables_of(point: Mapping[str, Any]) -> list[str]:
    """The variables a detector of a point weighs: its numeric values as recorded; none for
    a point that is not an unconditional publish point (a conditional point's samples are
    the moments its condition held, not a stretch of time a window can summarise)."""
    conditional = Pairing.from_json(point).filters or point.get("condition")
    if point.get("kind") != "publish" or conditional:
        return []
    return [
        v["name"]
        for v in point.get("variables", ())
        if v.get("type") in _VALUE_TYPES and v.get("derived") in (None, "avg", "std")
    ]


@dataclass
class Learnt:
    """A detector invariant and what its cross-fitting saw."""

    invariant: dict[str, Any]
    choice: Choice


@dataclass(frozen=True)
class Refused:
    """A point whose best detector's held-out detections chance explains
    (:attr:`Choice.separates`): none is kept, and the report says why."""

    point: str
    variables: int
    choice: Choice


def learn(
    key: str, variables: Sequence[str], runs: Sequence[Run], alpha: float = 1.0
) -> Learnt | Refused | None:
    """The detector of point ``key`` from its runs' samples, its threshold at ``alpha``
    (``None``: no pair detects a held-out failed run; :class:`Refused`: chance explains
    what the best one detects)."""
    if not learnable(variables, runs):
        return None
    choice = choose(runs, alpha)
    if choice is None:
        return None
    if not choice.separates:
        return Refused(key, len(variables), choice)
    model = fit(runs, choice.strength)
    weights = [float(w) for w in model.weights]
    invariant = {
        "id": detector_id(key, variables),
        "point": key,
        "family": DETECTOR,
        "kind": "logistic",
        "variables": list(variables),
        "params": {
            "window": WINDOW,
            "center": [float(c) for c in model.center],
            "scale": [float(s) for s in model.scale],
            "weights": weights[:-1],
            "bias": weights[-1],
            "threshold": choice.threshold,
            "smooth": choice.smooth,
            "penalty": choice.strength,
        },
        "text": f"{evidence_text(choice.smooth)} of {len(variables)} variables of {key} "
        f"<= {choice.threshold:.6g}",
    }
    return Learnt(invariant, choice)


def learnable(variables: Sequence[str], runs: Sequence[Run]) -> bool:
    """Whether a point has variables to weigh and failed samples to learn from."""
    return bool(variables) and any(r.faulty.any() for r in runs)


def evidence_text(smooth: float) -> str:
    """What a detector's threshold bounds, in words."""
    if smooth <= 0.0:
        return "detector score"
    return f"detector mean score over {smooth:g} s"


def detector_id(key: str, variables: Sequence[str]) -> str:
    """A stable id, as :func:`imrosc.invariants.invariant_id` gives."""
    return hashed_id([key, DETECTOR, "logistic", *variables])


def run_of(name: str, start: float, onset: float | None, samples: Sampled) -> Run:
    """One point's :class:`Run` from its samples in one run."""
    times = np.asarray(samples.times, dtype=np.float64)
    rows = np.asarray(samples.rows, dtype=np.float64).reshape(len(times), -1)
    return Run(name, start, onset, times, features(times, rows, WINDOW))
