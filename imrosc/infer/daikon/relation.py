"""What the linear and ternary families share: candidates, screening, exact sums.

A state holds the live candidates (pairs or triples of a point's numeric, non-derived
variables, in variable order; all of them before the first sample), and for each the exact
moment matrix of its variables over the samples where all of them are present (NaN rows
skipped). Per chunk:

1. a candidate meeting ``inf`` on a row where its other variables are present dies;
2. the float screen (``screen``) runs on the chunk's first and last rows, then on rows
   spread over the chunk for the survivors that met a variable constant on those rows;
3. the survivors add the chunk's exact sums (``exact``) to their moments.

A candidate only ever dies, so a live one has the sums of every sample. The state also
keeps per-variable extremes (constants, tolerance scale), distinct-value counts (a
relation needs more than 3 values per variable) and equality flags (relations are
reported among the leaders of equality classes only).
"""

from __future__ import annotations

import math
from collections.abc import Iterator, Sequence
from itertools import combinations
from typing import Any

import numpy as np

from imrosc.infer.core import FinalizeContext, FloatArray, Samples, Variable
from imrosc.infer.daikon import screen
from imrosc.infer.daikon.chunk import ChunkView, view
from imrosc.infer.daikon.common import (
    BoolArray,
    ColumnSummary,
    Distinct,
    Extremes,
    IntArray,
    equality_classes,
    number_text,
    relation_variables,
)
from imrosc.infer.daikon.exact import Moments
from imrosc.infer.daikon.pairs import PairFlags

Candidate = tuple[int, ...]
_BLOCK = 1 << 17


def _copy(moments: Moments) -> Moments:
    return Moments(moments.size, list(moments.values), moments.count)


class RelationState:
    """Base of the linear (``width = 2``) and ternary (``width = 3``) states.

    ``live`` is ``None`` while the state has seen no sample (every candidate is alive),
    then the ``(m, width)`` array of live candidates in lexicographic order: after the
    first chunk it is small, so a point with hundreds of variables does not carry millions
    of dead triples around.
    """

    family = ""
    width = 2

    def __init__(self, variables: Sequence[Variable]) -> None:
        self.variables = relation_variables(variables)
        self.names = tuple(v.name for v in self.variables)
        size = len(self.variables)
        self.live: IntArray | None = None
        self.moments: dict[Candidate, Moments] = {}
        self.extremes = Extremes(size)
        self.distinct = Distinct(size)
        self.flags = PairFlags(size, "equality")

    def _all_candidates(self) -> Iterator[IntArray]:
        """Every candidate in lexicographic order, in blocks of about ``_BLOCK``."""
        size = len(self.names)
        if self.width == 2:
            first, second = np.triu_indices(size, 1)
            every = np.stack([first, second], axis=1).astype(np.int64)
            for start in range(0, every.shape[0], _BLOCK):
                yield every[start : start + _BLOCK]
            return
        for head in range(size - 2):
            second, third = np.triu_indices(size - head - 1, 1)
            rest = np.stack([second, third], axis=1).astype(np.int64) + head + 1
            block = np.concatenate(
                [np.full((rest.shape[0], 1), head, dtype=np.int64), rest], axis=1
            )
            for start in range(0, block.shape[0], _BLOCK):
                yield block[start : start + _BLOCK]

    def live_candidates(self) -> IntArray:
        """The live candidates (every one while no sample was seen)."""
        if self.live is not None:
            return self.live
        blocks = list(self._all_candidates())
        if not blocks:
            return np.zeros((0, self.width), dtype=np.int64)
        return np.concatenate(blocks)

    # -- updating ---------------------------------------------------------------------------

    def update(self, samples: Samples) -> None:
        """Consume one chunk."""
        if not self.names or len(samples) == 0:
            return
        chunk = view(samples)
        columns = chunk.columns(self.names)
        summaries = [chunk.summary(name) for name in self.names]
        self.extremes.update(summaries)
        self.distinct.update(columns, summaries)
        self.flags.update(columns, summaries)
        blocks = self._all_candidates() if self.live is None else [self.live]
        infinite = np.array([math.isinf(m.lo) or math.isinf(m.hi) for m in summaries], dtype=bool)
        survivors = [self._survivors(columns, infinite, block) for block in blocks]
        kept = [block for block in survivors if block.size]
        self.live = np.concatenate(kept) if kept else np.zeros((0, self.width), dtype=np.int64)
        if self.live.size:
            self._accumulate(chunk, summaries, self.live)
        alive = {tuple(int(v) for v in row) for row in self.live}
        self.moments = {key: value for key, value in self.moments.items() if key in alive}

    def end_run(self) -> None:
        """Nothing spans runs."""

    def _survivors(
        self, columns: list[FloatArray], infinite: BoolArray, block: IntArray
    ) -> IntArray:
        if block.size == 0:
            return block
        if infinite.any():
            block = self._drop_infinite(columns, infinite, block)
        rows = columns[0].size
        block, blind = self._screen(columns, block, screen.window(rows))
        if rows > 2 * screen.PREFIX and blind.any():
            rest, _ = self._screen(columns, block[blind], screen.spread_rows(rows))
            block = np.concatenate([block[~blind], rest])
            order = np.lexsort(block.T[::-1])
            block = block[order]
        return block

    @staticmethod
    def _drop_infinite(columns: list[FloatArray], infinite: BoolArray, block: IntArray) -> IntArray:
        keep = np.ones(block.shape[0], dtype=bool)
        for k in np.flatnonzero(infinite[block].any(axis=1)):
            members = [columns[int(v)] for v in block[k]]
            present = np.all([~np.isnan(m) for m in members], axis=0)
            if np.any(present & np.any([np.isinf(m) for m in members], axis=0)):
                keep[k] = False
        return block[keep]

    def _screen(
        self, columns: list[FloatArray], block: IntArray, rows: IntArray | None
    ) -> tuple[IntArray, BoolArray]:
        """Drop the candidates the rows falsify; return survivors and which of them met a
        constant variable there (no evidence: worth a look at the whole chunk)."""
        if block.size == 0:
            return block, np.zeros(0, dtype=bool)
        used = np.unique(block)
        local = np.full(len(columns), -1, dtype=np.int64)
        local[used] = np.arange(used.size)
        matrix = screen.gather(columns, used, rows)
        stats = screen.candidate_stats(matrix, local[block])
        dead = screen.pair_dead(stats) if self.width == 2 else screen.triple_dead(stats)
        blind = np.asarray(stats.constant.any(axis=1), dtype=bool)
        keep = ~dead
        return block[keep], blind[keep]

    def _accumulate(self, chunk: ChunkView, summaries: list[ColumnSummary], live: IntArray) -> None:
        groups: dict[tuple[str, ...], list[Candidate]] = {}
        for row in live:
            candidate = tuple(int(v) for v in row)
            key = tuple(self.names[v] for v in candidate if summaries[v].nan)
            groups.setdefault(key, []).append(candidate)
        for key, members in groups.items():
            _, count = chunk.mask(key)
            if count == 0:
                continue
            names = sorted({self.names[v] for c in members for v in c})
            pairs = sorted(
                {(self.names[a], self.names[b]) for c in members for a, b in combinations(c, 2)}
            )
            sums = chunk.sums(key, names, pairs)
            for c in members:
                own = [self.names[v] for v in c]
                width = len(own)
                entries: dict[tuple[int, int], int] = {}
                for i, name in enumerate(own):
                    entries[(i, width)] = sums[(name, "")]
                    entries[(i, i)] = sums[(name, name)]
                    for j in range(i + 1, width):
                        entries[(i, j)] = sums[(name, own[j])]
                self.moments.setdefault(c, Moments(width)).add(entries, count)

    # -- merging ----------------------------------------------------------------------------

    def merge(self, other: Any) -> None:
        """Absorb a state of the same family whose samples come after ours."""
        if not isinstance(other, type(self)) or other.names != self.names:
            raise TypeError(f"cannot merge {type(other).__name__} into {self.family}")
        self.extremes.merge(other.extremes)
        self.distinct.merge(other.distinct)
        self.flags.merge(other.flags)
        if other.live is None:
            return
        if self.live is None:
            self.live = other.live.copy()
            self.moments = {key: _copy(value) for key, value in other.moments.items()}
            return
        theirs = {tuple(int(v) for v in row) for row in other.live}
        keep = np.array([tuple(int(v) for v in row) in theirs for row in self.live], dtype=bool)
        self.live = self.live[keep] if self.live.size else self.live
        moments: dict[Candidate, Moments] = {}
        for row in self.live:
            key = tuple(int(v) for v in row)
            total = Moments(self.width)
            for part in (self.moments.get(key), other.moments.get(key)):
                if part is not None:
                    total.merge(part)
            if total.count:
                moments[key] = total
        self.moments = moments

    # -- finalizing -------------------------------------------------------------------------

    def usable(self, context: FinalizeContext) -> BoolArray:
        """Variables a relation may use: non-constant, >3 values, equality-class leaders."""
        usable: BoolArray = self.leaders(context) & np.array(self.distinct.overflow, dtype=bool)
        return usable

    def leaders(self, context: FinalizeContext) -> BoolArray:
        """Non-constant variables that lead their equality class (whatever their values)."""
        constant = self.extremes.constant()
        eligible = [not bool(constant[v]) for v in range(len(self.names))]
        classes = equality_classes(len(self.names), self.flags.equal_pairs(context), eligible)
        followers = {v for members in classes for v in members[1:]}
        return np.array(
            [eligible[v] and v not in followers for v in range(len(self.names))], dtype=bool
        )

    def scales(self, members: Sequence[int]) -> tuple[list[float], list[float]]:
        """Spread and magnitude of each member (the tolerance scale)."""
        spread = self.extremes.spread()
        magnitude = self.extremes.magnitude()
        return [float(spread[v]) for v in members], [float(magnitude[v]) for v in members]


def relation_text(dependent: str, terms: Sequence[tuple[float, str]], intercept: float) -> str:
    """``z = x - 2*m + 1``: unit coefficients omitted, signs folded, zero terms dropped."""
    parts: list[tuple[bool, str]] = []
    for coefficient, name in terms:
        if coefficient == 0:
            continue
        size = abs(coefficient)
        body = name if size == 1 else f"{number_text(size)}*{name}"
        parts.append((coefficient < 0, body))
    if intercept != 0 or not parts:
        parts.append((intercept < 0, number_text(abs(intercept))))
    text = ("-" if parts[0][0] else "") + parts[0][1]
    for negative, body in parts[1:]:
        text += f" {'-' if negative else '+'} {body}"
    return f"{dependent} = {text}"
