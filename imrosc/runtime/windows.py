"""Time windows online: frequency, windowed variance, change rate and mean of one program
point.

Inference computes every window of a run at once (``imrosc.infer.timed``); this module
computes the window of each new sample as it arrives, bit for bit the same:

* the window of a sample at time ``t`` holds the samples ``j`` of the run with
  ``t_j > t - w'``, ``w' = window - min(1e-6, window / 1000)`` (one float64 subtraction);
* a window is defined once the first sample of its stretch has left it (``t_first <= t -
  w'``): a stretch begins at the run's first sample and at every sample whose predecessor
  has left its window (a silence longer than the window), whose windows would otherwise
  hold a second's worth of samples or less and span less than a window;
* frequency is ``len(window) / window``; the rate is ``(x_last - x_first) / (t_last -
  t_first)`` (no rate when the times are equal); the variance is the fixed dyadic
  algorithm of ``docs/families/time-and-polygon.md``, whose blocks are memoised per
  sample, so each new sample costs O(log L) block combinations for a window of L samples;
  the mean is the mean that algorithm carries (windows of two samples or more).

>>> w = Windows(1.0, 1)
>>> [w.add(0.1 * i, [float(i)]) for i in range(12)][-1]
True
>>> w.frequency(), round(float(w.rate()[0]), 9), round(float(w.variance()[0]), 6)
(10.0, 10.0, 9.166667)
>>> float(w.mean()[0])
6.5
"""

from __future__ import annotations

import bisect
import math
from typing import Any, List, Optional, Sequence, Tuple

import numpy as np

TIME_EPSILON = 1e-6

Block = Tuple[int, Any, Any]
"""``(n, mean, M2)`` of a dyadic block, mean and M2 per variable."""


def effective_width(window: float) -> float:
    """``w'``: the window width less the rounding allowance."""
    return window - min(TIME_EPSILON, window * 1e-3)


def _combine(a: Block, b: Block) -> Block:
    na, ma, m2a = a
    nb, mb, m2b = b
    n = na + nb
    d = mb - ma
    return n, ma + d * (nb / n), (m2a + m2b) + (d * d) * ((na * nb) / n)


class Windows:
    """The sliding window of one point within one run, with ``variables`` values per sample."""

    def __init__(self, window: float, variables: int) -> None:
        self.window = float(window)
        self.width = effective_width(self.window)
        self.variables = variables
        self.reset()

    def reset(self) -> None:
        """A new run: forget every sample."""
        self.first_time: Optional[float] = None
        self.times: List[float] = []
        self.values: List[Any] = []
        self.blocks: List[List[Optional[Block]]] = []
        self.base = 0
        """Absolute index of ``times[0]``."""
        self.front = 0
        """Absolute index of the window's oldest sample."""
        self.count = 0
        self.memo: Optional[Tuple[int, Block]] = None
        """The last window's moments and the sample count they were for."""

    def _evict(self, cutoff: float) -> None:
        while self.front < self.count and self.times[self.front - self.base] <= cutoff:
            self.front += 1
        drop = self.front - self.base
        if drop > 1024 and drop * 2 > len(self.times):
            del self.times[:drop], self.values[:drop], self.blocks[:drop]
            self.base = self.front

    def add(self, time: float, values: Sequence[float]) -> bool:
        """Append a sample; whether its window is defined."""
        cutoff = time - self.width
        if self.first_time is None or (
            self.count and self.times[self.count - 1 - self.base] <= cutoff
        ):  # the run's first sample, or the first after a silence longer than the window
            self.first_time = time
        self.times.append(time)
        self.values.append(np.asarray(values, dtype=np.float64))
        self.blocks.append([])
        self.count += 1
        self._evict(cutoff)
        return self.first_time <= cutoff

    def defined_at(self, time: float) -> bool:
        """Whether a window ending at ``time`` is defined."""
        return self.first_time is not None and self.first_time <= time - self.width

    def last_time(self) -> float:
        """Time of the latest sample (NaN before the first)."""
        return self.times[self.count - 1 - self.base] if self.count else math.nan

    def size(self) -> int:
        """Samples in the current window."""
        return self.count - self.front

    def frequency(self) -> float:
        """Samples per second in the current window."""
        return self.size() / self.window

    def size_at(self, time: float) -> int:
        """Samples that a window ending at ``time`` (no sample then) would hold."""
        start = bisect.bisect_right(self.times, time - self.width, self.front - self.base)
        return len(self.times) - start

    def rate(self) -> Any:
        """Change rate per variable over the current window (NaN where undefined)."""
        first, last = self.front - self.base, self.count - 1 - self.base
        dt = self.times[last] - self.times[first]
        if not dt > 0:
            return np.full(self.variables, np.nan)
        with np.errstate(all="ignore"):
            return (self.values[last] - self.values[first]) / dt

    def step(self) -> Any:
        """Change per variable between the window's last two samples (NaN below 2)."""
        if self.size() < 2:
            return np.full(self.variables, np.nan)
        last = self.count - 1 - self.base
        with np.errstate(all="ignore"):
            return self.values[last] - self.values[last - 1]

    def _block(self, end: int, level: int) -> Block:
        """The dyadic block of ``2**level`` samples ending at absolute index ``end``."""
        cache = self.blocks[end - self.base]
        while len(cache) <= level:
            cache.append(None)
        found = cache[level]
        if found is None:
            if level == 0:
                values = self.values[end - self.base]
                found = (1, values, np.zeros_like(values))
            else:
                half = 1 << (level - 1)
                found = _combine(self._block(end - half, level - 1), self._block(end, level - 1))
            cache[level] = found
        return found

    def variance(self) -> Any:
        """Sample variance per variable over the current window (NaN below 2 samples)."""
        size = self.size()
        if size < 2:
            return np.full(self.variables, np.nan)
        return self._moments()[2] / (size - 1)

    def mean(self) -> Any:
        """Mean per variable over the current window, as the variance's algorithm carries
        it (NaN below 2 samples)."""
        if self.size() < 2:
            return np.full(self.variables, np.nan)
        return self._moments()[1]

    def _moments(self) -> Block:
        """``(n, mean, M2)`` of the current window by the fixed dyadic algorithm (once per
        sample: variance and mean both ask)."""
        if self.memo is not None and self.memo[0] == self.count:
            return self.memo[1]
        size = self.size()
        acc: Optional[Block] = None
        position = self.front
        level = 0
        with np.errstate(all="ignore"):
            while size >> level:
                if (size >> level) & 1:
                    block = self._block(position + (1 << level) - 1, level)
                    acc = block if acc is None else _combine(acc, block)
                    position += 1 << level
                level += 1
            assert acc is not None
            self.memo = (self.count, acc)
            return acc
