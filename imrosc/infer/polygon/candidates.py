"""Which samples of a chunk may be hull vertices: the fast equivalent of Algorithm 6.

Algorithm 6 keeps only the points outside the current polygon. Testing every sample of
every pair costs pairs x rows work (1,540 x 160,000 on the benchmark), so a chunk is
reduced without touching most (pair, row) combinations, using the shapes the
:class:`~imrosc.infer.polygon.guide.Guide` keeps strictly inside each current hull:

* per pair, the square box or the cheapest cross (a wide and a tall box) is chosen by
  costing each on a sample of the chunk; the rows outside it are read from per-variable
  sorted tails (one sort per variable per chunk serves all its pairs): part A, the rows
  left or right of the cross; part B, above or below it; part C, its corners, read from
  the smaller of the two tails and filtered by the other coordinate. The cost follows the
  number of samples near the boundary, not pairs x rows;
* pairs no cross fits (a band along a diagonal) are scanned row by row;
* every row so found is tested against the pair's polar table (a sector lookup, a compare);
* pairs where a variable takes few values (constants, flags, modes) keep, per value, only
  the rows with the least and greatest partner value; pairs of identical columns keep
  their two end points; pairs without a guide (no hull yet, or a degenerate one) keep all.

Everything discarded is provably strictly inside the current hull, hence no vertex of
``hull(current hull | chunk)``: the exact hull of the current vertices plus the survivors is
that hull, whatever the chunking.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from imrosc.infer.core import FloatArray
from imrosc.infer.polygon.guide import Guide
from imrosc.infer.polygon.hull import GroupSet, IntArray

BoolArray = npt.NDArray[np.bool_]

FEW_VALUES = 16
"""A discrete (int/uint/bool) column with at most this many values in a chunk is grouped."""

SAMPLE = 1024
"""Rows per chunk whose sorted values estimate how many rows a guide lets through."""

EXPANDING = 0.05
"""A guide letting more than this fraction of a chunk through calls for a head start."""

_SCAN = 0.75
"""Pairs whose cross would enumerate this fraction of the rows are scanned row by row."""

_BLOCK = 1 << 15
"""Samples filtered together (keeps the temporaries in cache)."""


def ragged_arange(starts: IntArray, lengths: IntArray) -> IntArray:
    """``concatenate([arange(s, s + n) for s, n in zip(starts, lengths)])``, vectorised."""
    lengths = lengths.astype(np.int64)
    total = int(lengths.sum())
    if total == 0:
        return np.empty(0, np.int64)
    keep = lengths > 0
    starts, lengths = starts[keep].astype(np.int64), lengths[keep]
    step = np.ones(total, np.int64)
    ends = np.cumsum(lengths)
    step[0] = starts[0]
    step[ends[:-1]] = starts[1:] - (starts[:-1] + lengths[:-1] - 1)
    return np.cumsum(step)


@dataclass
class Chunk:
    """One chunk of the polygon variables, column per variable (``(variables, rows)``)."""

    values: FloatArray
    discrete: Sequence[bool]

    def __post_init__(self) -> None:
        self.rows = self.values.shape[1]
        self.nan = np.isnan(self.values)
        self.has_nan: BoolArray = np.asarray(self.nan.any(axis=1), dtype=bool)
        with np.errstate(all="ignore"):
            self.low = np.fmin.reduce(self.values, axis=1) if self.rows else np.full(0, np.nan)
            self.high = np.fmax.reduce(self.values, axis=1) if self.rows else np.full(0, np.nan)
        self.empty = np.isnan(self.low)
        self._before: IntArray | None = None
        self._sorted_sample: dict[int, FloatArray] | None = None
        self.classes: tuple[list[tuple[int, IntArray]], IntArray, IntArray] | None = None
        self.plan: _Plan | None = None
        self.plan_stamp = np.empty(0, np.int64)

    def every(self, stride: int) -> Chunk:
        """The chunk's rows ``0, stride, 2 * stride, ...``."""
        return Chunk(np.ascontiguousarray(self.values[:, ::stride]), self.discrete)

    def extreme_rows(self, count: int) -> IntArray:
        """Per variable, rows of its ``count`` least and ``count`` greatest values
        (``(variables, 2 * count)``; rows of missing values may stand among the greatest)."""
        if 2 * count >= self.rows:
            rows = np.broadcast_to(np.arange(self.rows), (self.values.shape[0], self.rows))
            return np.ascontiguousarray(rows).astype(np.int64)
        split = np.argpartition(self.values, (count, self.rows - count - 1), axis=1)
        return np.concatenate([split[:, :count], split[:, -count:]], axis=1).astype(np.int64)

    def sample_size(self) -> int:
        """Rows in the estimation sample."""
        return len(_sample_rows(self.rows, SAMPLE))

    def sorted_sample(self) -> dict[int, FloatArray]:
        """Per variable, the sorted present values of the estimation sample."""
        if self._sorted_sample is None:
            picked = self.values[:, _sample_rows(self.rows, SAMPLE)]
            self._sorted_sample = {}
            for var in range(picked.shape[0]):
                column = picked[var]
                self._sorted_sample[var] = np.sort(column[~np.isnan(column)])
        return self._sorted_sample

    def valid_counts(self, pi: IntArray, pj: IntArray) -> IntArray:
        """Rows where both variables of each pair are present."""
        counts = np.full(len(pi), self.rows, np.int64)
        gaps = np.flatnonzero(self.has_nan)
        if not len(gaps):
            return counts
        missing = self.nan[gaps].astype(np.float64)
        both = missing @ missing.T  # exact: integer counts far below 2**53
        slot = np.full(len(self.has_nan), -1, np.int64)
        slot[gaps] = np.arange(len(gaps))
        a, b = slot[pi], slot[pj]
        single = np.diag(both)
        lost = np.where(a >= 0, single[np.maximum(a, 0)], 0) + np.where(
            b >= 0, single[np.maximum(b, 0)], 0
        )
        lost -= np.where((a >= 0) & (b >= 0), both[np.maximum(a, 0), np.maximum(b, 0)], 0)
        return counts - lost.astype(np.int64)

    def valid_rank(self, pi: IntArray, pj: IntArray, pair: IntArray, row: IntArray) -> IntArray:
        """Position of ``row`` among the rows where pair ``pair`` is present."""
        rank: IntArray = row.astype(np.int64).copy()
        if not self.has_nan.any() or not len(row):
            return rank
        if self._before is None:
            self._before = np.zeros((self.values.shape[0], self.rows + 1), np.int64)
            np.cumsum(self.nan, axis=1, out=self._before[:, 1:])
        i, j = pi[pair], pj[pair]
        rank -= self._before[i, row] + self._before[j, row]
        both = self.has_nan[i] & self.has_nan[j]
        for p in np.unique(pair[both]).tolist():
            mine = np.flatnonzero(both & (pair == p))
            shared = np.zeros(self.rows + 1, np.int64)
            np.cumsum(self.nan[pi[p]] & self.nan[pj[p]], out=shared[1:])
            rank[mine] += shared[row[mine]]
        return rank


def _few_valued(chunk: Chunk) -> BoolArray:
    """Constant variables, and discrete ones with at most ``FEW_VALUES`` values here."""
    few: BoolArray = np.asarray((chunk.low == chunk.high) & ~chunk.empty, dtype=bool)
    for var in np.flatnonzero(~few & ~chunk.empty & np.asarray(chunk.discrete, bool)).tolist():
        column = chunk.values[var][~chunk.nan[var]]
        if len(np.unique(column)) <= FEW_VALUES:
            few[var] = True
    return few


def _identical(chunk: Chunk, wanted: BoolArray) -> dict[int, int]:
    """Map each wanted variable to the first wanted one with the very same column."""
    first: dict[bytes, list[int]] = {}
    root: dict[int, int] = {}
    for var in np.flatnonzero(wanted).tolist():
        column = chunk.values[var]
        key = column.tobytes()
        for other in first.get(key, []):
            if np.array_equal(column, chunk.values[other], equal_nan=True):
                root[var] = other
                break
        else:
            first.setdefault(key, []).append(var)
            root[var] = var
    return root


def _grouped(chunk: Chunk, var: int, pairs: IntArray, pi: IntArray, pj: IntArray) -> GroupSet:
    """Candidates of pairs where ``var`` takes few values: per value, the partner's ends."""
    values = chunk.values[var]
    order = np.argsort(values, kind="stable")
    count = int(np.count_nonzero(~chunk.nan[var]))
    order = order[:count]
    keys = values[order]
    starts = np.concatenate([[0], np.flatnonzero(np.diff(keys)) + 1]).astype(np.int64)
    run = np.zeros(count, np.int64)
    run[starts[1:]] = 1
    run = np.cumsum(run)
    partner = np.where(pi[pairs] == var, pj[pairs], pi[pairs])
    other = chunk.values[partner][:, order]
    position = np.broadcast_to(np.arange(count), other.shape)
    parts: list[tuple[IntArray, IntArray]] = []
    with np.errstate(all="ignore"):
        for reduce in (np.fmin, np.fmax):
            ends = reduce.reduceat(other, starts, axis=1)
            hit = other == ends[:, run]
            at = np.minimum.reduceat(np.where(hit, position, count), starts, axis=1)
            p_idx, g_idx = np.nonzero(at < count)
            parts.append((pairs[p_idx], order[at[p_idx, g_idx]]))
    pair = np.concatenate([parts[0][0], parts[1][0]])
    row = np.concatenate([parts[0][1], parts[1][1]])
    return _points(chunk, pi, pj, pair, row)


def _points(chunk: Chunk, pi: IntArray, pj: IntArray, pair: IntArray, row: IntArray) -> GroupSet:
    order = np.argsort(pair, kind="stable")
    pair, row = pair[order], row[order]
    x = chunk.values[pi[pair], row]
    y = chunk.values[pj[pair], row]
    return GroupSet(pair.astype(np.int64), x, y, row.astype(np.int64))


def _sample_rows(rows: int, size: int) -> IntArray:
    return np.arange(0, rows, max(1, rows // size), dtype=np.int64)


def _counts(
    sorted_sample: dict[int, FloatArray], owner: IntArray, lo: FloatArray, hi: FloatArray
) -> FloatArray:
    """Sampled rows of ``owner`` outside ``[lo, hi]`` (``(options, pairs)`` each)."""
    out = np.zeros(lo.shape)
    for var in np.unique(owner).tolist():
        mine = np.flatnonzero(owner == var)
        values = sorted_sample[var]
        below = np.searchsorted(values, lo[:, mine], side="left")
        above = np.searchsorted(values, hi[:, mine], side="right")
        out[:, mine] = below + len(values) - np.maximum(above, below)
    return out


@dataclass
class _Plan:
    """Per pair: the cross (or square) whose outside is enumerated, and its cost estimate."""

    a: FloatArray  # (2, pairs): x interval of part A (enumerated from x)
    b: FloatArray  # (2, pairs): y interval of part B (enumerated from y)
    c: FloatArray  # (4, pairs): x and y intervals of part C (corners)
    c_on_x: BoolArray  # part C enumerated from x (else from y)
    cost: FloatArray  # estimated fraction of rows enumerated


def _plan(chunk: Chunk, pairs: IntArray, pi: IntArray, pj: IntArray, guide: Guide) -> _Plan:
    """The cheapest cross (or the square) per pair, cached on the chunk while guides hold."""
    if chunk.plan is None:
        n = len(pi)
        chunk.plan = _Plan(
            np.zeros((2, n)), np.zeros((2, n)), np.zeros((4, n)), np.zeros(n, bool), np.zeros(n)
        )
        chunk.plan_stamp = np.full(n, -1, np.int64)
    plan = chunk.plan
    need = pairs[chunk.plan_stamp[pairs] != guide.stamp[pairs]]
    if len(need):
        fresh = _make_plan(chunk, need, pi, pj, guide)
        plan.a[:, need] = fresh.a
        plan.b[:, need] = fresh.b
        plan.c[:, need] = fresh.c
        plan.c_on_x[need] = fresh.c_on_x
        plan.cost[need] = fresh.cost
        chunk.plan_stamp[need] = guide.stamp[need]
    return _take_plan(plan, pairs)


def _take_plan(plan: _Plan, pairs: IntArray) -> _Plan:
    return _Plan(
        plan.a[:, pairs], plan.b[:, pairs], plan.c[:, pairs], plan.c_on_x[pairs], plan.cost[pairs]
    )


def _make_plan(chunk: Chunk, pairs: IntArray, pi: IntArray, pj: IntArray, guide: Guide) -> _Plan:
    sample = chunk.sorted_sample()
    size = max(1, chunk.sample_size())
    ox, oy = pi[pairs], pj[pairs]
    sq = guide.square[:, pairs]
    wide = guide.wide[:, :, pairs]
    tall = guide.tall[:, :, pairs]
    k = wide.shape[0]
    # option 0: the square box; option 1 + a * k + b: wide[a] with tall[b]
    ax = np.concatenate([sq[None, 0:2], np.repeat(wide[:, 0:2], k, axis=0)])
    by = np.concatenate([sq[None, 2:4], np.tile(tall[:, 2:4], (k, 1, 1))])
    cx = np.concatenate(
        [np.full((1, 2, len(pairs)), [[-np.inf], [np.inf]]), np.tile(tall[:, 0:2], (k, 1, 1))]
    )
    cy = np.concatenate(
        [np.full((1, 2, len(pairs)), [[-np.inf], [np.inf]]), np.repeat(wide[:, 2:4], k, axis=0)]
    )
    col = np.arange(len(pairs))
    sides = ((ax, ox), (by, oy), (cx, ox), (cy, oy))
    # a pair whose guide is unchanged keeps its choice: only that option is costed
    kept = guide.choice_stamp[pairs] == guide.stamp[pairs]
    best = np.where(kept, guide.choice[pairs], 0)
    cost = np.zeros((4, len(pairs)))
    fresh = np.flatnonzero(~kept)
    if len(fresh):
        parts = [
            _counts(sample, owner[fresh], option[:, 0, fresh], option[:, 1, fresh])
            for option, owner in sides
        ]
        choice = np.argmin(parts[0] + parts[1] + np.minimum(parts[2], parts[3]), axis=0)
        best[fresh] = choice
        guide.choice[pairs[fresh]] = choice
        guide.choice_stamp[pairs[fresh]] = guide.stamp[pairs[fresh]]
        cost[:, fresh] = np.stack([part[choice, np.arange(len(fresh))] for part in parts])
    old = np.flatnonzero(kept)
    if len(old):
        pick = best[old]
        cost[:, old] = np.stack(
            [
                _counts(sample, owner[old], option[pick, 0, old][None], option[pick, 1, old][None])[
                    0
                ]
                for option, owner in sides
            ]
        )
    total = cost[0] + cost[1] + np.minimum(cost[2], cost[3])
    return _Plan(
        a=ax[best, :, col].T,
        b=by[best, :, col].T,
        c=np.concatenate([cx[best, :, col].T, cy[best, :, col].T]),
        c_on_x=cost[2] <= cost[3],
        cost=total / size,
    )


def _general(
    chunk: Chunk, pairs: IntArray, pi: IntArray, pj: IntArray, guide: Guide, cross: bool = True
) -> GroupSet:
    """Candidates of the pairs with continuous variables (see the module docstring)."""
    if not len(pairs):
        return GroupSet.empty()
    plan = _plan(chunk, pairs, pi, pj, guide) if cross else _square_plan(pairs, guide)
    ox, oy = pi[pairs], pj[pairs]
    nvar = chunk.values.shape[0]
    # parts: A from x, B from y, C (corners) from x or y; each as (owner, lo, hi)
    c_owner = np.where(plan.c_on_x, ox, oy)
    c_lo = np.where(plan.c_on_x, plan.c[0], plan.c[2])
    c_hi = np.where(plan.c_on_x, plan.c[1], plan.c[3])
    parts = ((ox, plan.a[0], plan.a[1]), (oy, plan.b[0], plan.b[1]), (c_owner, c_lo, c_hi))
    scan = plan.cost >= _SCAN
    need_lo = np.full(nvar, -np.inf)
    need_hi = np.full(nvar, np.inf)
    for owner, lo, hi in parts:
        np.maximum.at(need_lo, owner[~scan], lo[~scan])
        np.minimum.at(need_hi, owner[~scan], hi[~scan])
    sorted_values: dict[int, FloatArray] = {}
    sorted_rows: list[IntArray] = []
    offsets = np.zeros(nvar, np.int64)
    total = 0
    for var in np.union1d(ox[~scan], oy[~scan]).tolist():
        column = chunk.values[var]
        with np.errstate(invalid="ignore"):
            rows = np.flatnonzero((column < need_lo[var]) | (column > need_hi[var]))
        order = np.argsort(column[rows], kind="stable")
        sorted_rows.append(rows[order].astype(np.int64))
        sorted_values[var] = column[rows][order]
        offsets[var] = total
        total += len(rows)
    flat_rows = np.concatenate(sorted_rows) if sorted_rows else np.empty(0, np.int64)
    values = chunk.values.ravel()
    width = chunk.rows
    gaps = bool(chunk.has_nan.any())
    other_lo = np.where(plan.c_on_x, plan.c[2], plan.c[0])
    other_hi = np.where(plan.c_on_x, plan.c[3], plan.c[1])
    found: list[GroupSet] = []
    for part, (owner, lo, hi) in enumerate(parts):
        starts = np.zeros((len(pairs), 2), np.int64)
        lengths = np.zeros((len(pairs), 2), np.int64)
        for var in np.unique(owner[~scan]).tolist():
            mine = np.flatnonzero((owner == var) & ~scan)
            vals = sorted_values[var]
            below = np.searchsorted(vals, lo[mine], side="left")
            above = np.maximum(np.searchsorted(vals, hi[mine], side="right"), below)
            starts[mine, 0] = offsets[var]
            lengths[mine, 0] = below
            starts[mine, 1] = offsets[var] + above
            lengths[mine, 1] = len(vals) - above
        all_rows = flat_rows.take(ragged_arange(starts.ravel(), lengths.ravel()))
        all_slots = np.repeat(np.arange(len(pairs)), lengths.sum(axis=1))
        for first in range(0, len(all_rows), _BLOCK):
            row = all_rows[first : first + _BLOCK]
            slot = all_slots[first : first + _BLOCK]
            x = values.take(ox.take(slot) * width + row)
            y = values.take(oy.take(slot) * width + row)
            pair = pairs.take(slot)
            with np.errstate(invalid="ignore"):
                if part == 2:  # corners: outside the cross on the other axis too
                    other = np.where(plan.c_on_x.take(slot), y, x)
                    out = (other < other_lo.take(slot)) | (other > other_hi.take(slot))
                    sel = np.flatnonzero(out)
                    slot, row, pair = slot.take(sel), row.take(sel), pair.take(sel)
                    x, y = x.take(sel), y.take(sel)
                keep = ~guide.inside(pair, x, y)
                if gaps:  # a NaN compares false everywhere: drop it explicitly
                    keep &= ~(np.isnan(x) | np.isnan(y))
                if part == 1:  # rows of A come from A
                    keep &= (x >= plan.a[0].take(slot)) & (x <= plan.a[1].take(slot))
            sel = np.flatnonzero(keep)
            found.append(GroupSet(pair.take(sel), x.take(sel), y.take(sel), row.take(sel)))
    # pairs no cross fits (bands along a diagonal, no hull yet): every row, by blocks
    rows_all = np.arange(width, dtype=np.int64)
    for slot in np.flatnonzero(scan).tolist():
        x = chunk.values[ox[slot]]
        y = chunk.values[oy[slot]]
        sel = np.flatnonzero(~(np.isnan(x) | np.isnan(y)))
        pair = np.full(len(sel), pairs[slot], np.int64)
        found.append(_outside(guide, pair, x[sel], y[sel], rows_all[sel]))
    return GroupSet.concat(found)


def _outside(guide: Guide, pair: IntArray, x: FloatArray, y: FloatArray, row: IntArray) -> GroupSet:
    """The samples the guide cannot place strictly inside their pair's hull."""
    sel = np.flatnonzero(~guide.inside(pair, x, y))
    return GroupSet(pair[sel].astype(np.int64), x[sel], y[sel], row[sel])


def _square_plan(pairs: IntArray, guide: Guide) -> _Plan:
    """Only the square box (part C empty)."""
    sq = guide.square[:, pairs]
    none = np.empty((4, len(pairs)))
    none[0::2] = -np.inf
    none[1::2] = np.inf
    return _Plan(sq[0:2], sq[2:4], none, np.ones(len(pairs), bool), np.zeros(len(pairs)))


def _classify(
    chunk: Chunk, pi: IntArray, pj: IntArray
) -> tuple[list[tuple[int, IntArray]], IntArray, IntArray]:
    """``(grouped by a few-valued variable, identical pairs, general pairs)``."""
    if chunk.classes is None:
        chunk.classes = _classes(chunk, pi, pj)
    return chunk.classes


def _classes(
    chunk: Chunk, pi: IntArray, pj: IntArray
) -> tuple[list[tuple[int, IntArray]], IntArray, IntArray]:
    alive = ~(chunk.empty[pi] | chunk.empty[pj])
    few = _few_valued(chunk)
    grouped = alive & (few[pi] | few[pj])
    groups: list[tuple[int, IntArray]] = []
    if grouped.any():
        # group by the variable with few values (the first one when both have)
        by = np.where(few[pi], pi, pj)
        for var in np.unique(by[grouped]).tolist():
            groups.append((var, np.flatnonzero(grouped & (by == var))))
    rest = alive & ~grouped
    wanted = np.zeros(len(few), bool)
    wanted[pi[rest]] = True
    wanted[pj[rest]] = True
    root = _identical(chunk, wanted)
    lookup = np.array([root.get(v, -1 - v) for v in range(len(few))], np.int64)
    twin = rest & (lookup[pi] == lookup[pj])
    return groups, np.flatnonzero(twin), np.flatnonzero(rest & ~twin)


def seeds(
    chunk: Chunk, pi: IntArray, pj: IntArray, guide: Guide, only: BoolArray, extremes: int
) -> GroupSet:
    """Likely vertices for the pairs in ``only``: the rows holding each variable's
    ``extremes`` least and greatest values, plus a regular sample of rows."""
    _, _, general = _classify(chunk, pi, pj)
    pairs = general[only[general]]
    if not len(pairs) or not chunk.rows:
        return GroupSet.empty()
    ends = chunk.extreme_rows(extremes)
    sample = _sample_rows(chunk.rows, 2 * extremes)
    rows = np.concatenate(
        [ends[pi[pairs]], ends[pj[pairs]], np.broadcast_to(sample, (len(pairs), len(sample)))],
        axis=1,
    )
    pair = np.repeat(pairs, rows.shape[1])
    row = rows.ravel()
    x = chunk.values[pi[pair], row]
    y = chunk.values[pj[pair], row]
    keep = ~(np.isnan(x) | np.isnan(y))
    keep[keep] = ~guide.inside(pair[keep], x[keep], y[keep])
    sel = np.flatnonzero(keep)
    return GroupSet(pair[sel], x[sel], y[sel], row[sel])


def expanding(chunk: Chunk, pi: IntArray, pj: IntArray, guide: Guide) -> BoolArray:
    """Pairs whose guide would let more than ``EXPANDING`` of the chunk's rows through."""
    _, _, general = _classify(chunk, pi, pj)
    out = np.zeros(len(pi), bool)
    if len(general):
        out[general] = _plan(chunk, general, pi, pj, guide).cost > EXPANDING
    return out


def candidates(
    chunk: Chunk,
    pi: IntArray,
    pj: IntArray,
    guide: Guide,
    cross: bool = True,
    only: BoolArray | None = None,
) -> GroupSet:
    """The chunk's samples that may be vertices of ``hull(current hull | chunk)``.

    ``at`` of the result is the sample's row in the chunk; ``guide`` (shapes inside the
    current hulls) decides what is discarded; ``cross=False`` uses only the square box
    (cheaper to plan, for small chunks); ``only`` restricts the work to some continuous
    pairs (a head start: the other pairs get nothing).
    """
    groups, twins, general = _classify(chunk, pi, pj)
    if only is not None:
        return _general(chunk, general[only[general]], pi, pj, guide, cross)
    parts = [_grouped(chunk, var, pairs, pi, pj) for var, pairs in groups]
    if len(twins):
        column = chunk.values[pi[twins]]
        low = np.nanargmin(column, axis=1)
        high = np.nanargmax(column, axis=1)
        pair = np.concatenate([twins, twins])
        row = np.concatenate([low, high]).astype(np.int64)
        parts.append(_points(chunk, pi, pj, pair, row))
    parts.append(_general(chunk, general, pi, pj, guide, cross))
    return GroupSet.concat(parts)
