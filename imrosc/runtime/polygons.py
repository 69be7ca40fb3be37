"""Polygon checks: a lookup grid first, the half-planes only near the boundary.

A polygon invariant holds ``A [x, y] <= b`` (one row per edge, a margin for rounding built
into ``b``). Evaluating every edge of every polygon on every sample would be the bulk of a
point's checking cost. So each variable gets a grid of ``GRID`` cells over the polygons'
vertices on it (a hull's bounding box is its variables' range) plus a border cell on each
side, and each polygon, once, a table over the cells of its two variables' grids: a cell is
*inside* when its corners (widened a little) pass every edge with room for float64 rounding,
so that every point of the cell passes too (the polygon is convex). A sample is quantised
once per variable; looking up all polygons is then a few array operations. Only the polygons
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
        # one grid per variable over the range of the polygons' vertices on it (a hull's
        # bounding box is its variables' range): a sample is quantised once per variable
        size = int(max(self.x.max(), self.y.max())) + 1 if count else 0
        low = np.full(size, np.inf)
        high = np.full(size, -np.inf)
        for owner, polygon in enumerate(polygons):
            points = np.asarray(polygon["params"]["vertices"], dtype=np.float64).reshape(-1, 2)
            if len(points):
                for axis, var in enumerate(axes[owner]):
                    low[var] = min(low[var], points[:, axis].min())
                    high[var] = max(high[var], points[:, axis].max())
        with np.errstate(all="ignore"):
            cell = (high - low) / GRID
            usable = np.isfinite(cell) & (cell > 0) & np.isfinite(1.0 / cell)
            self.scale = np.where(usable, 1.0 / np.where(usable, cell, 1.0), 0.0)
        # the origin sits one cell below the range: inner cells are 1..GRID, 0 and GRID + 1
        # the border
        self.origin = np.where(usable, low - cell, 0.0)
        self.size = size
        need = np.ones((count, _SIDE, _SIDE), dtype=bool)
        for owner, polygon in enumerate(polygons):
            x, y = axes[owner]
            if len(polygon["params"]["vertices"]) >= 3 and usable[x] and usable[y]:
                box = np.array([low[x], low[y]]), np.array([cell[x], cell[y]])
                reach = np.array([max(abs(low[x]), abs(high[x])), max(abs(low[y]), abs(high[y]))])
                need[owner] = _grid(per[owner], box[0], box[1], reach)
        self.need = need.ravel()
        self.base = np.arange(count, dtype=np.int64) * (_SIDE * _SIDE)

    def candidates(self, row: Any) -> Any:
        """The polygons whose grid cell for ``row`` is not certainly inside."""
        g = row[: self.size] - self.origin
        g *= self.scale
        # NaN and huge values cast to garbage, clipped into the border: an exact check
        # follows there, which finds no violation for NaN (callers ignore the cast warning)
        cells = g.astype(np.int64)
        np.maximum(cells, 0, out=cells)  # (np.clip costs three times as much)
        np.minimum(cells, GRID + 1, out=cells)
        flat = (cells * _SIDE).take(self.x)
        flat += cells.take(self.y)
        flat += self.base
        return self.need.take(flat).nonzero()[0]

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


def _grid(edges: Sequence[Tuple[float, float, float]], low: Any, size: Any, reach: Any) -> Any:
    """The needs-a-check table of one polygon on the grids of its two variables (cells of
    ``size`` from ``low``; ``reach`` bounds the magnitude of the coordinates)."""
    need = np.ones((_SIDE, _SIDE), dtype=bool)
    if not edges:
        return need
    # corners of cell (i, j) of the inner grid, widened; cell k covers [k - 1, k) in units
    steps = np.arange(GRID + 1, dtype=np.float64)
    xs_lo = low[0] + (steps[:-1] - _WIDEN) * size[0]
    xs_hi = low[0] + (steps[1:] + _WIDEN) * size[0]
    ys_lo = low[1] + (steps[:-1] - _WIDEN) * size[1]
    ys_hi = low[1] + (steps[1:] + _WIDEN) * size[1]
    big_x, big_y = reach + 2 * size
    inside = np.ones((GRID, GRID), dtype=bool)
    for a, b, c in edges:
        room = c - _SAFETY * (abs(a) * big_x + abs(b) * big_y + abs(c))
        # a linear function is largest at a corner: the worst corner per cell
        x_worst = np.where(a >= 0, xs_hi, xs_lo) * a
        y_worst = np.where(b >= 0, ys_hi, ys_lo) * b
        inside &= (x_worst[:, None] + y_worst[None, :]) <= room
    need[1:-1, 1:-1] = ~inside
    return need
