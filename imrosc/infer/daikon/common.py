"""Shared, exactly mergeable summaries of Daikon's families.

Every summary here is a function of the multiset of values seen and of their order of first
appearance, never of how the rows were cut into chunks: updating with a chunk is "summarize
the chunk, then merge", and merging is associative. Positions are counted per variable over
its non-NaN samples, so justification (``1 - 2**-n``, thesis 3.5) can say how many samples
passed since a minimum, a maximum or a value set last changed.

Columns are canonicalised before use: ``-0.0`` counts as ``0.0`` (``x + 0.0``), so the
result never depends on which zero a reduction happens to return.
"""

from __future__ import annotations

import json
import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import numpy.typing as npt

from imrosc.infer.core import (
    FinalizeContext,
    FloatArray,
    Invariant,
    Samples,
    Variable,
    confidence,
)

IntArray = npt.NDArray[np.int64]
BoolArray = npt.NDArray[np.bool_]

PREFIX = 64
"""Rows at each end of a chunk that every live candidate is tested on first."""

ONE_OF_LIMIT = 3
"""Daikon's limit on the values of a one-of invariant."""


def window(rows: int) -> IntArray:
    """The rows every live candidate is tested on first: the chunk's first and last ones.

    The last rows matter: the input topics of a point are missing (NaN) until their first
    message, which makes the first rows of a run useless for them.
    """
    if rows <= 2 * PREFIX:
        return np.arange(rows, dtype=np.int64)
    return np.concatenate([np.arange(PREFIX), np.arange(rows - PREFIX, rows)]).astype(np.int64)


def unary_variables(variables: Sequence[Variable]) -> tuple[Variable, ...]:
    """Numeric, non-derived variables: the subjects of bounds, one-of and non-zero.

    Variables typed ``time`` are absolute stamps that no other run shares: no unary family
    describes them (the translator leaves header stamps out anyway).
    """
    return tuple(v for v in variables if v.numeric and v.derived is None and v.type != "time")


def relation_variables(variables: Sequence[Variable]) -> tuple[Variable, ...]:
    """Numeric, non-derived variables: the subjects of equality, order, linear, ternary."""
    return tuple(v for v in variables if v.numeric and v.derived is None)


def float_column(samples: Samples, name: str) -> FloatArray:
    """The float64 column of ``name`` with ``-0.0`` turned into ``0.0``."""
    column = np.asarray(samples.column(name), dtype=np.float64)
    return column + 0.0


def number_text(value: float, type_: str = "float") -> str:
    """A value as invariants print it: integers without a point, floats shortest round-trip."""
    if math.isnan(value):
        return "nan"
    if math.isinf(value):
        return "inf" if value > 0 else "-inf"
    if type_ == "bool":
        return "true" if value else "false"
    if value.is_integer() and abs(value) < 2.0**53:
        return str(int(value))
    return repr(value)


def string_text(value: str) -> str:
    """A string as invariants print it (JSON quoting)."""
    return json.dumps(value)


@dataclass(frozen=True)
class ColumnSummary:
    """Count, NaN count, extremes and their first positions among non-NaN samples."""

    count: int
    nan: int
    lo: float
    hi: float
    lo_first: int
    hi_first: int
    distinct: dict[str, Any] = field(default_factory=dict, compare=False, repr=False)
    """The column's distinct values as :class:`Distinct` finds them, computed once for every
    state of the point that tracks them (see :func:`_distinct`)."""


def summarize(column: FloatArray) -> ColumnSummary:
    """The :class:`ColumnSummary` of a canonical column (NaN skipped, inf kept)."""
    if column.size == 0:
        return ColumnSummary(0, 0, math.inf, -math.inf, 0, 0)
    lo = float(column.min())
    if not math.isnan(lo):
        hi = float(column.max())
        return ColumnSummary(
            column.size, 0, lo + 0.0, hi + 0.0, int(column.argmin()), int(column.argmax())
        )
    valid = ~np.isnan(column)
    count = int(np.count_nonzero(valid))
    if count == 0:
        return ColumnSummary(0, column.size, math.inf, -math.inf, 0, 0)
    kept = column[valid]
    lo, hi = float(kept.min()), float(kept.max())
    return ColumnSummary(
        count,
        column.size - count,
        lo + 0.0,
        hi + 0.0,
        int(np.argmax(kept == lo)),
        int(np.argmax(kept == hi)),
    )


@dataclass
class Extremes:
    """Count, minimum and maximum of each variable, with where they first occurred.

    ``lo_first``/``hi_first`` index the first occurrence of the current minimum/maximum in
    the variable's sequence of non-NaN samples, so ``count - lo_first`` samples have seen
    the lower bound unchanged. NaN is skipped (and counted in ``nan``); inf takes part.
    """

    size: int
    count: IntArray = field(init=False)
    nan: IntArray = field(init=False)
    lo: FloatArray = field(init=False)
    hi: FloatArray = field(init=False)
    lo_first: IntArray = field(init=False)
    hi_first: IntArray = field(init=False)

    def __post_init__(self) -> None:
        self.count = np.zeros(self.size, dtype=np.int64)
        self.nan = np.zeros(self.size, dtype=np.int64)
        self.lo = np.full(self.size, np.inf)
        self.hi = np.full(self.size, -np.inf)
        self.lo_first = np.zeros(self.size, dtype=np.int64)
        self.hi_first = np.zeros(self.size, dtype=np.int64)

    def update(self, summaries: Sequence[ColumnSummary]) -> None:
        """Absorb one chunk, given the summary of each variable's column."""
        chunk = Extremes(self.size)
        for i, summary in enumerate(summaries):
            chunk.nan[i] = summary.nan
            if summary.count == 0:
                continue
            chunk.count[i] = summary.count
            chunk.lo[i] = summary.lo
            chunk.hi[i] = summary.hi
            chunk.lo_first[i] = summary.lo_first
            chunk.hi_first[i] = summary.hi_first
        self.merge(chunk)

    def merge(self, other: Extremes) -> None:
        """Absorb the summary of samples that come after ours."""
        lower = (other.count > 0) & ((self.count == 0) | (other.lo < self.lo))
        higher = (other.count > 0) & ((self.count == 0) | (other.hi > self.hi))
        self.lo = np.where(lower, other.lo, self.lo)
        self.hi = np.where(higher, other.hi, self.hi)
        self.lo_first = np.where(lower, self.count + other.lo_first, self.lo_first)
        self.hi_first = np.where(higher, self.count + other.hi_first, self.hi_first)
        self.count = self.count + other.count
        self.nan = self.nan + other.nan

    def constant(self) -> BoolArray:
        """Variables with one value (or none) over all their samples."""
        return np.asarray((self.count == 0) | (self.lo == self.hi), dtype=bool)

    def magnitude(self) -> FloatArray:
        """``max |x|`` over each variable's samples (0 when it has none)."""
        with np.errstate(all="ignore"):
            value = np.maximum(np.abs(self.lo), np.abs(self.hi))
        return np.where(self.count > 0, value, 0.0)

    def spread(self) -> FloatArray:
        """``max x - min x`` (0 when it has no samples)."""
        with np.errstate(all="ignore"):
            value = self.hi - self.lo
        return np.where(self.count > 0, value, 0.0)


def _distinct(
    column: FloatArray, limit: int, summary: ColumnSummary | None
) -> tuple[list[float], list[int], int] | None:
    """The distinct non-NaN values of ``column`` (increasing), the positions of their first
    occurrences among its non-NaN samples and their count; None when there are more than
    ``limit`` values (the first ``PREFIX`` rows are screened first). The column's
    ``summary``, if given, keeps what was found for the point's other states."""
    cache = summary.distinct if summary is not None else {}
    head = cache.get("head")
    if head is None:
        values = np.unique(column[:PREFIX])
        head = cache["head"] = int(np.count_nonzero(~np.isnan(values)))
    if head > limit:
        return None
    key = f"full{limit}"
    if key not in cache:
        cache[key] = _few_values(column[~np.isnan(column)], limit)
    found: tuple[list[float], list[int], int] | None = cache[key]
    return found


def _few_values(kept: FloatArray, limit: int) -> tuple[list[float], list[int], int] | None:
    """``(values, first positions, count)`` of ``kept`` (no NaN), values increasing; None
    when it has more than ``limit`` values. Value by value: each is the first row left and
    takes its equal rows with it (a pass or two per value, where a sort would cost far more
    on the few-valued columns that get this far)."""
    left = np.ones(len(kept), bool)
    found: list[tuple[float, int]] = []
    while len(found) <= limit:
        at = int(left.argmax()) if len(kept) else 0
        if not len(kept) or not left[at]:
            found.sort()
            return [v for v, _ in found], [p for _, p in found], len(kept)
        value = kept[at]
        found.append((float(value), at))
        left &= kept != value
    return None


@dataclass
class Distinct:
    """The distinct values of each variable while there are at most ``limit`` of them.

    ``values[i]`` maps each value to the position of its first occurrence among the
    variable's non-NaN samples and ``count[i]`` counts them; ``overflow[i]`` says more than
    ``limit`` values were seen (then values and count are forgotten: nothing reads them).
    Every chunk is first screened on its first rows, so a continuous variable overflows
    after a handful of samples.
    """

    size: int
    limit: int = ONE_OF_LIMIT
    count: list[int] = field(init=False)
    values: list[dict[Any, int]] = field(init=False)
    overflow: list[bool] = field(init=False)

    def __post_init__(self) -> None:
        self.count = [0] * self.size
        self.values = [{} for _ in range(self.size)]
        self.overflow = [False] * self.size

    def update(
        self, columns: Sequence[FloatArray], summaries: Sequence[ColumnSummary] | None = None
    ) -> None:
        """Absorb one chunk of numeric columns (canonicalised, NaN skipped); the columns'
        summaries, when given, spare the work on columns constant in the chunk."""
        for i, column in enumerate(columns):
            if self.overflow[i]:
                continue
            if summaries is not None:
                summary = summaries[i]
                if summary.count == 0:
                    continue
                if summary.lo == summary.hi:
                    self._add(i, [summary.lo], [0], summary.count)
                    continue
            found = _distinct(column, self.limit, None if summaries is None else summaries[i])
            if found is None:
                self._overflow(i)
                continue
            self._add(i, *found)

    def update_strings(self, columns: Sequence[npt.NDArray[Any]]) -> None:
        """Absorb one chunk of string columns (values that are not ``str`` are skipped)."""
        for i, column in enumerate(columns):
            if self.overflow[i]:
                continue
            items = column.tolist()
            head = {v for v in items[:PREFIX] if isinstance(v, str)}
            if len(head | self.values[i].keys()) > self.limit:
                self._overflow(i)
                continue
            seen: dict[str, int] = {}
            position = 0
            for value in items:
                if not isinstance(value, str):
                    continue
                if value not in seen:
                    seen[value] = position
                position += 1
            self._add(i, list(seen), list(seen.values()), position)

    def _overflow(self, i: int) -> None:
        self.overflow[i] = True
        self.values[i] = {}
        self.count[i] = 0

    def _add(self, i: int, found: list[Any], first: list[int], count: int) -> None:
        merged = self.values[i]
        for value, position in zip(found, first, strict=True):
            if value not in merged:
                merged[value] = self.count[i] + position
        self.count[i] += count
        if len(merged) > self.limit:
            self._overflow(i)

    def merge(self, other: Distinct) -> None:
        """Absorb the summary of samples that come after ours."""
        for i in range(self.size):
            if self.overflow[i] or other.overflow[i]:
                self._overflow(i)
                continue
            values = other.values[i]
            self._add(i, list(values), list(values.values()), other.count[i])

    def stable(self, i: int) -> int:
        """Samples since the value set last changed (0 when there is no set)."""
        if self.overflow[i] or not self.values[i]:
            return 0
        return self.count[i] - max(self.values[i].values())

    def reported(self, i: int, context: FinalizeContext) -> bool:
        """Whether the one-of invariant of variable ``i`` is justified."""
        return context.justified(self.stable(i))

    def confidence(self, i: int) -> float:
        """The one-of invariant's confidence."""
        return confidence(self.stable(i))

    def invariant(
        self,
        i: int,
        variable: Variable,
        family: str,
        shown: Sequence[str],
        context: FinalizeContext,
    ) -> Invariant:
        """The one-of invariant of variable ``i``: ``x == v`` or ``x one of {...}``; ``shown``
        are its sorted values as text."""
        if len(shown) == 1:
            text = f"{variable.name} == {shown[0]}"
        else:
            text = f"{variable.name} one of {{{', '.join(shown)}}}"
        return Invariant(
            family=family,
            kind=family,
            point=context.point,
            variables=(variable.name,),
            params={"values": sorted(self.values[i])},
            text=text,
            samples=self.count[i],
            confidence=self.confidence(i),
            condition=context.condition,
            runs=context.runs,
        )


def pair_index(i: int, j: int, size: int) -> int:
    """Position of the pair ``i < j`` in ``np.triu_indices(size, 1)`` order."""
    return i * size - i * (i + 1) // 2 + (j - i - 1)


def equality_classes(
    size: int, equal: set[tuple[int, int]], eligible: Sequence[bool]
) -> list[list[int]]:
    """Greedy cliques of pairwise-equal variables, in variable order.

    A variable joins the first class all of whose members it equals (with NaN skipped,
    equality need not be transitive, so every pair is required); the first member leads.
    """
    classes: list[list[int]] = []
    for v in range(size):
        if not eligible[v]:
            continue
        for members in classes:
            if all((u, v) in equal for u in members):
                members.append(v)
                break
        else:
            classes.append([v])
    return classes
