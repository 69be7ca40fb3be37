"""Polygon checks: a lookup grid first, the half-planes only near the boundary.

A polygon invariant holds ``A [x, y] <= b`` (one row per edge, a margin for rounding built
into ``b``). Evaluating every edge of every polygon on every sample would be the bulk of a
point's checking cost, so each polygon gets, once, a grid of ``GRID x GRID`` cells over its
bounding box plus a ring of border cells, each cell marked *inside* when its corners
(widened a little) pass every edge with room for float64 rounding, so that every point of
the cell passes too (the polygon is convex). A sample costs a handful of array operations
for all polygons together: its cell in each grid and one table lookup. Only the polygons
whose cell is not inside (the boundary, the border, missing values) have their edges
evaluated, as one padded array operation.

>>> square = {"params": {"A": [[1.0, 0.0], [0.0, 1.0], [-1.0, 0.0], [0.0, -1.0]],
...                      "b": [1.0, 1.0, 1.0, 1.0],
...                      "vertices": [[-1, -1], [1, -1], [1, 1], [-1, 1]]}}
>>> rows = [(0, 1, a, b, c, 0) for (a, b), c in zip(square["params"]["A"], square["params"]["b"])]
>>> checks = PolygonChecks([square], rows)
>>> [checks.broken(np.array(p)).tolist() for p in ([0.5, 2.0], [0.999, -0.999], [0.1, 0.2])]
[[0], [], []]
"""

from __future__ import annotations

from typing import Any, List, Mapping, Sequence, Tuple

import numpy as np

GRID = 64
"""Cells per axis over a polygon's bounding box (plus one border cell on each side)."""
_SIDE = GRID + 2
_SAFETY = 16 * 2.0**-53
"""Relative rounding allowance (of the edge's magnitude) kept between an inside cell and
an edge."""
_WIDEN = 1e-6
"""Cells are classified widened by this fraction of their size: a sample that float64
rounding puts in the wrong cell is still inside the widened one."""


class PolygonChecks:
    """The polygons of one point: their grids and their padded half-planes."""

    def __init__(
        self,
        polygons: Sequence[Mapping[str, Any]],
        edges: Sequence[Tuple[int, int, float, float, float, int]],
    ) -> None:
        count = len(polygons)
        self.count = count
        per: List[List[Tuple[float, float, float]]] = [[] for _ in range(count)]
        axes: List[Tuple[int, int]] = [(0, 0)] * count
        for x, y, a, b, c, owner in edges:
            per[owner].append((a, b, c))
            axes[owner] = (x, y)
        width = max([len(e) for e in per] + [1])
        table = np.zeros((count, width, 3))
        for owner, rows in enumerate(per):
            padded = rows + [rows[0]] * (width - len(rows)) if rows else [(0.0, 0.0, 0.0)] * width
            table[owner] = padded
        self.abc = np.ascontiguousarray(np.moveaxis(table, 2, 0))
        """``(3, polygons, edges)``: each edge's ``a``, ``b`` and ``c``."""
        self.x = np.asarray([ax[0] for ax in axes], dtype=np.int64)
        self.y = np.asarray([ax[1] for ax in axes], dtype=np.int64)
        self.at = np.stack([self.x, self.y], axis=1).ravel()
        origin = np.zeros((count, 2))
        scale = np.zeros((count, 2))
        need = np.ones((count, _SIDE, _SIDE), dtype=bool)
        for owner, polygon in enumerate(polygons):
            grid = _grid(polygon["params"]["vertices"], per[owner])
            if grid is not None:
                origin[owner], scale[owner], need[owner] = grid
        # x cells of polygon p are numbered from p * _SIDE (its table's first row), y cells
        # from 0; the origins sit one cell below the box, so inner cells start at 1
        first = np.stack([np.arange(count) * _SIDE, np.zeros(count)], axis=1)
        cell = 1.0 / np.where(scale > 0, scale, 1.0)
        self.origin = (origin - (first + 1.0) * cell).ravel()
        self.scale = scale.ravel()
        self.low = first.astype(np.int64).ravel()
        self.high = self.low + GRID + 1
        self.weights = np.tile(np.array([_SIDE, 1], np.int64), count)
        self.need = need.ravel()

    def candidates(self, row: Any) -> Any:
        """The polygons whose grid cell for ``row`` is not certainly inside."""
        g = row.take(self.at)
        g -= self.origin
        g *= self.scale
        # NaN and huge values cast to garbage, clipped into the border: an exact check
        # follows there, which finds no violation for NaN (callers ignore the cast warning)
        cells = g.astype(np.int64)
        np.maximum(cells, self.low, out=cells)  # (np.clip costs three times as much)
        np.minimum(cells, self.high, out=cells)
        cells *= self.weights
        return self.need.take(cells[0::2] + cells[1::2]).nonzero()[0]

    def broken(self, row: Any, candidates: Any = None) -> Any:
        """Which polygons (of ``candidates``, default all) ``row`` is outside of."""
        if candidates is None:
            candidates = self.candidates(row)
        if not len(candidates):
            return candidates
        px = row.take(self.x.take(candidates))[:, None]
        py = row.take(self.y.take(candidates))[:, None]
        a, b, c = self.abc.take(candidates, axis=1)
        hit = (a * px + b * py > c).any(axis=1)
        if not np.count_nonzero(hit):
            return candidates[:0]
        # inference builds hulls from finite samples only: a NaN or infinite coordinate
        # breaks no polygon (a NaN compares false already; an inf would reach past an edge)
        finite = np.isfinite(px[:, 0]) & np.isfinite(py[:, 0])
        return candidates[hit & finite]


def _grid(
    vertices: Sequence[Sequence[float]], edges: Sequence[Tuple[float, float, float]]
) -> Tuple[Any, Any, Any] | None:
    """``(origin, cells per unit, needs-a-check table)`` of one polygon, or None."""
    if len(vertices) < 3 or not edges:
        return None
    points = np.asarray(vertices, dtype=np.float64)
    low = points.min(axis=0)
    size = (points.max(axis=0) - low) / GRID
    if not (np.all(size > 0) and np.all(np.isfinite(size))):
        return None
    with np.errstate(all="ignore"):
        scale = 1.0 / size
    if not np.all(np.isfinite(scale)):
        return None
    # corners of cell (i, j) of the inner grid, widened; cell k covers [k - 1, k) in units
    steps = np.arange(GRID + 1, dtype=np.float64)
    xs_lo = low[0] + (steps[:-1] - _WIDEN) * size[0]
    xs_hi = low[0] + (steps[1:] + _WIDEN) * size[0]
    ys_lo = low[1] + (steps[:-1] - _WIDEN) * size[1]
    ys_hi = low[1] + (steps[1:] + _WIDEN) * size[1]
    big_x, big_y = np.abs(points).max(axis=0) + 2 * size
    inside = np.ones((GRID, GRID), dtype=bool)
    for a, b, c in edges:
        room = c - _SAFETY * (abs(a) * big_x + abs(b) * big_y + abs(c))
        # a linear function is largest at a corner: the worst corner per cell
        x_worst = np.where(a >= 0, xs_hi, xs_lo) * a
        y_worst = np.where(b >= 0, ys_hi, ys_lo) * b
        inside &= (x_worst[:, None] + y_worst[None, :]) <= room
    need = np.ones((_SIDE, _SIDE), dtype=bool)
    need[1:-1, 1:-1] = ~inside
    return low, scale, need
