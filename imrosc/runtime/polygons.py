"""Polygon checks: a lookup table first, the edges near the sample only.

A polygon invariant holds ``A [x, y] <= b`` (one row per edge, a margin for rounding built
into ``b``). Evaluating every edge of every polygon on every sample would be the bulk of a
point's checking cost, so each polygon gets, once, a table over a grid on its two
variables, and a sample costs a few array operations over all polygons plus the exact
test of the few edges that pass near it.

The grid. Each variable the polygons use gets ``grid`` cells over the range of the
polygons' vertices on it (a hull's bounding box is its variables' range), its ends a thin
slice into the first and the last cell (samples pile up at a range's ends). A sample
inside every range (the common case; callers say so, or :meth:`PolygonChecks.in_range`
finds out) is quantised once per variable. Outside a range, or not finite, the sample
takes the slow path below.

The tables. For each polygon and each cell pair, one byte: the cyclic run of edges a sample
in the cell may break (0 when none: the cell is inside; see :data:`DECODE`). An edge can
only be broken in a cell when the float64 value ``a*x + b*y`` at the cell's worst corner
exceeds ``c``: rounding is monotone, so ``fl(fl(a*x) + fl(b*y))`` is largest at that
corner for every point of the cell, however each sample rounds. The cell is the box its
samples can lie in: widened by the rounding of the quantisation, cut to the variables'
ranges (the fast path only runs inside them, so an edge along a range's end is never
broken there). Cells whose edges are not one cyclic run get the smallest run holding them
(checking an edge more is harmless).

The bits. For each polygon, one bit per cell of a grid twice as fine (each cell split in
four), by the same worst-corner test: whether a sample there may break an edge at all.
Eight polygons share each byte, so the bits take half the memory of the codes: a lookup
touches one cache line per polygon and a large point's tables do not fit a core's cache,
so the smaller table is the quicker read; and a fine cell near an edge sends half as many
samples to the exact test as a coarse one.

A sample: the fine cells of all polygons at once (quantise, gather, look up the bits), then
for the few polygons whose fine cell is near an edge, the edges of its coarse cell's code,
in float64 as the invariant reads. Many candidates (a sample far off) or the slow path:
every edge of the candidate polygons as one padded array operation. The answer is the same
either way: exactly the polygons with an edge ``a*x + b*y > c``, finite samples only.

Where numba is importable, a sample is first asked whether it breaks nothing by one compiled
loop over every check of its point (:mod:`.compiled`, from :meth:`PolygonChecks.compiled`:
the same cells, bits and edges); the steps above find the violations of the others.

>>> square = {"params": {"A": [[1.0, 0.0], [0.0, 1.0], [-1.0, 0.0], [0.0, -1.0]],
...                      "b": [1.0, 1.0, 1.0, 1.0],
...                      "vertices": [[-1, -1], [1, -1], [1, 1], [-1, 1]]}}
>>> rows = [(0, 1, a, b, c, 0) for (a, b), c in zip(square["params"]["A"], square["params"]["b"])]
>>> checks = PolygonChecks([square], rows)
>>> [checks.broken(np.array(p)) for p in ([0.5, 2.0], [0.999, -0.999], [0.1, 0.2])]
[[0], [], []]
"""

from __future__ import annotations

from typing import Any, Dict, List, Mapping, Optional, Sequence, Tuple

import numpy as np

from .compiled import COARSE, Guard, Polygon
from .fast import count_nonzero

Edge = Tuple[float, float, float]

TABLE_BUDGET = 8 * 2**20
"""Bytes the tables of one point may take (codes and bits, 1.5 bytes per polygon and
cell): the grid is 64 cells per axis while it fits, coarser for points with thousands of
polygons."""
_WIDEN = 1e-6
"""Cells are widened by this fraction of their size (and a few ulps of the values'
magnitude): a sample that float64 rounding puts in the wrong cell is still inside the
widened one."""
_MANY = 24
"""Beyond this many candidate polygons, one array operation over all their edges is
cheaper than testing their cells' edges one by one."""
_END = 0.125
"""The first and the last cell reach this fraction of a cell into the range: samples pile
up at a range's ends (zeros, saturations, the extremes of a discrete value) and the hull's
edges run close to them there; thin end cells keep those samples out of boundary cells."""
_RUNS = 6
"""Longest run of edges a table code names; a longer run (a cell well outside the
polygon) reads as every edge."""
_FIRSTS = 42
"""Edges a run may start at (polygons with more edges test all of them in the cells past
this)."""
_SPLIT = 1
"""The bits' cells split each coarse cell in ``2**_SPLIT`` along each axis (2 was measured:
half the candidates again, but four times the bits, and slower)."""
_FEW = 4
"""Up to this many candidates read their coordinates one by one (``row.item``); more
convert the whole sample to a list once."""
_FINE_RUNS = 1 << 16
"""Fine cells whose run of edges is remembered (a dictionary cleared when full: a miss
only costs a look at the codes)."""
_BLOCK = 1 << 18
"""Edge-cell pairs whose float64 worst corners a table build holds at once (2 MiB per
array): all edges at once, a hull of 1,400 edges took 86 MB to build 12 MB of tables."""
_ALL = 255
_NONE = np.empty(0, dtype=np.int64)
"""No candidates (shared, never written)."""
"""Table code: test every edge of the polygon."""
DECODE: List[Tuple[int, int]] = [(0, 0)] * 256
"""Table code -> ``(first, stop)`` of the run of edges to test (code 0: none; 255: all,
read by the caller)."""
for _first in range(_FIRSTS):
    for _count in range(1, _RUNS + 1):
        DECODE[1 + _first * _RUNS + _count - 1] = (_first, _first + _count)


def grid_size(count: int) -> int:
    """Cells per axis for ``count`` polygons (a divisor of 128: ``256 // grid`` polygons'
    cells share a row of 256 in the codes, ``8 * 128 // grid`` in the bits)."""
    grid = 64
    while grid > 8 and count * grid * grid * 3 // 2 > TABLE_BUDGET:
        grid //= 2
    return grid


class PolygonChecks:
    """The polygons of one point: their grids, their tables and their edges.

    ``edges`` are ``(x, y, a, b, c, owner)``: the positions of the polygon's variables in
    the sample, an edge ``a*x + b*y <= c``, and the polygon's index in ``polygons``.
    """

    def __init__(
        self,
        polygons: Sequence[Mapping[str, Any]],
        edges: Sequence[Tuple[int, int, float, float, float, int]],
        lazy: bool = False,
    ) -> None:
        """``lazy``: the tables are built at their first use (:meth:`broken`,
        :meth:`compiled`), not here."""
        count = len(polygons)
        self.count = count
        per: List[List[Edge]] = [[] for _ in range(count)]
        axes: List[Tuple[int, int]] = [(0, 0)] * count
        for x, y, a, b, c, owner in edges:
            per[owner].append((a, b, c))
            axes[owner] = (x, y)
        self.xs = [ax[0] for ax in axes]
        self.ys = [ax[1] for ax in axes]
        self.x = np.asarray(self.xs, dtype=np.int64)
        self.y = np.asarray(self.ys, dtype=np.int64)
        # each polygon's edges twice: a cyclic run is one slice
        self.edges = [e + e for e in per]
        self._runs: Dict[int, Tuple[int, int, Tuple[Edge, ...]]] = {}
        """The runs of edges met so far, by ``polygon * 256 + table code``."""
        self._fine_runs: Dict[int, Tuple[int, int, Tuple[Edge, ...]]] = {}
        """The runs of the fine cells met lately, by ``bit table offset * 8 + bit``."""
        self._last_cells = b""
        self._last: Tuple[Any, Any] = (np.empty(0, np.int64), None)
        """The last lookup: its candidates and every polygon's offset in the bits."""
        width = max([len(e) for e in per] + [1])
        table = np.zeros((count, width, 3))
        for owner, rows in enumerate(per):
            table[owner] = rows + [rows[0]] * (width - len(rows)) if rows else [(0.0,) * 3]
        self.abc = np.ascontiguousarray(np.moveaxis(table, 2, 0))
        """``(3, polygons, edges)``: each edge's ``a``, ``b`` and ``c``, padded by
        repeating the first."""
        self.size = int(max(self.x.max(), self.y.max())) + 1 if count else 0
        self._ranges(polygons, axes)
        self.grid = grid_size(count)
        self._pending: Optional[Tuple[List[List[Edge]], List[Tuple[int, int]]]] = (per, axes)
        """The edges and axes of the tables not built yet (``None`` once they are)."""
        if not lazy:
            self._build()

    def _build(self) -> None:
        """Build the tables (once)."""
        if self._pending is not None:
            per, axes = self._pending
            self._tables(per, axes)
            self._pending = None

    def _ranges(self, polygons: Sequence[Mapping[str, Any]], axes: List[Tuple[int, int]]) -> None:
        """Each variable's range over the polygons' vertices, and its quantisation."""
        size = self.size
        low = np.full(size, np.inf)
        high = np.full(size, -np.inf)
        for owner, polygon in enumerate(polygons):
            points = np.asarray(polygon["params"]["vertices"], dtype=np.float64).reshape(-1, 2)
            if len(points):
                for axis, var in enumerate(axes[owner]):
                    low[var] = min(low[var], points[:, axis].min())
                    high[var] = max(high[var], points[:, axis].max())
        used = np.zeros(size, dtype=bool)
        used[self.x] = True
        used[self.y] = True
        # a variable no polygon reads accepts anything but NaN in the range test
        self.low = np.where(used, low, -np.inf)
        self.high = np.where(used, high, np.inf)
        self.used = used.nonzero()[0]
        self.reach = np.maximum(np.abs(low), np.abs(high))

    def _tables(self, per: List[List[Edge]], axes: List[Tuple[int, int]]) -> None:
        grid = self.grid
        fine = grid << _SPLIT
        low, high = self.low, self.high
        with np.errstate(all="ignore"):
            cell = (high - low) / (grid - 2 + 2 * _END)
            scale = 1.0 / cell
            usable = (
                np.isfinite(low)
                & np.isfinite(high)
                & (high > low)
                & np.isfinite(scale)
                & (cell > 2.0**-40 * self.reach)
            )
            # the range's ends a thin slice into the first and the last cell
            self.origin = np.where(usable, low - (1 - _END) * cell, 0.0)
            self.scale = np.where(usable, scale, 0.0)
            widen = _WIDEN * cell + 8 * 2.0**-52 * self.reach
        # twice the scale, exactly: a fine cell is half a coarse one, and the fine cell
        # of a sample is a child of its coarse cell, however the product rounds
        self.fine_scale = float(1 << _SPLIT) * self.scale
        fine_cell = cell / (1 << _SPLIT)
        self._fine_boxes = [
            (float(o), float(f), float(w), float(lo), float(hi)) if ok else None
            for o, f, w, lo, hi, ok in zip(self.origin, fine_cell, widen, low, high, usable)
        ]
        """Per variable, what its fine cells' boxes are made of (:func:`_cells`); ``None``
        where the variable has no grid."""
        owners = np.arange(self.count, dtype=np.int64)
        per_row = 256 // grid
        blocks = -(-self.count // per_row) if self.count else 0
        self.table = np.zeros(blocks * 256 * grid, dtype=np.uint8)
        self.base = (owners // per_row) * (256 * grid) + (owners % per_row) * grid
        # bits: a plane of 256 x fine bytes, 256 // fine slots of fine columns, each slot's
        # bytes shared by up to 8 polygons reading the same row variable
        self.flipped, slot_of, bit_of = _byte_groups(self.xs, self.ys)
        slots = 256 // fine
        planes = -(-(max(slot_of) + 1) // slots) if self.count else 0
        self.bits = np.zeros(planes * 256 * fine, dtype=np.uint8)
        slot = np.asarray(slot_of, dtype=np.int64)
        self.fine_base = (slot // slots) * (256 * fine) + (slot % slots) * fine
        self.bit = np.asarray([1 << b for b in bit_of], dtype=np.uint8)
        self.plane = 256 * fine
        # the gathers read (column cell, row cell) as one uint16: column + 256 * row; the
        # codes' columns are x, the bits' the variable that is not the row's
        self.at = np.stack([self.x, self.y], axis=1).ravel()
        pairs = [(y, x) if flip else (x, y) for x, y, flip in zip(self.xs, self.ys, self.flipped)]
        self.fine_at = np.asarray(pairs, dtype=np.int64).reshape(-1)
        self._pairs = np.zeros(2 * self.count, dtype=np.uint8)
        self._pairs16 = self._pairs.view(np.uint16)
        """The gathered (column cell, row cell) of every polygon, and as uint16."""
        self._hit = np.zeros(self.count, dtype=np.uint8)
        self._near = self._hit.view(np.bool_)
        """Every polygon's byte of the bits, masked to its bit, and as bool."""
        steps = np.arange(grid, dtype=np.int64)
        spots = steps[:, None] + 256 * steps[None, :]  # [x cell, y cell] -> offset
        fine_steps = np.arange(fine, dtype=np.int64)
        fine_spots = fine_steps[:, None] + 256 * fine_steps[None, :]
        for owner, rows in enumerate(per):
            x, y = axes[owner]
            codes = np.full((grid, grid), _ALL, dtype=np.uint8)
            near = np.ones((fine, fine), dtype=bool)
            if rows and usable[x] and usable[y]:
                box_x = _cells(self.origin[x], cell[x], widen[x], low[x], high[x], grid)
                box_y = _cells(self.origin[y], cell[y], widen[y], low[y], high[y], grid)
                codes = _codes(rows, box_x, box_y)
                half_x = _cells(self.origin[x], fine_cell[x], widen[x], low[x], high[x], fine)
                half_y = _cells(self.origin[y], fine_cell[y], widen[y], low[y], high[y], fine)
                near = _near(rows, half_x, half_y, codes != 0)
            self.table[self.base[owner] + spots.ravel()] = codes.ravel()
            at = fine_spots.T if self.flipped[owner] else fine_spots
            self.bits[self.fine_base[owner] + at[near]] |= self.bit[owner]

    def compiled(self) -> Tuple[List[Guard], List[Polygon], int]:
        """The grids' variables, the polygons and the shift from a fine cell to its coarse
        one, as :func:`.compiled.pack` takes them (the bits' quantisation, offsets and bits,
        each polygon's coarse bits and its edges once)."""
        self._build()
        guards: List[Guard] = [
            (
                int(v),
                float(self.low[v]),
                float(self.high[v]),
                float(self.origin[v]),
                float(self.fine_scale[v]),
            )
            for v in self.used
        ]
        fine = self.grid << _SPLIT
        shift = (fine // COARSE).bit_length() - 1
        steps = np.arange(fine, dtype=np.int64)
        spots = steps[:, None] + 256 * steps[None, :]  # [column cell, row cell] -> offset
        polygons: List[Polygon] = []
        for j in range(self.count):
            near = (self.bits[self.fine_base[j] + spots] & self.bit[j]) != 0
            cells = near.reshape(COARSE, fine // COARSE, COARSE, fine // COARSE).any(axis=(1, 3))
            # bit column + COARSE * row, little-endian: bit b of word b >> 5 is bit b & 31
            words = np.packbits(cells.T.reshape(-1), bitorder="little").view("<i4")
            polygons.append(
                Polygon(
                    int(self.fine_at[2 * j]),
                    int(self.fine_at[2 * j + 1]),
                    int(self.fine_base[j]),
                    int(self.bit[j]),
                    words.tolist(),
                    self.xs[j],
                    self.ys[j],
                    self.edges[j][: len(self.edges[j]) // 2],
                )
            )
        return guards, polygons, shift

    def forget(self) -> None:
        """Forget the last lookup: the next sample is looked up even in the same cells."""
        self._last_cells = b""

    def in_range(self, row: Any) -> bool:
        """Whether every value the polygons read is finite and inside its grid's range
        (then :meth:`broken` may take the fast path)."""
        values = row[: self.size]
        return bool(((values >= self.low) & (values <= self.high)).all())

    def broken(self, row: Any, in_range: Optional[bool] = None) -> List[int]:
        """The polygons ``row`` is outside of, ascending. ``in_range``: whether the caller
        knows every value the polygons read to be finite and inside its range (``None``:
        find out)."""
        if not self.count:
            return []
        if self._pending is not None:
            self._build()
        if in_range is None:
            in_range = self.in_range(row)
        if not in_range:
            return self._slow(row)
        g = row[: self.size] - self.origin
        g *= self.fine_scale
        cells = g.astype(np.uint8)
        # the candidates depend on the cells alone: a signal that stays in its cells (a
        # slow one, a discrete one) costs no lookup
        key_cells = cells.tobytes()
        if key_cells == self._last_cells:
            candidates, offsets = self._last
        else:
            # gathers into buffers made once, in "clip" mode (the indices are in range by
            # construction): numpy buffers ``out`` in "raise" mode, and a new array and its
            # views cost a call each; together a tenth of the point's time
            cells.take(self.fine_at, out=self._pairs, mode="clip")
            offsets = self._pairs16 + self.fine_base
            hit = self.bits.take(offsets, out=self._hit, mode="clip")
            hit &= self.bit
            # most samples have no candidate: counting is quicker than finding; then
            # nonzero over a bool view (numpy's fast path for bool: any nonzero byte is
            # true) is several times quicker than over uint8
            near = self._near
            candidates = near.nonzero()[0] if count_nonzero(near) else _NONE
            self._last_cells = key_cells
            self._last = candidates, offsets
        if not len(candidates):
            return []
        return self._edges_near(row, candidates, offsets)

    def _edges_near(self, row: Any, candidates: Any, offsets: Any) -> List[int]:
        """Which of ``candidates`` ``row`` is outside of: each one's edges near its fine cell
        (``offsets``: every polygon's offset in the bits), or all of them when many."""
        if len(candidates) > _MANY:
            return self._outside(row, candidates)
        found = []
        value = row.item if len(candidates) <= _FEW else row.tolist().__getitem__
        offset_of = offsets.item
        runs = self._fine_runs
        plane = self.plane
        within = plane - 1
        for owner in candidates.tolist():
            offset = offset_of(owner)
            key = owner * plane + (offset & within)
            run = runs.get(key)
            if run is None:
                run = self._fine_run(owner, offset, key)
            x = value(run[0])
            y = value(run[1])
            for a, b, c in run[2]:
                if a * x + b * y > c:
                    found.append(owner)
                    break
        return found

    def _fine_run(self, owner: int, offset: int, key: int) -> Tuple[int, int, Tuple[Edge, ...]]:
        """The edges polygon ``owner`` may break in its fine cell at ``offset`` in the bits
        (its coarse cell's run, less the edges the fine cell keeps clear of), remembered
        under ``key``."""
        mask = (self.grid << _SPLIT) - 1
        column, row = offset & mask, (offset >> 8) & mask
        x_cell, y_cell = (row, column) if self.flipped[owner] else (column, row)
        code = self.table.item(
            int(self.base[owner]) + (x_cell >> _SPLIT) + 256 * (y_cell >> _SPLIT)
        )
        coarse = owner * 256 + code
        run = self._runs.get(coarse)
        if run is None:
            run = self._runs[coarse] = self._run(owner, code)
        x, y, edges = run
        box_x, box_y = self._fine_boxes[x], self._fine_boxes[y]
        if box_x is not None and box_y is not None:
            x_low, x_high = _box(box_x, x_cell)
            y_low, y_high = _box(box_y, y_cell)
            # the worst corner as the bits were made (:func:`_near`)
            edges = tuple(
                (a, b, c)
                for a, b, c in edges
                if (x_high if a >= 0 else x_low) * a + (y_high if b >= 0 else y_low) * b > c
            )
            run = (x, y, edges)
        if len(self._fine_runs) >= _FINE_RUNS:
            self._fine_runs.clear()
        self._fine_runs[key] = run
        return run

    def _run(self, owner: int, code: int) -> Tuple[int, int, Tuple[Edge, ...]]:
        """The variables of polygon ``owner`` and the edges its table ``code`` names."""
        edges = self.edges[owner]
        first, stop = (0, len(edges) // 2) if code == _ALL else DECODE[code]
        return self.xs[owner], self.ys[owner], tuple(edges[first:stop])

    def _slow(self, row: Any) -> List[int]:
        """A value outside its range or not finite: the polygons reading such a value are
        all candidates (every edge tested), the others are looked up as usual."""
        values = row[: self.size]
        outside = ~((values >= self.low) & (values <= self.high))
        g = values - self.origin
        g *= self.scale
        np.fmax(g, 0.0, out=g)  # NaN -> 0
        np.fmin(g, self.grid - 0.5, out=g)
        flat = g.astype(np.uint8).take(self.at).view(np.uint16) + self.base
        hit = self.table.take(flat) != 0
        hit |= outside.take(self.x)
        hit |= outside.take(self.y)
        return self._outside(row, hit.nonzero()[0])

    def _outside(self, row: Any, candidates: Any) -> List[int]:
        """Which of ``candidates`` ``row`` is outside of, testing every edge."""
        if not len(candidates):
            return []
        px = row.take(self.x.take(candidates))[:, None]
        py = row.take(self.y.take(candidates))[:, None]
        a, b, c = self.abc.take(candidates, axis=1)
        hit = (a * px + b * py > c).any(axis=1)
        if not count_nonzero(hit):
            return []
        # inference builds hulls from finite samples only: a NaN or infinite coordinate
        # breaks no polygon (a NaN compares false already; an inf would reach past an edge)
        hit &= np.isfinite(px[:, 0]) & np.isfinite(py[:, 0])
        return [int(k) for k in candidates[hit]]


def _byte_groups(xs: Sequence[int], ys: Sequence[int]) -> Tuple[List[bool], List[int], List[int]]:
    """Polygons sharing bytes in the bits: each polygon's row variable (``flipped``: x,
    else y), slot and bit. The polygons of a slot read the same row variable, so a sample
    reads one row of the slot for all of them (a cache line or two, not eight). Greedy: the
    variable with the most polygons left takes them by the eight while one has eight left,
    then the variable with the most left takes all of its."""
    count = len(xs)
    incident: Dict[int, List[int]] = {}
    for owner in range(count):
        incident.setdefault(xs[owner], []).append(owner)
        incident.setdefault(ys[owner], []).append(owner)
    left = {var: len(owners) for var, owners in incident.items()}
    row_of = [-1] * count
    groups: List[List[int]] = []
    for whole in (True, False):
        while left:
            var = max(left, key=lambda v: (left[v], -v))
            if left[var] < (8 if whole else 1):
                break
            free = [owner for owner in incident[var] if row_of[owner] < 0]
            take = len(free) - len(free) % 8 if whole else len(free)
            for owner in free[:take]:
                row_of[owner] = var
                left[xs[owner]] -= 1
                left[ys[owner]] -= 1
            groups += [free[k : k + 8] for k in range(0, take, 8)]
    flipped = [row_of[owner] == xs[owner] != ys[owner] for owner in range(count)]
    slot_of, bit_of = [0] * count, [0] * count
    for slot, members in enumerate(groups):
        for bit, owner in enumerate(members):
            slot_of[owner], bit_of[owner] = slot, bit
    return flipped, slot_of, bit_of


def _box(box: Tuple[float, float, float, float, float], k: int) -> Tuple[float, float]:
    """The low and high ends of fine cell ``k`` of a variable whose fine cells are ``box``
    (origin, cell, widening, range): :func:`_cells` in float64 scalars, the same roundings."""
    origin, cell, widen, low, high = box
    return max(origin + k * cell - widen, low), min(origin + (k + 1) * cell + widen, high)


def _cells(origin: float, cell: float, widen: float, low: float, high: float, grid: int) -> Any:
    """``(2, grid)``: the low and high ends of the box each cell's samples lie in."""
    steps = np.arange(grid + 1, dtype=np.float64)
    ends = origin + steps * cell
    return np.stack(
        [np.maximum(ends[:-1] - widen, low), np.minimum(ends[1:] + widen, high)], axis=0
    )


def _codes(edges: Sequence[Edge], box_x: Any, box_y: Any) -> Any:
    """``(grid, grid)`` table codes of one polygon: per cell the cyclic run of edges a
    sample in the cell may break (:data:`DECODE`), 0 for none."""
    a, b, c = (np.asarray(column, dtype=np.float64) for column in zip(*edges))
    # the worst corner of each cell per edge: a linear function is largest at a corner,
    # and so is its float64 evaluation (rounding is monotone)
    x_worst = np.where(a[:, None] >= 0, box_x[1], box_x[0]) * a[:, None]
    y_worst = np.where(b[:, None] >= 0, box_y[1], box_y[0]) * b[:, None]
    m, grid = len(edges), box_x.shape[1]
    may = np.empty((m, grid, grid), dtype=bool)  # (edges, gx, gy)
    step = max(1, _BLOCK // (grid * grid))
    for start in range(0, m, step):  # the float64 sums of a few edges at a time
        part = slice(start, start + step)
        np.greater(
            x_worst[part, :, None] + y_worst[part, None, :], c[part, None, None], out=may[part]
        )
    codes = np.zeros((grid, grid), dtype=np.uint8)
    near = may.any(axis=0)
    if not near.any():
        return codes
    rel = may[:, near]  # (edges, cells near an edge)
    # the longest cyclic run of edges that cannot be broken: the rest is the run to test
    run = np.zeros(rel.shape[1], dtype=np.int64)
    best = np.zeros_like(run)
    best_end = np.zeros_like(run)
    for k in range(2 * m):
        run = np.where(rel[k % m], 0, run + 1)
        longer = run > best
        best = np.where(longer, run, best)
        best_end = np.where(longer, k, best_end)
    best = np.minimum(best, m)
    first = np.where(best > 0, (best_end + 1) % m, 0)
    count = m - best
    code = np.where((first < _FIRSTS) & (count <= _RUNS), 1 + first * _RUNS + count - 1, _ALL)
    codes[near] = code.astype(np.uint8)
    return codes


def _near(edges: Sequence[Edge], box_x: Any, box_y: Any, coarse: Any) -> Any:
    """``(fine, fine)``: the fine cells (``box_x``, ``box_y``) where a sample may break an
    edge. Only the children of ``coarse`` cells (the coarse grid, near an edge) are
    looked at: a fine cell lies inside its coarse one, and a linear function's worst corner
    over a box within another is no larger."""
    a, b, c = (np.asarray(column, dtype=np.float64) for column in zip(*edges))
    fine = box_x.shape[1]
    near = np.zeros((fine, fine), dtype=bool)
    xs, ys = np.repeat(np.repeat(coarse, 1 << _SPLIT, axis=0), 1 << _SPLIT, axis=1).nonzero()
    if not len(xs):
        return near
    low_x, high_x, low_y, high_y = box_x[0][xs], box_x[1][xs], box_y[0][ys], box_y[1][ys]
    hit = np.zeros(len(xs), dtype=bool)
    step = max(1, _BLOCK // len(xs))
    for start in range(0, len(a), step):  # a few edges at a time: (edges, cells) arrays
        part = slice(start, start + step)
        x_worst = np.where(a[part, None] >= 0, high_x, low_x) * a[part, None]
        y_worst = np.where(b[part, None] >= 0, high_y, low_y) * b[part, None]
        hit |= ((x_worst + y_worst) > c[part, None]).any(axis=0)
    near[xs, ys] = hit
    return near
