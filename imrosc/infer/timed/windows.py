"""Sliding time windows and the per-window statistics of the time-related families.

The window of a message
-----------------------
Within one run (bag), the window of message ``i`` received at time ``t_i`` holds the
messages ``j <= i`` of the same run with ``t_j > t_i - w'``, where ``w' = window -
TIME_EPSILON`` (``window`` is the configured width in seconds; ``TIME_EPSILON`` is 1 us, or
a thousandth of the window if that is smaller). The subtraction ``t_i - w'`` is one float64
operation, so the online monitor can reproduce it bit for bit: keep a queue, append the new
message, drop from the front while ``front.time <= t - w'``.

The epsilon exists because bag times are integer nanoseconds, but seconds since the epoch
as float64 keep only about 0.24 us: a 10 Hz stream stamped exactly 0.1 s apart would put
the message one window old in or out of the window by rounding alone. With ``w'`` it is
always out, so a 10 Hz stream has exactly 10 messages per 1 s window.

A window is *defined* (yields a value) once the run's first message has left it, i.e.
``t_first <= t_i - w'``: a full window has passed since the recording started. This fixes
the warm-up erratum of the thesis' Algorithm 2 (a partial window would make the minimum
frequency ``1 / window`` on every run) and is applied alike to variance and change rate,
whose partial windows hold fewer samples than any later window. Windows never span runs.
A silence longer than the window (a message whose predecessor has left its window) begins
a stretch as the run's start does: ``t_first`` is then that message's time, so the partial
windows after a pause (a driver restarted, a robot idle) are not values either; a live
monitor, one run for its whole life, would otherwise judge a rate over two messages
0.05 s apart.

Window variance: the fixed algorithm
------------------------------------
The sample variance (``ddof = 1``, like ``Statistic.variance`` in the thesis' Java) of a
window of ``L >= 2`` values ``v[0..L-1]`` is computed by one fixed algorithm that depends
only on those values, so that it does not matter how a run is cut into chunks and so that a
monitor holding the window computes the very same float:

* a dyadic block of ``2**k`` consecutive values has statistics ``(n, mean, M2)`` computed
  by the pairwise tree: a single value is ``(1, v, 0)``; a block of ``2**(k+1)`` combines its
  two halves;
* the window is cut into dyadic blocks by the binary digits of ``L``, smallest first from
  the left (``L = 13 = 1 + 4 + 8``: ``v[0:1]``, ``v[1:5]``, ``v[5:13]``), and the blocks are
  combined left to right;
* combining ``(na, ma, M2a)`` with ``(nb, mb, M2b)`` (Chan et al.) is, in this order of
  float64 operations: ``n = na + nb``; ``d = mb - ma``; ``mean = ma + d * (nb / n)``;
  ``M2 = (M2a + M2b) + (d * d) * ((na * nb) / n)``, where ``nb / n`` and ``(na * nb) / n``
  are exact integer products divided once;
* the variance is ``M2 / (L - 1)``.

A constant window gives exactly 0. :func:`window_variance` is the reference implementation
(plain Python floats); :func:`windowed_variances` is the vectorised one used by inference
and is tested to agree with it bit for bit.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np
import numpy.typing as npt

from imrosc.infer.core import FloatArray

IntArray = npt.NDArray[np.int64]
BoolArray = npt.NDArray[np.bool_]

TIME_EPSILON = 1e-6
"""Seconds: how much older than one window a message may be and still count as one
window old (float64 seconds since the epoch round to about 0.24 us)."""

_WINDOW_BLOCK = 1024
"""Windows evaluated together (keeps the working set in cache)."""

_MAX_GROUPS = 48
"""Above this many distinct window lengths per block, switch to bit masks."""


def effective_width(window: float) -> float:
    """``w'``: the window width less the rounding allowance."""
    if not window > 0 or not math.isfinite(window):
        raise ValueError(f"time window must be a positive number of seconds, not {window!r}")
    return window - min(TIME_EPSILON, window * 1e-3)


def window_starts(time: FloatArray, width: float) -> IntArray:
    """For each message, the index of the first message of its window (same run)."""
    cutoff = time - effective_width(width)
    return np.searchsorted(time, cutoff, side="right").astype(np.int64)


def _combine(
    na: int, ma: float, m2a: float, nb: int, mb: float, m2b: float
) -> tuple[int, float, float]:
    n = na + nb
    d = mb - ma
    return n, ma + d * (nb / n), (m2a + m2b) + (d * d) * ((na * nb) / n)


def _dyadic(values: Sequence[float]) -> tuple[int, float, float]:
    if len(values) == 1:
        return 1, float(values[0]), 0.0
    half = len(values) // 2
    na, ma, m2a = _dyadic(values[:half])
    nb, mb, m2b = _dyadic(values[half:])
    return _combine(na, ma, m2a, nb, mb, m2b)


def _fixed(values: Sequence[float]) -> tuple[int, float, float]:
    """``(n, mean, M2)`` of a window of at least one value, by the fixed algorithm."""
    size = len(values)
    acc: tuple[int, float, float] | None = None
    pos = 0
    k = 0
    while size >> k:
        if (size >> k) & 1:
            block = _dyadic(values[pos : pos + (1 << k)])
            acc = block if acc is None else _combine(*acc, *block)
            pos += 1 << k
        k += 1
    assert acc is not None
    return acc


def window_variance(values: Sequence[float]) -> float:
    """The reference fixed-algorithm sample variance of one window (NaN if ``len < 2``)."""
    size = len(values)
    return math.nan if size < 2 else _fixed(values)[2] / (size - 1)


def window_mean(values: Sequence[float]) -> float:
    """The reference fixed-algorithm mean of one window (NaN if ``len < 2``): the mean the
    variance's dyadic combination carries."""
    return math.nan if len(values) < 2 else _fixed(values)[1]


def _levels(values: FloatArray, top: int) -> tuple[list[FloatArray], list[FloatArray]]:
    """Dyadic block statistics at every start position, for block sizes ``2**0..2**top``."""
    means = [values]
    m2s = [np.zeros_like(values)]
    for k in range(1, top + 1):
        half = 1 << (k - 1)
        mean, m2 = means[-1], m2s[-1]
        d = mean[half:] - mean[:-half]
        new_mean = d * 0.5
        new_mean += mean[:-half]
        new_m2 = m2[:-half] + m2[half:]
        d *= d
        d *= half / 2
        new_m2 += d
        means.append(new_mean)
        m2s.append(new_m2)
    return means, m2s


def consecutive(rows: IntArray) -> bool:
    """Whether ``rows`` are ``k, k + 1, ...`` (at least one): what a steady rate gives, whose
    rows can be read as a slice instead of gathered."""
    return len(rows) > 0 and bool(np.all(rows[1:] - rows[:-1] == 1))


def _block_by_length(
    means: list[FloatArray],
    m2s: list[FloatArray],
    start: IntArray,
    length: IntArray,
    out: FloatArray,
    out_mean: FloatArray,
) -> None:
    if int(length.min()) == int(length.max()):  # one length: no grouping
        lengths, inverse = length[:1], np.zeros(len(length), np.int64)
    else:
        lengths, inverse = np.unique(length, return_inverse=True)
    # one length and consecutive starts (a steady rate): the blocks are slices
    steady = len(lengths) == 1 and consecutive(start)
    for group, size in enumerate(lengths.tolist()):
        rows = np.flatnonzero(inverse == group) if not steady else np.arange(len(start))
        first = start[rows]
        acc_mean: FloatArray | None = None
        acc_m2: FloatArray | None = None
        na = 0
        offset = 0
        for k in range(int(size).bit_length()):
            if not (size >> k) & 1:
                continue
            block = 1 << k
            if steady:
                at = int(first[0]) + offset
                bm = means[k][at : at + len(first)]
                bm2 = m2s[k][at : at + len(first)]
            else:
                bm = means[k][first + offset]
                bm2 = m2s[k][first + offset]
            offset += block
            if acc_mean is None or acc_m2 is None:
                acc_mean, acc_m2, na = bm, bm2, block
                continue
            n = na + block
            d = bm - acc_mean
            new_mean = d * (block / n)
            new_mean += acc_mean
            d *= d
            d *= (na * block) / n
            bm2 = bm2 + acc_m2  # not in place: a slice is the levels' own
            bm2 += d
            acc_mean, acc_m2, na = new_mean, bm2, n
        assert acc_m2 is not None and acc_mean is not None
        if steady:
            np.divide(acc_m2, size - 1, out=out)
            out_mean[:] = acc_mean
        else:
            out[rows] = acc_m2 / (size - 1)
            out_mean[rows] = acc_mean


def _block_by_bits(
    means: list[FloatArray],
    m2s: list[FloatArray],
    start: IntArray,
    length: IntArray,
    out: FloatArray,
    out_mean: FloatArray,
) -> None:
    count, width = out.shape
    acc_mean = np.zeros((count, width))
    acc_m2 = np.zeros((count, width))
    acc_n = np.zeros(count, np.int64)
    for k in range(int(length.max()).bit_length()):
        block = 1 << k
        bit = ((length >> k) & 1).astype(bool)
        if not bit.any():
            continue
        pos = np.where(bit, start + (length & (block - 1)), 0)
        bm = means[k][pos]
        bm2 = m2s[k][pos]
        na = acc_n
        n = na + block
        d = bm - acc_mean
        new_mean = d * (block / n)[:, None]
        new_mean += acc_mean
        d *= d
        d *= ((na * block) / n)[:, None]
        new_m2 = acc_m2 + bm2
        new_m2 += d
        first = (bit & (na == 0))[:, None]
        later = (bit & (na > 0))[:, None]
        np.copyto(acc_mean, new_mean, where=later)
        np.copyto(acc_m2, new_m2, where=later)
        np.copyto(acc_mean, bm, where=first)
        np.copyto(acc_m2, bm2, where=first)
        acc_n += np.where(bit, block, 0)
    out[:] = acc_m2 / (length - 1)[:, None]
    out_mean[:] = acc_mean


def windowed_moments(
    values: FloatArray, start: IntArray, length: IntArray
) -> tuple[FloatArray, FloatArray]:
    """Fixed-algorithm means and variances of the windows ``values[start[w] : start[w] +
    length[w]]``: the mean is the combined blocks' mean, the very float the variance's
    algorithm carries (so inference and a monitor holding the window agree bit for bit).

    ``values`` is ``(rows, variables)``; each result is ``(windows, variables)``. Every
    ``length`` must be at least 2.
    """
    count = len(start)
    out = np.empty((count, values.shape[1]))
    out_mean = np.empty((count, values.shape[1]))
    if count == 0:
        return out_mean, out
    with np.errstate(all="ignore"):
        for first in range(0, count, _WINDOW_BLOCK):
            sl = slice(first, first + _WINDOW_BLOCK)
            st, ln = start[sl], length[sl]
            base = int(st.min())
            end = int((st + ln).max())
            top = int(ln.max()).bit_length() - 1
            means, m2s = _levels(np.ascontiguousarray(values[base:end]), top)
            target, target_mean = out[sl], out_mean[sl]
            if ln.min() == ln.max() or len(np.unique(ln)) <= _MAX_GROUPS:
                _block_by_length(means, m2s, st - base, ln, target, target_mean)
            else:
                _block_by_bits(means, m2s, st - base, ln, target, target_mean)
    return out_mean, out


def windowed_variances(values: FloatArray, start: IntArray, length: IntArray) -> FloatArray:
    """Fixed-algorithm variances of the windows ``values[start[w] : start[w] + length[w]]``
    (:func:`windowed_moments`)."""
    return windowed_moments(values, start, length)[1]


def episode_starts(
    restarts: npt.NDArray[np.bool_] | None,
    all_time: FloatArray,
    starts: IntArray,
    ends: IntArray,
    first_time: float,
) -> tuple[IntArray, FloatArray | float, int]:
    """The windows ``starts .. ends`` (rows of ``all_time``) when the rows ``restarts``
    begin episodes of a condition, which restart the windows as a run's start does: each
    window's start moved up to its episode's first row, the time its episode began (the
    run's ``first_time`` before any), and the row the last episode began at (-1: no row
    begins one, and nothing moves)."""
    if restarts is None or not restarts.any():
        return starts, first_time, -1
    begun = np.maximum.accumulate(np.where(restarts, ends, -1))
    first = np.where(begun >= 0, all_time[np.maximum(begun, 0)], first_time).astype(np.float64)
    return np.maximum(starts, begun), first, int(begun[-1])


def with_silences(
    restarts: npt.NDArray[np.bool_] | None, all_time: FloatArray, cutoff: FloatArray, old: int
) -> npt.NDArray[np.bool_] | None:
    """``restarts`` (rows ``old ..`` of ``all_time``, whose windows end at ``cutoff``) and
    the rows after a silence longer than the window: their predecessor has left their
    window. Such a row begins a stretch as a run's first row does (module docstring)."""
    rows = np.arange(old, len(all_time))
    silent = np.zeros(len(rows), dtype=bool)
    after = rows >= 1
    silent[after] = all_time[rows[after] - 1] <= cutoff[after]
    if not silent.any():
        return restarts
    return silent if restarts is None else restarts | silent


class WindowTracker:
    """Carries the open window of the current run from one chunk to the next."""

    def __init__(self, window: float, width: int) -> None:
        self.window = float(window)
        self.effective = effective_width(self.window)
        self.width = width
        self.reset()

    def reset(self) -> None:
        """A new run starts: forget the open window."""
        self.first_time: float | None = None
        self.tail_time: FloatArray = np.empty(0)
        self.tail_values: FloatArray = np.empty((0, self.width))

    def advance(
        self,
        time: FloatArray,
        values: FloatArray | None = None,
        restarts: npt.NDArray[np.bool_] | None = None,
    ) -> tuple[FloatArray, FloatArray, IntArray, IntArray]:
        """Append a chunk; return ``(time, values, ends, starts)`` of its defined windows.

        ``time`` and ``values`` returned are the carried tail followed by the chunk; each
        defined window is the rows ``starts[w] .. ends[w]`` (inclusive) of them.
        ``restarts`` (optional) marks the rows where a condition's episode begins: a window
        holds no row before its episode's first, and is defined once that row has left it,
        as at a run's start.
        """
        if values is None:
            values = np.empty((len(time), self.width))
        if self.first_time is None and len(time):
            self.first_time = float(time[0])
        all_time = np.concatenate([self.tail_time, time]) if len(self.tail_time) else time
        all_values = np.concatenate([self.tail_values, values]) if len(self.tail_time) else values
        old = len(self.tail_time)
        if len(time) == 0:
            return all_time, all_values, np.empty(0, np.int64), np.empty(0, np.int64)
        cutoff = all_time[old:] - self.effective
        starts = np.searchsorted(all_time, cutoff, side="right").astype(np.int64)
        ends = np.arange(old, len(all_time), dtype=np.int64)
        assert self.first_time is not None
        keep = int(np.searchsorted(all_time, all_time[-1] - self.effective, side="right"))
        restarts = with_silences(restarts, all_time, cutoff, old)
        starts, first, begun = episode_starts(restarts, all_time, starts, ends, self.first_time)
        defined = cutoff >= first
        if begun >= 0:
            keep = max(keep, begun)
            self.first_time = float(all_time[begun])
        self.tail_time = all_time[keep:].copy()
        self.tail_values = all_values[keep:].copy()
        return all_time, all_values, ends[defined], starts[defined]

    def adopt(self, other: WindowTracker) -> None:
        """Continue the (possibly open) run of ``other``."""
        self.first_time = other.first_time
        self.tail_time = other.tail_time
        self.tail_values = other.tail_values


class Extremes:
    """Mergeable minima and maxima of a sequence of values per variable, with support.

    ``count`` values seen; ``low``/``high`` the extremes and ``low_at``/``high_at`` the
    position (in the sequence of values of that variable) where each was first reached. The
    samples since the invariant last changed are ``count - max(low_at, high_at)``: a
    value changes the invariant exactly when it is a new strict extreme, and the last such
    change is the first occurrence of the final minimum or maximum.
    """

    def __init__(self, width: int) -> None:
        self.count = np.zeros(width, np.int64)
        self.low = np.full(width, np.inf)
        self.low_at = np.zeros(width, np.int64)
        self.high = np.full(width, -np.inf)
        self.high_at = np.zeros(width, np.int64)

    def add(self, values: FloatArray, valid: BoolArray) -> None:
        """Append a chunk of values ``(rows, variables)``; ``valid`` marks defined ones."""
        if values.shape[0] == 0:
            return
        chunk = Extremes(values.shape[1])
        cols = np.arange(values.shape[1])
        partial = ~valid.all(axis=0)
        if partial.any():
            values = values.copy()
            values[:, partial] = np.where(valid[:, partial], values[:, partial], np.nan)
        # nanargmin/max would warn on all-NaN columns: use fmin-style reductions instead
        with np.errstate(invalid="ignore"):
            low = np.fmin.reduce(values, axis=0)
            high = np.fmax.reduce(values, axis=0)
        seen = ~np.isnan(low)
        lo = np.argmax(values == low, axis=0)
        hi = np.argmax(values == high, axis=0)
        chunk.count = np.full(values.shape[1], values.shape[0], np.int64)
        chunk.low_at = lo.astype(np.int64)
        chunk.high_at = hi.astype(np.int64)
        for col in np.flatnonzero(partial).tolist():
            ok = valid[:, col]
            chunk.count[col] = int(np.count_nonzero(ok))
            chunk.low_at[col] = int(np.count_nonzero(ok[: lo[col]]))
            chunk.high_at[col] = int(np.count_nonzero(ok[: hi[col]]))
        chunk.low = np.where(seen, values[lo, cols], np.inf)
        chunk.high = np.where(seen, values[hi, cols], -np.inf)
        chunk.low_at = np.where(seen, chunk.low_at, 0)
        chunk.high_at = np.where(seen, chunk.high_at, 0)
        self.merge(chunk)

    def merge(self, other: Extremes) -> None:
        """Append the sequence summarised by ``other``."""
        seen = other.count > 0
        lower = seen & ((self.count == 0) | (other.low < self.low))
        higher = seen & ((self.count == 0) | (other.high > self.high))
        self.low = np.where(lower, other.low, self.low)
        self.low_at = np.where(lower, other.low_at + self.count, self.low_at)
        self.high = np.where(higher, other.high, self.high)
        self.high_at = np.where(higher, other.high_at + self.count, self.high_at)
        self.count = self.count + other.count

    def since_change(self) -> IntArray:
        """Samples since each variable's bounds last changed (0 when none seen)."""
        return np.where(
            self.count > 0, self.count - np.maximum(self.low_at, self.high_at), 0
        ).astype(np.int64)
