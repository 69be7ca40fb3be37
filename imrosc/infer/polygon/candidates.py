"""Which samples of a chunk may be hull vertices: the fast equivalent of Algorithm 6.

Algorithm 6 keeps only the points outside the current polygon. Testing every sample of
every pair costs pairs x rows work (1,540 x 160,000 on the benchmark), so a chunk is
reduced without touching most (pair, row) combinations, using what the
:class:`~imrosc.infer.polygon.guide.Guide` knows to lie inside each current hull:

* per pair, the cheapest box (the square one, a wide or a tall one) or cross (a wide and a
  tall box) is chosen by costing each on a sample of the chunk; the rows outside it are
  read from per-variable sorted tails (one sort per variable per chunk serves all its
  pairs): part A, the rows left or right of the cross; part B, above or below it; part C,
  its corners, read from the smaller of the two tails and filtered by the other
  coordinate. The cost follows the number of samples near the boundary, not pairs x rows;
* pairs no cross fits well (a band along a diagonal, a random walk wandering off the
  box) go by blocks of consecutive rows instead: a block whose bounding box has its four
  corners inside the hull has every row inside (the hull's interior is convex), so only
  the rows of the other blocks are read, refining 256-row blocks into 32-row ones. Smooth
  signals (positions, integrated quantities) have small boxes: few blocks stay open.
  Rows drawn independently leave most blocks open: a pair whose open blocks would hold
  more than ``_CROSS_GAIN`` times the rows of its cross (if it costs under
  ``_CROSS_AT_MOST``) goes by the cross after all;
* every row so found is tested against the pair's polar table (a sector lookup, a compare);
* pairs without a table whose hull is a segment or a sliver (a variable that is a linear
  function of the other, up to rounding) have every row located exactly in their hull
  (:mod:`~imrosc.infer.polygon.locate`);
* pairs where a variable takes few values (constants, flags, modes, whatever their type)
  keep, per value, only the rows with the least and greatest partner value, found in the
  partner's tails; pairs of identical (or exactly negated) columns keep their two end
  points; pairs without any hull keep all.

Everything discarded is provably in the current hull and none of its vertices, hence no
vertex of ``hull(current hull | chunk)``: the exact hull of the current vertices plus the
survivors is that hull, whatever the chunking.

A chunk where a pair's guide fits badly (no hull yet, a variable drifting into new ground)
first gives that pair a head start (:func:`seeds`, :func:`heads`): likely vertices whose
hull, inside the final one, tightens the guide before the whole chunk is filtered.
"""

from __future__ import annotations

import itertools
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from imrosc.infer.core import FloatArray
from imrosc.infer.polygon.guide import Guide
from imrosc.infer.polygon.hull import GroupSet, IntArray

BoolArray = npt.NDArray[np.bool_]

FEW_VALUES = 16
"""A column with at most this many values in a chunk is grouped (see :func:`_few_valued`)."""

SAMPLE = 1024
"""Rows per chunk whose sorted values estimate how many rows a guide lets through."""

TAIL = 4
"""A variable's tails hold its values beyond the ``TAIL``-th least and greatest sampled."""

EXPANDING = 0.05
"""A guide letting more than this fraction of a chunk through calls for a head start."""

_BY_BLOCKS = 0.15
"""Pairs whose cross would enumerate this fraction of the rows go by blocks instead."""

_CROSS_AT_MOST = 0.6
"""Pairs whose cross would enumerate more than this fraction of the rows go by blocks."""
_CROSS_GAIN = 1.5
"""A pair goes by its cross after all when its open blocks hold this many times the rows."""

_NEGATED_HEAD = 64
"""Rows whose bytes pick the candidate negated columns (see :func:`_negated`)."""

_RUNS = 8
"""A block of samples of fewer runs of one pair than this is filtered run by run."""

_BLOCK = 1 << 15
"""Samples filtered together (keeps the temporaries in cache)."""

_LINE_HEAD = 256
"""Rows of a pair read in full that tell whether it has rows on ``y = x`` or ``y = -x``."""

BLOCKS = (256, 32)
"""Sizes of the blocks of consecutive rows whose bounding boxes are tested, coarse to fine."""


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
        self._extremes: dict[tuple[int, int], IntArray] = {}
        self._tails: dict[int, tuple[IntArray, IntArray]] = {}
        self.levels: dict[int, FloatArray] = {}
        self._blocks: dict[int, tuple[FloatArray, FloatArray]] = {}
        self._firsts: dict[int, IntArray] = {}
        self._block_rows: dict[int, IntArray] = {}
        self.classes: tuple[list[tuple[int, IntArray]], IntArray, IntArray] | None = None
        self.plan: _Plan | None = None
        self.plan_stamp = np.empty(0, np.int64)

    def block_bounds(self, size: int) -> tuple[FloatArray, FloatArray]:
        """Per variable and block of ``size`` consecutive rows, the least and greatest
        present value (NaN for a block without any), ``(variables, blocks)`` each."""
        found = self._blocks.get(size)
        if found is None:
            base = BLOCKS[-1]
            if size % base == 0 and size > base:
                # from the finest blocks: a least of least values is the least value
                low, high = self.block_bounds(base)
                factor = size // base
                blocks = -(-low.shape[1] // factor)
                parts = []
                for fine, reduce in ((low, np.fmin), (high, np.fmax)):
                    padded = np.full((len(fine), blocks * factor), np.nan)
                    padded[:, : fine.shape[1]] = fine
                    parts.append(reduce.reduce(padded.reshape(len(fine), blocks, factor), axis=2))
                found = (parts[0], parts[1])
            else:
                starts = np.arange(0, self.rows, size)
                with np.errstate(all="ignore"):
                    found = (
                        np.fmin.reduceat(self.values, starts, axis=1),
                        np.fmax.reduceat(self.values, starts, axis=1),
                    )
            self._blocks[size] = found
        return found

    def block_extremes(self, size: int) -> IntArray:
        """Per variable and block of ``size`` consecutive rows, the rows of its least and
        greatest present value, ``(variables, 2, blocks)`` (a row of a missing value for a
        block without any)."""
        found = self._block_rows.get(size)
        if found is None:
            blocks = -(-self.rows // size)
            low = np.empty((self.values.shape[0], blocks), np.int64)
            high = np.empty_like(low)
            padded = np.full(blocks * size, np.nan)
            for var, column in enumerate(self.values):  # a column at a time: small temporaries
                padded[: self.rows] = column
                shaped = padded.reshape(blocks, size)
                if self.has_nan[var] or blocks * size > self.rows:
                    gaps = np.isnan(shaped)
                    low[var] = np.where(gaps, np.inf, shaped).argmin(axis=1)
                    high[var] = np.where(gaps, -np.inf, shaped).argmax(axis=1)
                else:
                    low[var] = shaped.argmin(axis=1)
                    high[var] = shaped.argmax(axis=1)
            start = np.arange(blocks) * size
            found = np.minimum(np.stack([low + start, high + start], axis=1), self.rows - 1)
            self._block_rows[size] = found
        return found

    def extreme_rows(self, variables: IntArray, count: int) -> IntArray:
        """Rows of the ``count`` least and ``count`` greatest values of each of
        ``variables`` (``(len(variables), 2 * count)``, or every row when the chunk is that
        short; rows of missing values may stand among the greatest)."""
        if 2 * count >= self.rows:
            return np.broadcast_to(
                np.arange(self.rows, dtype=np.int64), (len(variables), self.rows)
            )
        out = np.empty((len(variables), 2 * count), np.int64)
        for k, var in enumerate(variables.tolist()):
            found = self._extremes.get((var, count))
            if found is None:
                split = np.argpartition(self.values[var], (count, self.rows - count - 1))
                found = np.concatenate([split[:count], split[-count:]]).astype(np.int64)
                self._extremes[(var, count)] = found
            out[k] = found
        return out

    def first_rows(self, var: int) -> IntArray:
        """The first row of each present value of ``var``, in increasing value order."""
        found = self._firsts.get(var)
        if found is None:
            column = self.values[var]
            _, index = np.unique(column, return_index=True)
            found = index[~np.isnan(column[index])].astype(np.int64)
            self._firsts[var] = found
        return found

    def tail_rows(self, var: int) -> tuple[IntArray, IntArray]:
        """Rows of ``var``'s low and high tails: values at most (at least) the ``TAIL``-th
        least (greatest) of the estimation sample, ties included (about ``TAIL`` / ``SAMPLE``
        of the rows each, whatever the distribution)."""
        found = self._tails.get(var)
        if found is None:
            sample = self.sorted_sample()[var]
            if not len(sample):
                empty = np.empty(0, np.int64)
                found = (empty, empty)
            else:
                column = self.values[var]
                low = sample[min(TAIL, len(sample) - 1)]
                high = sample[max(len(sample) - 1 - TAIL, 0)]
                found = (np.flatnonzero(column <= low), np.flatnonzero(column >= high))
            self._tails[var] = found
        return found

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
    """Constant variables, and the others with at most ``FEW_VALUES`` values here (their
    values go to ``chunk.levels``): discrete ones (int/uint/bool) always looked at, float
    ones (modes, flags or integer counts stored as floats) when the estimation sample
    shows few values (a continuous column shows about one per sampled row)."""
    few: BoolArray = np.asarray((chunk.low == chunk.high) & ~chunk.empty, dtype=bool)
    for var in np.flatnonzero(few).tolist():
        chunk.levels[var] = chunk.low[var : var + 1].copy()
    discrete = np.asarray(chunk.discrete, bool)
    for var in np.flatnonzero(~few & ~chunk.empty).tolist():
        if not discrete[var]:
            sample = chunk.sorted_sample()[var]
            if len(sample) and 1 + int(np.count_nonzero(np.diff(sample))) > FEW_VALUES:
                continue
        levels = np.unique(chunk.values[var][~chunk.nan[var]])
        if len(levels) <= FEW_VALUES:
            few[var] = True
            chunk.levels[var] = levels
    return few


def _identical(chunk: Chunk, wanted: BoolArray) -> dict[int, int]:
    """Map each wanted variable to the first wanted one with the very same column (the
    same bytes: the first rows' pick the candidates, compared in full)."""
    first: dict[bytes, list[int]] = {}
    root: dict[int, int] = {}
    bits = chunk.values.view(np.uint64)
    for var in np.flatnonzero(wanted).tolist():
        key = bits[var, :_NEGATED_HEAD].tobytes()
        for other in first.get(key, []):
            if np.array_equal(bits[var], bits[other]):
                root[var] = other
                break
        else:
            first.setdefault(key, []).append(var)
            root[var] = var
    return root


def _negated(chunk: Chunk, wanted: BoolArray) -> BoolArray:
    """``(variables, variables)``: where one wanted column is the other's negation, value
    for value (NaN where the other has NaN). Such a pair's samples lie on the line ``y =
    -x`` exactly (negation is exact), so its hull, like an identical pair's, is the
    segment between the samples of least and greatest ``x``."""
    out = np.zeros((len(wanted), len(wanted)), bool)
    variables = np.flatnonzero(wanted).tolist()
    # the first rows' bytes pick the candidates, compared in full
    head = chunk.values[:, :_NEGATED_HEAD]
    first: dict[bytes, list[int]] = {}
    for var in variables:
        first.setdefault(head[var].tobytes(), []).append(var)
    for var in variables:
        for other in first.get((-head[var]).tobytes(), []):
            if np.array_equal(-chunk.values[var], chunk.values[other], equal_nan=True):
                out[var, other] = out[other, var] = True
    return out


def _grouped(chunk: Chunk, var: int, pairs: IntArray, pi: IntArray, pj: IntArray) -> GroupSet:
    """Candidates of pairs where ``var`` takes few values: per value, the partner's ends.

    Each end is the row of the least (greatest) partner value among the rows of that
    value of ``var``, the earliest on ties. They are looked for in the partner's tails
    first; pairs where a value has no row there are done in full.
    """
    partner = np.where(pi[pairs] == var, pj[pairs], pi[pairs])
    # a constant partner without gaps: every end is the value's first row
    flat = (chunk.low[partner] == chunk.high[partner]) & ~chunk.has_nan[partner]
    firsts = chunk.first_rows(var)
    found = [(np.repeat(pairs[flat], len(firsts)), np.tile(firsts, int(flat.sum())))]
    pair, row, missed = _ends_in_tails(chunk, var, pairs[~flat], partner[~flat])
    found.append((pair, row))
    if missed.any():
        found.append(_ends_in_full(chunk, var, pairs[~flat][missed], partner[~flat][missed]))
    return _points(
        chunk, pi, pj, np.concatenate([p for p, _ in found]), np.concatenate([r for _, r in found])
    )


def _ends_in_tails(
    chunk: Chunk, var: int, pairs: IntArray, partner: IntArray
) -> tuple[IntArray, IntArray, BoolArray]:
    """``(pair, row)`` of the per-value ends found in the partners' tails, and which pairs
    miss a value there.

    A tail holds every row whose value lies beyond its threshold, ties included, so the
    least partner value of the rows of a value of ``var`` met in the low tail is that
    value's least, and its earliest row there is the earliest of all.
    """
    levels = chunk.levels[var]
    keys = chunk.values[var]
    cells = len(pairs) * len(levels)  # one per (pair, value of var)
    found_cell: list[IntArray] = []
    found_row: list[IntArray] = []
    missed = np.zeros(len(pairs), bool)
    longest = max(chunk.rows // 4, 1024)
    for side, sign in ((0, 1.0), (1, -1.0)):
        tails = [chunk.tail_rows(p)[side] for p in partner.tolist()]
        lengths = np.array([len(t) for t in tails], np.int64)
        missed |= lengths > longest  # long ties: cheaper done in full
        lengths[missed] = 0
        tails = [t for t, m in zip(tails, missed.tolist(), strict=True) if not m]
        row = np.concatenate(tails) if tails else np.empty(0, np.int64)
        slot = np.repeat(np.arange(len(pairs)), lengths)
        key = keys.take(row)
        present = np.flatnonzero(~np.isnan(key))
        row, slot, key = row.take(present), slot.take(present), key.take(present)
        cell = slot * len(levels) + np.searchsorted(levels, key)
        value = sign * chunk.values.ravel().take(partner.take(slot) * chunk.rows + row)
        least = np.full(cells, np.inf)
        np.minimum.at(least, cell, value)
        tie = np.flatnonzero(value == least.take(cell))
        first = np.full(cells, chunk.rows, np.int64)
        np.minimum.at(first, cell.take(tie), row.take(tie))
        hit = np.flatnonzero(first < chunk.rows)
        missed |= np.bincount(hit // len(levels), minlength=len(pairs)) != len(levels)
        found_cell.append(hit)
        found_row.append(first.take(hit))
    cell = np.concatenate(found_cell)
    keep = np.flatnonzero(~missed[cell // len(levels)])
    pair = pairs.take(cell.take(keep) // len(levels))
    return pair, np.concatenate(found_row).take(keep), missed


def _ends_in_full(
    chunk: Chunk, var: int, pairs: IntArray, partner: IntArray
) -> tuple[IntArray, IntArray]:
    """``(pair, row)`` of every per-value end, from all rows of the chunk: per value of
    ``var``, its rows (increasing) gathered from every partner at once, whose first least
    and first greatest present values are the earliest ends."""
    column = chunk.values[var]
    others = chunk.values[partner]
    gaps = chunk.has_nan[partner].any()
    parts: list[tuple[IntArray, IntArray]] = []
    for level in chunk.levels[var].tolist():
        rows = np.flatnonzero(column == level)
        other = others[:, rows]
        for pick, fill in ((np.argmin, np.inf), (np.argmax, -np.inf)):
            if gaps:
                missing = np.isnan(other)
                at = pick(np.where(missing, fill, other), axis=1)
                hit = np.flatnonzero(~missing[np.arange(len(partner)), at])
            else:
                at = pick(other, axis=1)
                hit = np.arange(len(partner))
            parts.append((pairs[hit], rows[at[hit]]))
    pair = np.concatenate([p for p, _ in parts])
    row = np.concatenate([r for _, r in parts]).astype(np.int64)
    return pair, row


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
    # option 0: the square box; 1 + a * k + b: wide[a] with tall[b]; then each wide box
    # alone, then each tall box alone (a band of a variable that crowds one end of its
    # range, like |n|, leaves few rows outside the box nearly as tall as the hull)
    alone = np.concatenate([sq[None], wide, tall])
    nothing = np.full((len(alone), 2, len(pairs)), [[-np.inf], [np.inf]])
    ax = np.concatenate([alone[:1, 0:2], np.repeat(wide[:, 0:2], k, axis=0), alone[1:, 0:2]])
    by = np.concatenate([alone[:1, 2:4], np.tile(tall[:, 2:4], (k, 1, 1)), alone[1:, 2:4]])
    cx = np.concatenate([nothing[:1], np.tile(tall[:, 0:2], (k, 1, 1)), nothing[1:]])
    cy = np.concatenate([nothing[:1], np.repeat(wide[:, 2:4], k, axis=0), nothing[1:]])
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


def _general(chunk: Chunk, pairs: IntArray, pi: IntArray, pj: IntArray, guide: Guide) -> GroupSet:
    """Candidates of the pairs with continuous variables (see the module docstring)."""
    if not len(pairs):
        return GroupSet.empty()
    plan = _plan(chunk, pairs, pi, pj, guide)
    loose = guide.locator.slot[pairs] >= 0
    blocks = (plan.cost >= _BY_BLOCKS) | loose
    # a cross that fits however badly may still beat the blocks (samples that do not move
    # smoothly leave most blocks open): the blocks' own count decides
    fallback = np.where(loose | (plan.cost >= _CROSS_AT_MOST), np.inf, plan.cost)
    by_blocks, back = _by_blocks(chunk, pairs[blocks], pi, pj, guide, fallback[blocks])
    crossed = np.flatnonzero(~blocks)
    crossed = np.sort(np.concatenate([crossed, np.flatnonzero(blocks)[back]]))
    return GroupSet.concat(
        [_by_cross(chunk, pairs[crossed], pi, pj, guide, _take_plan(plan, crossed)), by_blocks]
    )


def _by_cross(
    chunk: Chunk, pairs: IntArray, pi: IntArray, pj: IntArray, guide: Guide, plan: _Plan
) -> GroupSet:
    """Candidates of ``pairs`` from the rows outside their cross, read from sorted tails."""
    if not len(pairs):
        return GroupSet.empty()
    ox, oy = pi[pairs], pj[pairs]
    nvar = chunk.values.shape[0]
    # parts: A from x, B from y, C (corners) from x or y; each as (owner, lo, hi)
    c_owner = np.where(plan.c_on_x, ox, oy)
    c_lo = np.where(plan.c_on_x, plan.c[0], plan.c[2])
    c_hi = np.where(plan.c_on_x, plan.c[1], plan.c[3])
    parts = ((ox, plan.a[0], plan.a[1]), (oy, plan.b[0], plan.b[1]), (c_owner, c_lo, c_hi))
    need_lo = np.full(nvar, -np.inf)
    need_hi = np.full(nvar, np.inf)
    for owner, lo, hi in parts:
        np.maximum.at(need_lo, owner, lo)
        np.minimum.at(need_hi, owner, hi)
    sorted_values: dict[int, FloatArray] = {}
    sorted_rows: list[IntArray] = []
    offsets = np.zeros(nvar, np.int64)
    total = 0
    for var in np.union1d(ox, oy).tolist():
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
        for var in np.unique(owner).tolist():
            mine = np.flatnonzero(owner == var)
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
    return GroupSet.concat(found)


def _by_blocks(
    chunk: Chunk, pairs: IntArray, pi: IntArray, pj: IntArray, guide: Guide, cross: FloatArray
) -> tuple[GroupSet, IntArray]:
    """Candidates of ``pairs`` from the rows of the blocks of consecutive rows whose
    bounding box the table cannot place strictly inside the hull (if it can, so is every
    row of the block: the hull's interior is convex), refined block size by block size.
    Pairs without a table have every row located exactly instead.

    ``cross`` is each pair's cross cost (the fraction of rows it would enumerate, infinite
    where none may serve): the pairs whose open blocks hold more than ``_CROSS_GAIN`` times
    that fraction of the rows are left out, their positions in ``pairs`` returned."""
    none = np.empty(0, np.int64)
    if not len(pairs) or not chunk.rows:
        return GroupSet.empty(), none
    every_pair = pairs
    loose = pairs[guide.locator.slot[pairs] >= 0]
    every = np.arange(chunk.rows, dtype=np.int64)
    found = _rows(
        chunk,
        loose,
        pi,
        pj,
        np.repeat(np.arange(len(loose), dtype=np.int64), chunk.rows),
        np.tile(every, len(loose)),
        guide,
        located=True,
    )
    pairs = pairs[guide.locator.slot[pairs] < 0]
    count = -(-chunk.rows // BLOCKS[0])
    slot = np.repeat(np.arange(len(pairs), dtype=np.int64), count)
    block = np.tile(np.arange(count, dtype=np.int64), len(pairs))
    for level, size in enumerate(BLOCKS):
        if level:
            factor = BLOCKS[level - 1] // size
            block = (block[:, None] * factor + np.arange(factor)).ravel()
            slot = np.repeat(slot, factor)
            real = np.flatnonzero(block < -(-chunk.rows // size))
            block, slot = block.take(real), slot.take(real)
        slot, block = _open_blocks(chunk, pairs, pi, pj, guide, size, slot, block)
    starts = block * BLOCKS[-1]
    lengths = np.minimum(BLOCKS[-1], chunk.rows - starts)
    tabled = np.flatnonzero(guide.locator.slot[every_pair] < 0)  # rows of ``pairs``
    opened = np.bincount(slot, weights=lengths, minlength=len(pairs))
    over = np.flatnonzero(opened > _CROSS_GAIN * cross[tabled] * chunk.rows)
    back = tabled[over]
    if len(over):
        stay = np.ones(len(pairs), bool)
        stay[over] = False
        keep = np.flatnonzero(stay[slot])
        slot, starts, lengths = slot.take(keep), starts.take(keep), lengths.take(keep)
    # pairs with every block open: their columns as they are, no gathering
    whole = np.bincount(slot, weights=lengths, minlength=len(pairs)) == chunk.rows
    if whole.any():
        found += _whole(chunk, pairs[whole], pi, pj, guide)
        rest = np.flatnonzero(~whole[slot])
        slot, starts, lengths = slot.take(rest), starts.take(rest), lengths.take(rest)
    row = ragged_arange(starts, lengths)
    found += _rows(chunk, pairs, pi, pj, np.repeat(slot, lengths), row, guide, located=False)
    return GroupSet.concat(found), back


def _whole(
    chunk: Chunk, pairs: IntArray, pi: IntArray, pj: IntArray, guide: Guide
) -> list[GroupSet]:
    """:func:`_rows` of every row of each of ``pairs`` (pairs with a table): the same
    lookups (:meth:`Guide.inside_run`) on slices of the columns, but for the rows on the
    line ``y = x`` or ``y = -x`` exactly (see :func:`_off_lines`)."""
    found: list[GroupSet] = []
    for pair in pairs.tolist():
        i, j = int(pi[pair]), int(pj[pair])
        for first in range(0, chunk.rows, _BLOCK):
            x = chunk.values[i, first : first + _BLOCK]
            y = chunk.values[j, first : first + _BLOCK]
            with np.errstate(invalid="ignore"):
                rest, ends = _off_lines(x, y)
                if rest is None:
                    keep = ~guide.inside_run(pair, x, y)
                    if chunk.has_nan[i] or chunk.has_nan[j]:
                        keep &= ~(np.isnan(x) | np.isnan(y))
                    sel = np.flatnonzero(keep)
                else:
                    rx, ry = x.take(rest), y.take(rest)
                    keep = ~guide.inside_run(pair, rx, ry) & ~(np.isnan(rx) | np.isnan(ry))
                    sel = np.sort(np.concatenate([rest[keep], ends]))
            found.append(
                GroupSet(np.full(len(sel), pair, np.int64), x.take(sel), y.take(sel), sel + first)
            )
    return found


def _off_lines(x: FloatArray, y: FloatArray) -> tuple[IntArray | None, IntArray]:
    """``(rest, ends)``: where some rows lie on the line ``y = x`` or ``y = -x`` exactly
    (``mx = max(n1, n2)`` beside ``n1``, ``|n|`` beside ``n``), the rows on neither, and
    per line the rows of its least and greatest ``x`` (the earliest on ties); ``(None,
    [])`` when the first ``_LINE_HEAD`` rows show no such row.

    A row of a line strictly between its ends is a proper convex combination of two rows of
    the chunk, so it is no vertex of any hull holding the chunk; an end at the place of
    other rows of its line is the earliest of them, as the hull's first occurrences are."""
    none = np.empty(0, np.int64)
    head = slice(0, _LINE_HEAD)
    if not bool(np.any((x[head] == y[head]) | (x[head] == -y[head]))):
        return None, none
    off = np.ones(len(x), bool)
    ends: list[int] = []
    for line in (x == y, x == -y):
        on = np.flatnonzero(line)
        if len(on):
            along = x.take(on)
            ends += [int(on[np.argmin(along)]), int(on[np.argmax(along)])]
            off[on] = False
    return np.flatnonzero(off), np.unique(np.array(ends, np.int64))


def _open_blocks(
    chunk: Chunk,
    pairs: IntArray,
    pi: IntArray,
    pj: IntArray,
    guide: Guide,
    size: int,
    slot: IntArray,
    block: IntArray,
) -> tuple[IntArray, IntArray]:
    """The ``(slot, block)`` whose bounding box has a corner the table cannot place."""
    low, high = chunk.block_bounds(size)
    width = low.shape[1]
    pair = pairs.take(slot)
    i = pi.take(pair) * width + block
    j = pj.take(pair) * width + block
    closed = np.arange(len(slot))  # every corner tested so far is inside
    for xs, ys in ((low, low), (high, high), (low, high), (high, low)):
        x = xs.ravel().take(i.take(closed))
        y = ys.ravel().take(j.take(closed))
        closed = closed.take(np.flatnonzero(guide.inside(pair.take(closed), x, y)))
    open_ = np.ones(len(slot), bool)
    open_[closed] = False
    keep = np.flatnonzero(open_)
    return slot.take(keep), block.take(keep)


def _rows(
    chunk: Chunk,
    pairs: IntArray,
    pi: IntArray,
    pj: IntArray,
    slot: IntArray,
    row: IntArray,
    guide: Guide,
    located: bool,
) -> list[GroupSet]:
    """The present rows ``row`` of ``pairs[slot]`` the guide keeps (``located``: pairs
    without a table, whose rows only exact location discards), by cache-sized blocks."""
    values = chunk.values.ravel()
    found: list[GroupSet] = []
    for first in range(0, len(row), _BLOCK):
        r = row[first : first + _BLOCK]
        part = slot[first : first + _BLOCK]
        pair = pairs.take(part)
        x = values.take(pi.take(pair) * chunk.rows + r)
        y = values.take(pj.take(pair) * chunk.rows + r)
        with np.errstate(invalid="ignore"):
            # pairs with a locator have no table: only exact location discards anything
            if located:
                drop = guide.locator.covered(pair, x, y)
            else:
                drop = _inside_by_runs(guide, part, pair, x, y)
            keep = ~drop & ~(np.isnan(x) | np.isnan(y))
        sel = np.flatnonzero(keep)
        found.append(GroupSet(pair.take(sel), x.take(sel), y.take(sel), r.take(sel)))
    return found


def _inside_by_runs(
    guide: Guide, slot: IntArray, pair: IntArray, x: FloatArray, y: FloatArray
) -> BoolArray:
    """``guide.inside(pair, x, y)``; samples that come in a few long runs of one pair
    (``slot`` non-decreasing) are looked up run by run, with the pair's scalars."""
    change = np.flatnonzero(slot[1:] != slot[:-1]) + 1
    if len(change) >= _RUNS or np.any(slot[change] < slot[change - 1]):
        return guide.inside(pair, x, y)
    out = np.empty(len(pair), bool)
    bounds = [0, *change.tolist(), len(pair)]
    for lo, hi in itertools.pairwise(bounds):
        out[lo:hi] = guide.inside_run(int(pair[lo]), x[lo:hi], y[lo:hi])
    return out


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
    twin = rest & ((lookup[pi] == lookup[pj]) | _negated(chunk, wanted)[pi, pj])
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
    used = np.union1d(pi[pairs], pj[pairs])
    slot = np.zeros(chunk.values.shape[0], np.int64)
    slot[used] = np.arange(len(used))
    ends = chunk.extreme_rows(used, extremes)
    sample = _sample_rows(chunk.rows, 2 * extremes)
    rows = np.concatenate(
        [
            ends[slot[pi[pairs]]],
            ends[slot[pj[pairs]]],
            np.broadcast_to(sample, (len(pairs), len(sample))),
        ],
        axis=1,
    )
    pair = np.repeat(pairs, rows.shape[1])
    row = rows.ravel()
    x = chunk.values[pi[pair], row]
    y = chunk.values[pj[pair], row]
    keep = ~(np.isnan(x) | np.isnan(y))
    keep[keep] = ~_discards(guide, pair[keep], x[keep], y[keep])
    sel = np.flatnonzero(keep)
    return GroupSet(pair[sel], x[sel], y[sel], row[sel])


def heads(
    chunk: Chunk, pi: IntArray, pj: IntArray, guide: Guide, only: BoolArray, size: int
) -> GroupSet:
    """A head start for the pairs in ``only``: per block of ``size`` consecutive rows whose
    bounding box the guide cannot place inside the hull, the rows of both variables'
    least and greatest values in the block (at most four), unless the guide discards them.
    """
    _, _, general = _classify(chunk, pi, pj)
    pairs = general[only[general]]
    if not len(pairs) or not chunk.rows:
        return GroupSet.empty()
    count = -(-chunk.rows // size)
    slot = np.repeat(np.arange(len(pairs), dtype=np.int64), count)
    block = np.tile(np.arange(count, dtype=np.int64), len(pairs))
    slot, block = _open_blocks(chunk, pairs, pi, pj, guide, size, slot, block)
    ends = chunk.block_extremes(size)
    width = ends.shape[2]
    pair = pairs.take(slot)
    rows = [
        ends[:, side].ravel().take(var.take(pair) * width + block)
        for var in (pi, pj)
        for side in (0, 1)
    ]
    pair = np.tile(pair, 4)
    row = np.concatenate(rows)
    values = chunk.values.ravel()
    x = values.take(pi.take(pair) * chunk.rows + row)
    y = values.take(pj.take(pair) * chunk.rows + row)
    with np.errstate(invalid="ignore"):
        keep = ~(np.isnan(x) | np.isnan(y))
        keep[keep] = ~_discards(guide, pair[keep], x[keep], y[keep])
    sel = np.flatnonzero(keep)
    order = np.argsort(pair[sel], kind="stable")
    sel = sel[order]
    return GroupSet(pair[sel], x[sel], y[sel], row[sel])


def _discards(guide: Guide, pair: IntArray, x: FloatArray, y: FloatArray) -> BoolArray:
    """:meth:`Guide.discards` by blocks of ``_BLOCK`` samples (bounded temporaries)."""
    out = np.empty(len(pair), bool)
    for first in range(0, len(pair), _BLOCK):
        part = slice(first, first + _BLOCK)
        out[part] = guide.discards(pair[part], x[part], y[part])
    return out


def expanding(chunk: Chunk, pi: IntArray, pj: IntArray, guide: Guide) -> BoolArray:
    """Pairs whose guide would let more than ``EXPANDING`` of the chunk's rows through."""
    _, _, general = _classify(chunk, pi, pj)
    out = np.zeros(len(pi), bool)
    if len(general):
        out[general] = _plan(chunk, general, pi, pj, guide).cost > EXPANDING
    return out


def candidates(chunk: Chunk, pi: IntArray, pj: IntArray, guide: Guide) -> GroupSet:
    """The chunk's samples that may be vertices of ``hull(current hull | chunk)``.

    ``at`` of the result is the sample's row in the chunk; ``guide`` (what lies inside the
    current hulls) decides what is discarded.
    """
    groups, twins, general = _classify(chunk, pi, pj)
    parts = [_grouped(chunk, var, pairs, pi, pj) for var, pairs in groups]
    if len(twins):
        column = chunk.values[pi[twins]]
        low = np.nanargmin(column, axis=1)
        high = np.nanargmax(column, axis=1)
        pair = np.concatenate([twins, twins])
        row = np.concatenate([low, high]).astype(np.int64)
        parts.append(_points(chunk, pi, pj, pair, row))
    parts.append(_general(chunk, general, pi, pj, guide))
    return GroupSet.concat(parts)
