"""Per-chunk work shared by the Daikon states updated with the same :class:`Samples`.

The engine hands one chunk to every family state of a point in turn. Canonical columns,
per-column extremes and exact sums do not depend on the family, so they are computed once
per chunk and kept while the same ``Samples`` object (by identity) comes back. Only the
last chunk is remembered; nothing here is part of a state, so states stay small and
picklable.
"""

from __future__ import annotations

import weakref
from collections.abc import Sequence

import numpy as np

from imrosc.infer.core import FloatArray, Samples
from imrosc.infer.daikon.common import BoolArray, ColumnSummary, float_column, summarize
from imrosc.infer.daikon.exact import SCALE, dyadic, exact_products, exact_sums

MaskKey = tuple[str, ...]


class ChunkView:
    """Cached computations on one chunk."""

    def __init__(self, samples: Samples) -> None:
        self.samples = samples
        self.rows = len(samples)
        self._columns: dict[str, FloatArray] = {}
        self._summaries: dict[str, ColumnSummary] = {}
        self._masks: dict[MaskKey, tuple[BoolArray | None, int]] = {}
        self._sums: dict[tuple[MaskKey, str, str], int] = {}

    def column(self, name: str) -> FloatArray:
        """The canonical float64 column (``-0.0`` as ``0.0``)."""
        found = self._columns.get(name)
        if found is None:
            found = float_column(self.samples, name)
            self._columns[name] = found
        return found

    def columns(self, names: Sequence[str]) -> list[FloatArray]:
        """Several canonical columns."""
        return [self.column(name) for name in names]

    def summary(self, name: str) -> ColumnSummary:
        """Count and extremes of a column."""
        found = self._summaries.get(name)
        if found is None:
            found = summarize(self.column(name))
            self._summaries[name] = found
        return found

    def mask(self, key: MaskKey) -> tuple[BoolArray | None, int]:
        """Rows where every variable of ``key`` is present, and their number."""
        found = self._masks.get(key)
        if found is None:
            if not key:
                found = (None, self.rows)
            else:
                mask = np.all([~np.isnan(self.column(name)) for name in key], axis=0)
                found = (mask, int(np.count_nonzero(mask)))
            self._masks[key] = found
        return found

    def sums(
        self, key: MaskKey, names: Sequence[str], pairs: Sequence[tuple[str, str]]
    ) -> dict[tuple[str, str], int]:
        """Exact scaled sums over the rows of ``key``: ``(v, "")`` is ``sum v``, ``(v, v)``
        is ``sum v*v`` and ``(a, b)`` is ``sum a*b``."""
        mask, count = self.mask(key)
        wanted = [(v, "") for v in names] + [(v, v) for v in names] + list(pairs)
        missing = [item for item in wanted if (key, item[0], item[1]) not in self._sums]
        if missing:
            self._compute(key, mask, count, missing)
        return {item: self._sums[(key, item[0], item[1])] for item in wanted}

    def _compute(
        self, key: MaskKey, mask: BoolArray | None, count: int, items: list[tuple[str, str]]
    ) -> None:
        involved = sorted({name for item in items for name in item if name})
        values = {
            name: self.column(name) if mask is None else self.column(name)[mask]
            for name in involved
        }
        constant: dict[str, float] = {}
        for name, column in values.items():
            if column.size and column[0] == column[-1] and bool(np.all(column == column[0])):
                constant[name] = float(column[0])
        plain = [v for v, w in items if not w and v not in constant]
        for name, total in zip(plain, _sums_of(values, plain), strict=True):
            self._sums[(key, name, "")] = total
        for name, value in constant.items():
            self._sums[(key, name, "")] = _scaled_times(value, count << SCALE)
        products = [(v, w) for v, w in items if w and v not in constant and w not in constant]
        for item, total in zip(products, _dots_of(values, products), strict=True):
            self._sums[(key, item[0], item[1])] = total
        for v, w in items:
            if not w or (key, v, w) in self._sums:
                continue
            if v in constant:
                other = self._single(key, values, w)
                self._sums[(key, v, w)] = _scaled_times(constant[v], other)
            else:
                other = self._single(key, values, v)
                self._sums[(key, v, w)] = _scaled_times(constant[w], other)

    def _single(self, key: MaskKey, values: dict[str, FloatArray], name: str) -> int:
        found = self._sums.get((key, name, ""))
        if found is None:
            found = exact_sums(values[name][None, :])[0]
            self._sums[(key, name, "")] = found
        return found


def _sums_of(values: dict[str, FloatArray], names: list[str]) -> list[int]:
    if not names:
        return []
    return exact_sums(np.stack([values[name] for name in names]), consume=True)


def _dots_of(values: dict[str, FloatArray], pairs: list[tuple[str, str]]) -> list[int]:
    if not pairs:
        return []
    names = sorted({name for pair in pairs for name in pair})
    position = {name: k for k, name in enumerate(names)}
    matrix = np.stack([values[name] for name in names])
    return exact_products(matrix, [(position[v], position[w]) for v, w in pairs])


def _scaled_times(value: float, scaled: int) -> int:
    """``value * S`` for a scaled exact sum ``S`` (exact: the result is a multiple of
    ``2**-SCALE`` because it is a sum of products of doubles)."""
    mantissa, exponent = dyadic(value)
    product = mantissa * scaled
    return product << exponent if exponent >= 0 else product >> -exponent


_LAST: list[tuple[weakref.ref[Samples], ChunkView]] = []


def view(samples: Samples) -> ChunkView:
    """The shared view of ``samples`` (a new one for a new chunk)."""
    if _LAST:
        reference, cached = _LAST[0]
        if reference() is samples:
            return cached
    fresh = ChunkView(samples)
    _LAST[:] = [(weakref.ref(samples), fresh)]
    return fresh
