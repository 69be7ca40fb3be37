"""Exact comparison flags of every pair of variables (equality and order families).

For each pair ``i < j`` of a point's numeric variables the tracker records whether some
sample had ``x_i < x_j``, ``x_i == x_j`` or ``x_i > x_j`` (rows where either is NaN are
skipped) and how many samples had both. The flags only ever switch on, so a pair is
falsified monotonically: in ``equality`` mode once it saw ``<`` or ``>``, in ``order`` mode
once it saw both. Dead pairs are never looked at again.

Per chunk, a live pair is decided from the variables' chunk ranges when they are disjoint
(every row then compares the same way), else tested on the chunk's first and last rows
and, if it survives them, on the whole chunk. All comparisons are exact, so the flags of a live pair
are the OR over every sample whatever the chunking.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any, Literal

import numpy as np

from imrosc.infer.core import FinalizeContext, FloatArray, Samples, Variable
from imrosc.infer.daikon.chunk import view
from imrosc.infer.daikon.common import (
    BoolArray,
    ColumnSummary,
    Extremes,
    IntArray,
    equality_classes,
    relation_variables,
    window,
)

Mode = Literal["equality", "order"]
_BLOCK = 64


@dataclass
class PairFlags:
    """Comparison flags and joint counts of all pairs of ``size`` variables."""

    size: int
    mode: Mode
    lt: BoolArray = field(init=False)
    eq: BoolArray = field(init=False)
    gt: BoolArray = field(init=False)
    count: IntArray = field(init=False)
    first: IntArray = field(init=False)
    second: IntArray = field(init=False)

    def __post_init__(self) -> None:
        first, second = np.triu_indices(self.size, 1)
        self.first = first.astype(np.int64)
        self.second = second.astype(np.int64)
        pairs = self.first.size
        self.lt = np.zeros(pairs, dtype=bool)
        self.eq = np.zeros(pairs, dtype=bool)
        self.gt = np.zeros(pairs, dtype=bool)
        self.count = np.zeros(pairs, dtype=np.int64)

    def alive(self) -> BoolArray:
        """Pairs not yet falsified."""
        if self.mode == "equality":
            return ~(self.lt | self.gt)
        return ~(self.lt & self.gt)

    def update(self, columns: Sequence[FloatArray], summaries: Sequence[ColumnSummary]) -> None:
        """Absorb one chunk (``columns[i]`` is variable ``i``, with its summary)."""
        live = np.flatnonzero(self.alive())
        if live.size == 0 or not columns or columns[0].size == 0:
            return
        rows = columns[0].size
        used = np.union1d(self.first[live], self.second[live])
        local = np.full(self.size, -1, dtype=np.int64)
        local[used] = np.arange(used.size)
        lo = np.array([summaries[v].lo for v in used])
        hi = np.array([summaries[v].hi for v in used])
        has_nan = np.array([summaries[v].nan > 0 for v in used], dtype=bool)
        a = local[self.first[live]]
        b = local[self.second[live]]
        joint = np.full(live.size, rows, dtype=np.int64)
        masked = np.flatnonzero(has_nan[a] | has_nan[b])
        if masked.size:
            valid = {int(v): ~np.isnan(columns[int(v)]) for v in used[has_nan]}
            everywhere = np.ones(rows, dtype=bool)
            for k in masked:
                left = valid.get(int(used[a[k]]), everywhere)
                right = valid.get(int(used[b[k]]), everywhere)
                joint[k] = int(np.count_nonzero(left & right))
        self.count[live] += joint
        some = joint > 0
        below = some & (hi[a] < lo[b])
        above = some & (lo[a] > hi[b])
        self.lt[live[below]] = True
        self.gt[live[above]] = True
        open_ = np.flatnonzero(some & ~below & ~above)
        if open_.size == 0:
            return
        involved = np.union1d(a[open_], b[open_])
        rows_first = window(rows)
        head = np.empty((used.size, rows_first.size))
        for k in involved:
            head[k] = columns[int(used[k])][rows_first]
        self._compare(live[open_], head[a[open_]], head[b[open_]])
        still = self.alive()[live[open_]]
        rest = open_[still]
        if rest.size == 0 or rows <= rows_first.size:
            return
        for start in range(0, rest.size, _BLOCK):
            block = rest[start : start + _BLOCK]
            left = np.stack([columns[int(used[k])] for k in a[block]])
            right = np.stack([columns[int(used[k])] for k in b[block]])
            self._compare(live[block], left, right)

    def _compare(self, pairs: IntArray, x: FloatArray, y: FloatArray) -> None:
        self.lt[pairs] |= (x < y).any(axis=1)
        self.eq[pairs] |= (x == y).any(axis=1)
        self.gt[pairs] |= (x > y).any(axis=1)

    def merge(self, other: PairFlags) -> None:
        """Absorb the flags of samples that come after ours."""
        self.lt |= other.lt
        self.eq |= other.eq
        self.gt |= other.gt
        self.count += other.count

    def equal_pairs(self, context: FinalizeContext) -> set[tuple[int, int]]:
        """Pairs equal on every joint sample, with justified support."""
        only = self.alive() & ~self.lt & ~self.gt & self.eq
        found = set()
        for p in np.flatnonzero(only):
            if context.justified(int(self.count[p])):
                found.add((int(self.first[p]), int(self.second[p])))
        return found


class PairRelationState:
    """What the equality and order families share: exact pair flags and column extremes
    over the relation variables, updated and merged alike. Subclasses set ``family`` and
    ``mode`` and write ``finalize``."""

    family = ""
    mode: Literal["equality", "order"] = "equality"

    def __init__(self, variables: Sequence[Variable]) -> None:
        self.variables = relation_variables(variables)
        self.extremes = Extremes(len(self.variables))
        self.flags = PairFlags(len(self.variables), self.mode)

    def update(self, samples: Samples) -> None:
        """Consume one chunk."""
        if not self.variables or len(samples) == 0:
            return
        chunk = view(samples)
        names = [v.name for v in self.variables]
        summaries = [chunk.summary(name) for name in names]
        self.extremes.update(summaries)
        self.flags.update(chunk.columns(names), summaries)

    def end_run(self) -> None:
        """Nothing spans runs."""

    def merge(self, other: Any) -> None:
        """Absorb a state whose samples come after ours."""
        if type(other) is not type(self):
            raise TypeError(f"cannot merge {type(other).__name__} into {self.family}")
        self.extremes.merge(other.extremes)
        self.flags.merge(other.flags)

    def classes(self, context: FinalizeContext) -> list[list[int]]:
        """Equality classes of the non-constant variables (leaders first)."""
        size = len(self.variables)
        constant = self.extremes.constant()
        eligible = [not bool(constant[v]) for v in range(size)]
        return equality_classes(size, self.flags.equal_pairs(context), eligible)
