"""The fault detector of a point: a linear score over the point's recent behaviour.

``imrosc classify`` can learn, from the good and the failed runs, one *detector* per
publish point (``docs/families/detector.md``): per sample, over the trailing window of
``window`` seconds of the point's samples, three statistics of each of its ``variables``:
the mean, the standard deviation and the change across the window (the sample's value less
the oldest one in the window). Standardised by ``center`` and ``scale``, they are weighed by
``weights`` (plus ``bias``); a score above ``threshold`` is a violation, and an alarm at
once: the threshold is already the calibrated decision (the largest score any held-out good
run reached).

The window of a sample at time ``t`` holds the point's samples with times ``> t - window``.
A value that is NaN or infinite is the variable's last finite value (0 before the
first): one infinity would otherwise poison the window's running sums for good. This module
computes each sample's statistics incrementally; :func:`features` computes a whole run's
with the same class, so what classification learnt from and what the monitor checks agree.

Python 3.8 syntax, numpy and the standard library: the monitors carry this module.

>>> d = Detector({"id": "i1", "point": "p", "family": "detector", "kind": "score",
...     "text": "t", "variables": ["x"], "params": {"window": 1.0, "center": [0, 0, 0],
...     "scale": [1, 1, 1], "weights": [0, 0, 1], "bias": 0.0, "threshold": 2.5}}, {"x": 0})
>>> [d.sample(0.25 * k, np.array([float(k)])) is not None for k in range(6)]
[False, False, False, True, True, True]
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

    def add(self, time: float, values: Any) -> Any:
        """The sample's statistics: ``[means, standard deviations, changes]``."""
        x = np.array(values, dtype=np.float64)
        missing = ~np.isfinite(x)
        if missing.any():
            x[missing] = self.last[missing]
        self.last = x
        held = self.held
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
        self.expected = f"score <= {self.threshold:.6g}"
        self.window = WindowFeatures(float(params["window"]), len(self.places))

    def reset(self) -> None:
        self.window.reset()

    def score(self, time: float, row: Any) -> float:
        """The score of the sample ``row`` (the window moves on)."""
        return float(self.weights.dot(self.window.add(time, row.take(self.places)))) + self.offset

    def sample(self, time: float, row: Any, point: str = "") -> Optional[Violation]:
        """The violation of the sample ``row``, if its score is above the threshold."""
        score = self.score(time, row)
        if score <= self.threshold or math.isnan(score):
            return None
        inv = self.invariant
        return Violation(
            time,
            point or inv["point"],
            inv["id"],
            DETECTOR,
            inv["kind"],
            inv["text"],
            score,
            self.expected,
        )
