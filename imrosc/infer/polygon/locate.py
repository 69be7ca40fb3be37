"""Exact point location in many convex hulls at once: which samples cannot be new vertices.

A hull here is a group of a :class:`~imrosc.infer.polygon.hull.GroupSet` as
:func:`~imrosc.infer.polygon.hull.hulls` returns it: strict vertices counter-clockwise from
the lexicographic minimum ``L``, so the vertices up to the lexicographic maximum ``R`` form
the lower chain (``x`` non-decreasing) and the rest, read backwards from ``L``, the upper
chain. A sample ``p`` with ``L.x <= p.x <= R.x`` lies in the closed hull exactly when it is
on or left of the lower chain's edge spanning ``p.x`` and on or right of the upper
chain's (an exact orientation each, the edges found by a vectorised binary search).

Such a sample is no vertex of any later hull: a point of the closed hull that is not one of
its vertices is a proper convex combination of them. A sample *at* a vertex is kept anyway
(it may be an earlier occurrence of that vertex). This is exact and needs no guide, so it
serves the hulls the guide cannot (slivers along a line, with rounding noise as width),
where the float filters prove nothing.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from imrosc.infer.core import FloatArray
from imrosc.infer.polygon.hull import GroupSet, IntArray
from imrosc.infer.polygon.predicates import (
    Frames,
    SignArray,
    _two_sum,
    edge_frames,
    frame_orientation,
    orientation,
)

BoolArray = npt.NDArray[np.bool_]

_RUN_SEARCH = 64
"""Samples per chain from which a chain's edges are found by one ``searchsorted`` per chain
rather than by a binary search across all chains at once."""


@dataclass
class Chains:
    """The lower or the upper chains of some hulls, each read with ``x`` non-decreasing:
    chain ``s`` is ``x[start[s]:start[s] + size[s]]`` (likewise ``y``)."""

    x: FloatArray
    y: FloatArray
    start: IntArray
    size: IntArray
    frames: Frames
    """Per vertex, the frame of the edge it starts (:func:`edge_frames`; kind 0 for none)."""

    @staticmethod
    def of(hull: GroupSet, index: IntArray, size: IntArray) -> Chains:
        """The chains whose vertices are ``hull``'s at ``index`` (chain after chain)."""
        start = np.concatenate([[0], np.cumsum(size)[:-1]]).astype(np.int64)
        x, y = hull.x[index], hull.y[index]
        nxt = np.minimum(np.arange(1, len(x) + 1), max(len(x) - 1, 0))
        frames = edge_frames(x, y, x[nxt], y[nxt])
        frames[0][start + size - 1] = 0  # a chain's last vertex starts no edge
        return Chains(x, y, start, size.astype(np.int64), frames)

    def turn(self, a: IntArray, b: IntArray, px: FloatArray, py: FloatArray) -> SignArray:
        """The exact sign of ``orient2d`` of each edge ``a -> b`` (``b = a + 1``) and point:
        in the edge's sheared frame where that decides (samples of exact relations crowd
        such edges), else by :func:`orientation`."""
        out = np.empty(len(a), np.int8)
        slow = np.arange(len(a))
        fast = np.flatnonzero(self.frames[0].take(a))
        if len(fast):
            at = a.take(fast)
            frames = tuple(part.take(at) for part in self.frames)
            sign, decided = frame_orientation(frames, px.take(fast), py.take(fast))  # type: ignore[arg-type]
            out[fast] = sign
            rest = np.ones(len(a), bool)
            rest[fast[decided]] = False
            slow = np.flatnonzero(rest)
        if len(slow):
            sa, sb = a.take(slow), b.take(slow)
            out[slow] = orientation(
                self.x.take(sa),
                self.y.take(sa),
                self.x.take(sb),
                self.y.take(sb),
                px.take(slow),
                py.take(slow),
            )
        return out

    def edge(self, chain: IntArray, px: FloatArray) -> tuple[IntArray, IntArray]:
        """Per sample, the flat indices ``(a, b)`` of the edge of its chain spanning
        ``px``, ``a.x < b.x``: ``a`` is the last vertex with ``x <= px`` (clipped to the
        chain's edges); a vertical last edge (at ``px == R.x``) gives way to the one
        before it."""
        start, size = self.start.take(chain), self.size.take(chain)
        lo = self._by_runs(chain, px)
        if lo is None:
            lo = np.zeros(len(px), np.int64)
            hi = size.copy()
            steps = int(np.ceil(np.log2(int(size.max()) + 1))) if len(size) else 0
            for _ in range(steps):  # count the vertices with x <= px
                mid = (lo + hi) >> 1
                open_ = lo < hi
                below = open_ & (self.x.take(start + np.minimum(mid, size - 1)) <= px)
                lo = np.where(below, mid + 1, lo)
                hi = np.where(open_ & ~below, mid, hi)
        a = start + np.clip(lo - 1, 0, size - 2)
        a = a - (self.x.take(a) == self.x.take(a + 1))
        return a, a + 1

    def _by_runs(self, chain: IntArray, px: FloatArray) -> IntArray | None:
        """Per sample, the number of its chain's vertices with ``x <= px``, by one
        ``searchsorted`` per chain when the samples come chain by chain (a located group
        set's do) with many samples per chain; None otherwise."""
        if len(chain) < _RUN_SEARCH or np.any(chain[1:] < chain[:-1]):
            return None
        change = np.flatnonzero(chain[1:] != chain[:-1]) + 1
        if _RUN_SEARCH * (len(change) + 1) > len(chain):
            return None
        firsts = np.concatenate([[0], change]).tolist()
        lasts = [*firsts[1:], len(chain)]
        count = np.empty(len(chain), np.int64)
        starts, sizes = self.start.tolist(), self.size.tolist()
        for first, last in zip(firsts, lasts, strict=True):
            c = int(chain[first])
            vertices = self.x[starts[c] : starts[c] + sizes[c]]
            count[first:last] = np.searchsorted(vertices, px[first:last], side="right")
        return count


_SAFE_HIGH = 2.0**900
_SAFE_LOW = 2.0**-900
_SLOPE_EXPONENT = 60
"""A band's slope is zero or ``+-2**k``, ``|k| <= 60``: with coordinates of magnitude in
``[_SAFE_LOW, _SAFE_HIGH]`` (or zero), ``y - s*x`` is exactly two floats (a two-sum; no
overflow, no underflow)."""


def _safe(v: FloatArray) -> BoolArray:
    with np.errstate(invalid="ignore"):
        size = np.abs(v)
        found: BoolArray = (v == 0) | ((size >= _SAFE_LOW) & (size <= _SAFE_HIGH))
    return found


@dataclass
class Band:
    """Per hull (chain slot), a band whose samples are strictly inside, by a cheap exact test.

    With ``w = y - s*x`` (``s`` the power of two nearest the slope of ``L -> R``, so ``w``
    is exactly ``high + low``, a two-sum), the lower chain is the graph of a convex function
    of ``x`` and the upper chain of a concave one (the shear keeps ``x`` and orientations).
    Over ``[lo, hi]``, the ``x`` from the first to the last interior vertex of both chains,
    the lower chain lies at or below its greatest interior offset (``floor``: a convex
    function peaks at an end of an interval) and the upper chain at or above its least one
    (``ceiling``); the first interior vertices lie right of ``L``, the last ones left of
    ``R``. A sample there with ``floor < w < ceiling`` is strictly inside the hull: in the
    closed hull and none of its vertices. Offsets compare exactly as two-sums: by their
    rounded parts (rounding is monotone), then by their tails.

    A segment whose ends have the very same offset (``line``) has the open segment as its
    band: a sample with ``lo < x < hi`` and that offset exactly lies on it strictly between
    its ends. Samples of an exact relation (``b = 2*a + 3`` where no sum rounds) lie there;
    those of a rounded one (``s = ab + 5``) scatter about its line by their roundings, many
    of them within the extremes the hull's interior vertices reached: neither needs an
    orientation. Hulls without a band (a chain of two vertices with ends of two offsets,
    magnitudes outside the safe range) have ``lo > hi``.
    """

    slope: FloatArray
    lo: FloatArray
    hi: FloatArray
    floor: tuple[FloatArray, FloatArray]
    ceiling: tuple[FloatArray, FloatArray]
    line: BoolArray

    @staticmethod
    def of(lower: Chains, upper: Chains) -> Band:
        """The bands of the hulls whose chains are ``lower`` and ``upper``."""
        if not len(lower.size):
            e = np.empty(0)
            return Band(e, e, e, (e, e), (e, e), np.empty(0, bool))
        first, last = lower.start, lower.start + lower.size - 1
        with np.errstate(all="ignore"):
            slope = (lower.y[last] - lower.y[first]) / (lower.x[last] - lower.x[first])
            mantissa, exponent = np.frexp(slope)
            exponent = np.where(np.abs(mantissa) > 0.7071067811865476, exponent, exponent - 1)
            s = np.where(slope == 0, 0.0, np.copysign(np.ldexp(1.0, exponent), slope))
        fits = (slope == 0) | (np.isfinite(slope) & (np.abs(exponent) <= _SLOPE_EXPONENT))
        s = np.where(fits, s, 0.0)
        ok = fits & (lower.size >= 3) & (upper.size >= 3)
        floor, lo_low, hi_low, bad_low = _interior(lower, s, ok, largest=True)
        ceiling, lo_up, hi_up, bad_up = _interior(upper, s, ok, largest=False)
        ok &= ~bad_low & ~bad_up
        lo = np.where(ok, np.maximum(lo_low, lo_up), np.inf)
        hi = np.where(ok, np.minimum(hi_low, hi_up), -np.inf)
        # a segment whose ends have one offset: the open segment (an exact relation's line)
        ends_x, ends_y = lower.x[np.stack([first, last])], lower.y[np.stack([first, last])]
        with np.errstate(all="ignore"):
            high, low = _two_sum(ends_y, -(s * ends_x))
        line = fits & (lower.size == 2) & (upper.size == 2)
        line &= (_safe(ends_x) & _safe(ends_y) & np.isfinite(high) & np.isfinite(low)).all(axis=0)
        line &= (high[0] == high[1]) & (low[0] == low[1])
        for part, value in zip((*floor, *ceiling), (high[0], low[0], high[0], low[0]), strict=True):
            part[line] = value[line]
        lo = np.where(line, ends_x[0], lo)
        hi = np.where(line, ends_x[1], hi)
        return Band(s, lo, hi, floor, ceiling, line)

    def inside(self, slot: IntArray, px: FloatArray, py: FloatArray) -> BoolArray:
        """Where the sample ``(px, py)`` of chain slot ``slot`` is in its hull's band."""
        s = self.slope.take(slot)
        lo, hi = self.lo.take(slot), self.hi.take(slot)
        with np.errstate(all="ignore"):
            high, low = _two_sum(py, -(s * px))
            fh, fl = (part.take(slot) for part in self.floor)
            ch, cl = (part.take(slot) for part in self.ceiling)
            found: BoolArray = (px >= lo) & (px <= hi)
            found &= (high > fh) | ((high == fh) & (low > fl))
            found &= (high < ch) | ((high == ch) & (low < cl))
            found |= self.line.take(slot) & (px > lo) & (px < hi) & (high == fh) & (low == fl)
            found &= _safe(px) & _safe(py)
        return found


def _interior(
    chains: Chains, s: FloatArray, ok: BoolArray, largest: bool
) -> tuple[tuple[FloatArray, FloatArray], FloatArray, FloatArray, BoolArray]:
    """Per chain (where ``ok``), the greatest (``largest``, else the least) offset ``y -
    s*x`` of its interior vertices as a two-sum, the ``x`` of its first and last interior
    vertex, and whether an interior vertex is outside the safe range."""
    count = len(chains.size)
    size = np.where(ok, chains.size - 2, 0)
    slot = np.repeat(np.arange(count), size)
    heads = np.cumsum(size) - size
    vertex = chains.start[slot] + 1 + (np.arange(len(slot)) - heads[slot])
    x, y = chains.x[vertex], chains.y[vertex]
    with np.errstate(all="ignore"):
        high, low = _two_sum(y, -(s[slot] * x))
    good = _safe(x) & _safe(y) & np.isfinite(high) & np.isfinite(low)
    bad = np.zeros(count, bool)
    bad[slot[~good]] = True
    sign = 1.0 if largest else -1.0  # the least is the negated greatest of the negated
    best_high = np.full(count, -np.inf)
    np.maximum.at(best_high, slot, sign * high)
    tie = np.flatnonzero(sign * high == best_high[slot])
    best_low = np.full(count, -np.inf)
    np.maximum.at(best_low, slot[tie], sign * low[tie])
    first_x = np.full(count, np.inf)
    last_x = np.full(count, -np.inf)
    mine = np.flatnonzero(ok)
    first_x[mine] = chains.x[chains.start[mine] + 1]
    last_x[mine] = chains.x[chains.start[mine] + chains.size[mine] - 2]
    return (sign * best_high, sign * best_low), first_x, last_x, bad


@dataclass
class Locator:
    """Hull vertices of some pairs, as chains, for location.

    ``slot[pair]`` is the pair's chain in ``lower`` and ``upper`` (or -1). Pairs whose
    hull is a point or a vertical segment get none.
    """

    slot: IntArray
    lower: Chains
    upper: Chains
    band: Band

    @staticmethod
    def build(hull: GroupSet, npairs: int) -> Locator:
        """The locator of every pair of ``hull`` that has a usable one."""
        slot = np.full(npairs, -1, np.int64)
        groups, starts, ends = hull.bounds()
        e = np.empty(0, np.int64)
        if not len(groups):
            none = Chains.of(hull, e, e)
            return Locator(slot, none, none, Band.of(none, none))
        run = np.repeat(np.arange(len(groups)), ends - starts)
        # the lexicographic maximum R: greatest x, then greatest y
        high_x = np.maximum.reduceat(hull.x, starts)
        at_high = hull.x == high_x[run]
        high_y = np.maximum.reduceat(np.where(at_high, hull.y, -np.inf), starts)
        at_top = at_high & (hull.y == high_y[run])
        position = np.arange(len(hull), dtype=np.int64)
        top = np.minimum.reduceat(np.where(at_top, position, len(hull)), starts)
        usable = np.flatnonzero((ends - starts >= 2) & (hull.x[starts] < high_x))
        slot[groups[usable]] = np.arange(len(usable))
        starts, ends, top = starts[usable], ends[usable], top[usable]
        # lower chain: L .. R; upper chain read from L: L, then the vertices back to R
        low_size = top - starts + 1
        up_size = ends - top + 1
        lower = _ragged(starts, low_size)
        back = _ragged(np.zeros_like(up_size), up_size)
        chain = np.repeat(np.arange(len(usable)), up_size)
        upper = np.where(back == 0, starts[chain], ends[chain] - back)
        low, up = Chains.of(hull, lower, low_size), Chains.of(hull, upper, up_size)
        return Locator(slot, low, up, Band.of(low, up))

    def covered(self, pair: IntArray, x: FloatArray, y: FloatArray) -> BoolArray:
        """Where ``(x, y)`` lies in its pair's closed hull and is none of its vertices."""
        out = np.zeros(len(pair), bool)
        slot = self.slot.take(pair) if len(pair) else pair
        mine = np.flatnonzero(slot >= 0)
        slot = slot.take(mine)
        px, py = x.take(mine), y.take(mine)
        low, up = self.lower, self.upper
        first = low.start.take(slot)
        last = first + low.size.take(slot) - 1
        with np.errstate(invalid="ignore"):
            spanned = (px >= low.x.take(first)) & (px <= low.x.take(last)) & ~np.isnan(py)
        banded = self.band.inside(slot, px, py)  # strictly inside: no orientation needed
        out[mine[banded]] = True
        sel = np.flatnonzero(spanned & ~banded)
        mine, slot, px, py = mine.take(sel), slot.take(sel), px.take(sel), py.take(sel)
        # on or left of the lower chain, then on or right of the upper one
        a, b = low.edge(slot, px)
        turn = low.turn(a, b, px, py)
        ok = turn >= 0
        ok &= ((px != low.x.take(a)) | (py != low.y.take(a))) & (
            (px != low.x.take(b)) | (py != low.y.take(b))
        )
        # a segment's upper chain is its lower one (L, R): on or right of the same edge,
        # so on it (the same exact sign); the other hulls test their upper chain
        segment = (low.size.take(slot) == 2) & (up.size.take(slot) == 2)
        out[mine[ok & segment & (turn == 0)]] = True
        rest = np.flatnonzero(ok & ~segment)
        slot, px, py = slot.take(rest), px.take(rest), py.take(rest)
        a, b = up.edge(slot, px)
        fit = up.turn(a, b, px, py) <= 0
        fit &= ((px != up.x.take(a)) | (py != up.y.take(a))) & (
            (px != up.x.take(b)) | (py != up.y.take(b))
        )
        out[mine[rest[fit]]] = True
        return out


def _ragged(starts: IntArray, lengths: IntArray) -> IntArray:
    """``concatenate([arange(s, s + n) for s, n in zip(starts, lengths)])``."""
    chain = np.repeat(np.arange(len(lengths)), lengths)
    offset = np.arange(len(chain)) - np.repeat(np.cumsum(lengths) - lengths, lengths)
    flat: IntArray = starts[chain] + offset
    return flat
