"""The fault detector of a point: a linear score over the point's recent behaviour.

``imrosc classify`` can learn, from the good and the failed runs, one *detector* per
publish point (``docs/families/detector.md``): per sample, over the trailing window of
``window`` seconds of the point's samples, three statistics of each of its ``variables``:
the mean, the standard deviation and the change across the window (the sample's value less
the oldest one in the window). Standardised by ``center`` and ``scale``, they are weighed by
``weights`` (plus ``bias``): the sample's score, the log-odds that the run is faulty. The
evidence is the mean of the scores over the trailing ``smooth`` seconds (the sample's own
score when ``smooth`` is 0 or absent): a fault persists, a good run's odd moment does not.
Evidence above ``threshold`` is a violation, and an alarm at once: the threshold is already
the calibrated decision (set on the evidence held-out good runs reached; imrosc.detectors).

The window of a sample at time ``t`` holds the point's samples with times ``> t - window``;
a run's samples are scored once they span the window (``window`` seconds after the first),
and weighed once those scores span ``smooth`` seconds: the statistics of a shorter stretch
are not the ones learnt from. A silence longer than the window (a sample whose predecessor
has left its window) begins a stretch as the run's first sample does: scored again once the
stretch spans the window, weighed once its scores span ``smooth`` (a monitor is one run for
its whole life; the windows after a pause would hold a sample or two).
A value that is NaN or infinite is the variable's last finite value (0 before the
first): one infinity would otherwise poison the window's running sums for good. This module
computes each sample's statistics incrementally; :func:`features` computes a whole run's
with the same class, so what classification learnt from and what the monitor checks agree.

Python 3.8 syntax, numpy and the standard library: the monitors carry this module.

>>> d = Detector({"id": "i1", "point": "p", "family": "detector", "kind": "score",
...     "text": "t", "variables": ["x"], "params": {"window": 1.0, "center": [0, 0, 0],
...     "scale": [1, 1, 1], "weights": [0, 0, 1], "bias": 0.0, "threshold": 2.5}}, {"x": 0})
>>> [d.sample(0.25 * k, np.array([float(k)])) is not None for k in range(6)]
[False, False, False, False, True, True]
"""

from __future__ import annotations

import collections
import math
from typing import Any, Deque, Mapping, Optional, Tuple

import numpy as np

from .families import DETECTOR
from .violation import Violation

RESUM = 4096
"""Samples after which the running sums are summed again from the window (float drift)."""
BOUND = 1e6
"""The largest score's magnitude the evidence sums: far above any threshold a log-odds is
given (tens), small enough that the running sums keep their precision. An overflowing
score (values near the float range) is clipped to it and a NaN score is 0: neither may
poison the sums."""


def bounded(score: float) -> float:
    """``score`` clipped to +-:data:`BOUND`, NaN as 0."""
    if math.isnan(score):
        return 0.0
    return min(BOUND, max(-BOUND, score))


class WindowFeatures:
    """Mean, standard deviation and change over the trailing window, sample by sample."""

    def __init__(self, window: float, width: int) -> None:
        self.window = float(window)
        self.width = width
        self.reset()

    def reset(self) -> None:
        """A new run: forget every sample."""
        self.held: Deque[Tuple[float, Any]] = collections.deque()
        self.total = np.zeros(self.width)
        self.squares = np.zeros(self.width)
        self.last = np.zeros(self.width)
        self.added = 0
        self.first: Optional[float] = None
        self.begun = False
        """Whether the latest sample began a stretch (the run's first, or the first after a
        silence longer than the window)."""

    def spans(self, time: float) -> bool:
        """Whether the samples so far span the window (before, the statistics describe a
        shorter stretch than the ones learnt from, and no score is given)."""
        return self.first is not None and time - self.first >= self.window

    def add(self, time: float, values: Any) -> Any:
        """The sample's statistics: ``[means, standard deviations, changes]``."""
        x = np.array(values, dtype=np.float64)
        missing = ~np.isfinite(x)
        if missing.any():
            x[missing] = self.last[missing]
        self.last = x
        held = self.held
        self.begun = self.first is None or (self.window > 0.0 and held[-1][0] <= time - self.window)
        if self.begun:
            self.first = time
        held.append((time, x))
        self.total += x
        self.squares += x * x
        edge = time - self.window
        while held[0][0] <= edge:
            _, old = held.popleft()
            self.total -= old
            self.squares -= old * old
        self.added += 1
        if self.added % RESUM == 0:
            rows = np.array([v for _, v in held])
            self.total = rows.sum(axis=0)
            self.squares = (rows * rows).sum(axis=0)
        count = float(len(held))
        mean = self.total / count
        variance = np.maximum(self.squares / count - mean * mean, 0.0)
        return np.concatenate((mean, np.sqrt(variance), x - held[0][1]))


class TrailingMean:
    """The mean of a score over the trailing ``seconds`` (the samples later than
    ``t - seconds``), sample by sample, once the scores span ``seconds``; the score itself
    when ``seconds`` is 0."""

    def __init__(self, seconds: float) -> None:
        self.seconds = float(seconds)
        self.reset()

    def reset(self) -> None:
        self.held: Deque[Tuple[float, float]] = collections.deque()
        self.total = 0.0
        self.added = 0
        self.first: Optional[float] = None

    def add(self, time: float, score: float) -> Optional[float]:
        """The mean with the score of ``time``; ``None`` while the scores span less than
        ``seconds``."""
        score = bounded(score)
        if self.seconds <= 0.0:
            return score
        if self.first is None:
            self.first = time
        held = self.held
        held.append((time, score))
        self.total += score
        edge = time - self.seconds
        while held[0][0] <= edge:
            self.total -= held.popleft()[1]
        self.added += 1
        if self.added % RESUM == 0:
            self.total = math.fsum(s for _, s in held)
        if time - self.first < self.seconds:
            return None
        return self.total / len(held)


def evidence(times: Any, scores: Any, window: float, smooth: float) -> Any:
    """What a :class:`Detector` weighs each sample of a run by, at once (what
    classification learns from; the monitors compute the same sample by sample): NaN before
    the samples span ``window``, then the scores' :class:`TrailingMean` over ``smooth``
    seconds (NaN until those scores span ``smooth`` in turn)."""
    at = np.asarray(times, dtype=np.float64)
    values = np.clip(np.nan_to_num(np.asarray(scores, dtype=np.float64)), -BOUND, BOUND)
    found = np.full(len(values), math.nan)
    if not len(values):
        return found
    spanning = spans(at, window)
    if not spanning.any():
        return found
    if smooth <= 0.0:
        found[spanning] = values[spanning]
        return found
    # the first scored sample of each stretch: scores are weighed within their stretch
    rows = np.arange(len(at))
    opens = spanning.copy()
    opens[1:] &= ~spanning[:-1] | stretches(at, window)[1:]
    scored = np.maximum.accumulate(np.where(opens, rows, 0))
    starts = np.maximum(np.searchsorted(at, at - smooth, side="right"), scored)
    sums = np.concatenate(([0.0], np.cumsum(values)))
    means = (sums[rows + 1] - sums[starts]) / (rows + 1 - starts)
    weighed = spanning & (at - at[scored] >= smooth)
    found[weighed] = means[weighed]
    return found


def stretches(times: Any, window: float) -> Any:
    """Per sample, whether it begins a stretch: the run's first, and every sample whose
    predecessor has left its window (``WindowFeatures.begun``)."""
    at = np.asarray(times, dtype=np.float64)
    begins = np.zeros(len(at), dtype=bool)
    begins[:1] = True
    if window > 0.0 and len(at) > 1:  # (no window: one stretch, as WindowFeatures keeps it)
        begins[1:] = at[:-1] <= at[1:] - window
    return begins


def spans(times: Any, window: float) -> Any:
    """Per sample, whether the samples of its stretch so far span the window (only those
    are scored: ``WindowFeatures.spans``)."""
    at = np.asarray(times, dtype=np.float64)
    if not len(at):
        return np.zeros(0, dtype=bool)
    rows = np.arange(len(at))
    first = at[np.maximum.accumulate(np.where(stretches(at, window), rows, 0))]
    return at - first >= window


def features(times: Any, rows: Any, window: float) -> Any:
    """The statistics of every sample of a run (``rows``: one row per sample)."""
    values = np.asarray(rows, dtype=np.float64)
    found = WindowFeatures(window, values.shape[1] if values.ndim == 2 else 0)
    return np.array([found.add(t, row) for t, row in zip(times, values)]).reshape(
        len(values), 3 * found.width
    )


class Detector:
    """One detector invariant of a point, checked on its samples (``index``: a numeric
    variable's position in the point's sample vector)."""

    def __init__(self, invariant: Mapping[str, Any], index: Mapping[str, int]) -> None:
        params = invariant["params"]
        self.invariant = invariant
        self.places = np.asarray([index[n] for n in invariant["variables"]], dtype=np.int64)
        self.center = np.asarray(params["center"], dtype=np.float64)
        self.scale = np.asarray(params["scale"], dtype=np.float64)
        self.weights = np.asarray(params["weights"], dtype=np.float64) / self.scale
        self.offset = float(params["bias"]) - float(self.weights.dot(self.center))
        self.threshold = float(params["threshold"])
        self.smooth = float(params.get("smooth", 0.0))
        what = "score" if self.smooth <= 0.0 else f"mean score over {self.smooth:g} s"
        self.expected = f"{what} <= {self.threshold:.6g}"
        self.window = WindowFeatures(float(params["window"]), len(self.places))
        self.evidence = TrailingMean(self.smooth)

    def reset(self) -> None:
        self.window.reset()
        self.evidence.reset()

    def score(self, time: float, row: Any) -> float:
        """The score of the sample ``row`` (the window moves on)."""
        return float(self.weights.dot(self.window.add(time, row.take(self.places)))) + self.offset

    def sample(self, time: float, row: Any, point: str = "") -> Optional[Violation]:
        """The violation of the sample ``row``, if the evidence is above the threshold."""
        score = self.score(time, row)
        if self.window.begun:  # a stretch begins: so does the evidence's
            self.evidence.reset()
        if not self.window.spans(time):
            return None
        weighed = self.evidence.add(time, score)
        if weighed is None or weighed <= self.threshold:
            return None
        inv = self.invariant
        return Violation(
            time,
            point or inv["point"],
            inv["id"],
            DETECTOR,
            inv["kind"],
            inv["text"],
            weighed,
            self.expected,
        )
