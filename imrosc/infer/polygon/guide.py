"""Conservative shapes inside each pair's current hull, used to discard samples cheaply.

For a pair whose hull ``H`` has at least three vertices, the guide keeps (recomputed only
when ``H`` changes):

* axis-aligned boxes certified strictly inside ``H`` (every corner passes Shewchuk's float
  orientation test against every edge): the largest *square-ish* box, and *wide* boxes
  (a fixed fraction of ``H``'s height, as wide as ``H`` allows) and *tall* boxes (the
  transpose); each serves alone, and a wide and a tall box together form a cross;
* a center ``c`` strictly inside ``H`` and ``H``'s bounding-box spans ``(sx, sy)``, which
  define normalised coordinates ``u = (x - cx) / sx``, ``v = (y - cy) / sy``;
* a polar table: the plane around ``c`` cut into ``BUCKETS`` sectors (equal steps of the
  "diamond angle", a cheap monotone stand-in for the angle); per sector the chord joining
  the points of ``H``'s boundary on the sector's two bounding rays, each pulled towards
  ``c`` by ``1e-7`` of its radius (far more than any rounding of the lookup), so the
  triangle it closes with ``c`` lies strictly inside ``H``. Hulls with an edge passing
  within ``1e-6`` (normalised) of ``c`` get no table: a ray grazing a vertex could meet
  a nearly radial edge far away.

Per sector facing a single edge of ``H`` (no vertex's angle near the sector) whose slope is
zero, infinite or a power of two up to rounding, the table also keeps that edge's sheared
frame (:func:`~imrosc.infer.polygon.predicates.edge_frames`): a sample the chord leaves
(samples of exact relations lie *on* such edges) is decided exactly there, and if on the
edge's inner side or on it, it is in the closed hull and none of its vertices.

A sample inside a box, or on the inner side of its sector's chord, is strictly inside
``H``, hence no vertex of any later hull; so is every point of a box whose four corners are
(the interior of ``H`` is convex). The tables are built in cache-sized batches of pairs.

Pairs left without a table (a hull that is a segment or a sliver a few units of rounding
wide, where no float test proves anything) keep their vertices in a
:class:`~imrosc.infer.polygon.locate.Locator` instead: :meth:`Guide.discards` locates
their samples exactly. Pairs without any hull keep every sample.
"""

from __future__ import annotations

import functools

import numpy as np
import numpy.typing as npt

from imrosc.infer.core import FloatArray
from imrosc.infer.polygon.hull import GroupSet, IntArray
from imrosc.infer.polygon.locate import Locator
from imrosc.infer.polygon.predicates import Frames, edge_frames, frame_orientation, surely_left

BoolArray = npt.NDArray[np.bool_]

BUCKETS = 256
"""Sectors of the polar table, at most (fewer when there are many pairs, see ``_TABLE``)."""

_TABLE = 64 * 2**20
"""Bytes the polar tables of one point may take (see ``_CELL``)."""
_CELL = 73
"""Bytes per sector of a polar table: the chord (three floats), the frame of the edge it
faces (six floats and its kind)."""
_MARGIN = 2.0**-20
"""A sector whose edge is known runs this far (in sectors) inside the edge's angular span
at both ends: far more than the rounding of any angle."""
_TABLE_BLOCK = 1 << 14
"""Table entries computed together (keeps the temporaries in cache)."""
FRACTIONS = (0.3, 0.55, 0.8, 0.98)
"""Heights of the wide boxes (widths of the tall ones) as fractions of the hull's span (the
nearly full one suits a variable of few values, or one crowding an end of its range, whose
extreme values hold many rows: an integer column beside ``|n|``)."""

_SHRINK = 1e-7
_CLEAR = 1e-6
_TINY = 2.0**-800
_HUGE = 2.0**800
_UNIT8 = 8 * 2.0**-53


def _empty_boxes(*shape: int) -> FloatArray:
    box = np.empty((*shape[:-1], 4, shape[-1]))
    box[..., 0::2, :] = np.inf
    box[..., 1::2, :] = -np.inf
    return box


def _padded(hull: GroupSet, pairs: IntArray) -> tuple[FloatArray, FloatArray, IntArray]:
    """The hull vertices of ``pairs`` as ``(pairs, width)`` arrays (NaN padded), counts."""
    top = max(int(hull.group.max()) + 1 if len(hull) else 0, int(pairs.max()) + 1)
    slot = np.full(top, -1, np.int64)
    slot[pairs] = np.arange(len(pairs))
    mine = np.flatnonzero(slot[hull.group] >= 0)
    rows = slot[hull.group[mine]]
    count = np.bincount(rows, minlength=len(pairs)).astype(np.int64)
    width = max(int(count.max()) if len(count) else 0, 1)
    first = np.concatenate([[0], np.cumsum(count)[:-1]])
    col = np.arange(len(mine)) - np.repeat(first, count)
    vx = np.full((len(pairs), width), np.nan)
    vy = np.full((len(pairs), width), np.nan)
    vx[rows, col] = hull.x[mine]
    vy[rows, col] = hull.y[mine]
    return vx, vy, count


class _Polygons:
    """Padded convex polygons (counter-clockwise) with their edges."""

    def __init__(self, vx: FloatArray, vy: FloatArray, count: IntArray) -> None:
        self.vx, self.vy, self.count = vx, vy, count
        col = np.arange(vx.shape[1])[None, :]
        self.real = col < count[:, None]
        nxt = np.where(col + 1 < count[:, None], col + 1, 0)
        self.wx = np.take_along_axis(vx, nxt, axis=1)
        self.wy = np.take_along_axis(vy, nxt, axis=1)

    def strictly_inside(self, x: FloatArray, y: FloatArray) -> BoolArray:
        """Whether each pair's point ``(x, y)`` is certainly strictly inside its polygon."""
        left = surely_left(self.vx, self.vy, self.wx, self.wy, x[:, None], y[:, None])
        inside: BoolArray = np.asarray((left | ~self.real).all(axis=1), dtype=bool)
        return inside

    def certified(self, box: FloatArray, ok: BoolArray) -> FloatArray:
        """``box`` where its four corners are certainly strictly inside, else empty."""
        good = ok & np.isfinite(box).all(axis=0) & (box[0] <= box[1]) & (box[2] <= box[3])
        for bx, by in ((box[0], box[2]), (box[0], box[3]), (box[1], box[2]), (box[1], box[3])):
            good &= self.strictly_inside(bx, by)
        out: FloatArray = box.copy()
        out[0::2, ~good] = np.inf
        out[1::2, ~good] = -np.inf
        return out

    def span(self, low: FloatArray, high: FloatArray) -> tuple[FloatArray, FloatArray]:
        """A ``[left, right]`` with ``[left, right] x [low, high]`` strictly inside.

        Each edge bounds ``x`` at both heights; the bound is moved inwards by eight units
        of rounding of its terms, which exceeds the error of computing it (the rounded
        edge direction included), so no corner needs a separate certificate.
        """
        dx = self.wx - self.vx
        dy = self.wy - self.vy
        left = np.full(len(low), -np.inf)
        right = np.full(len(low), np.inf)
        for y in (low, high):
            shift = dx * (y[:, None] - self.vy) / dy
            at = self.vx + shift
            slack = _UNIT8 * (np.abs(shift) + np.abs(at) + np.abs(self.vx))
            up = self.real & (dy > 0) & np.isfinite(at)
            down = self.real & (dy < 0) & np.isfinite(at)
            right = np.minimum(right, np.where(up, at - slack, np.inf).min(axis=1))
            left = np.maximum(left, np.where(down, at + slack, -np.inf).max(axis=1))
            flat = self.real & (dy == 0)
            blocked = flat & (dx * (y[:, None] - self.vy) <= 0)
            left = np.where(blocked.any(axis=1) | ~np.isfinite(y), np.inf, left)
        return left, right


class Guide:
    """Per-pair filters derived from the current hulls (a cache: not part of the state)."""

    def __init__(self, npairs: int) -> None:
        self.ok = np.zeros(npairs, bool)
        self.stamp = np.zeros(npairs, np.int64)
        self.version = 0
        # which box (square, or wide and tall) filtered each pair best, and for which guide
        self.choice = np.zeros(npairs, np.int64)
        self.choice_stamp = np.full(npairs, -1, np.int64)
        self.square = _empty_boxes(npairs)
        self.wide = _empty_boxes(len(FRACTIONS), npairs)
        self.tall = _empty_boxes(len(FRACTIONS), npairs)
        self.cx = np.zeros(npairs)
        self.cy = np.zeros(npairs)
        self.sx = np.ones(npairs)
        self.sy = np.ones(npairs)
        self.ix = np.ones(npairs)
        self.iy = np.ones(npairs)
        # per pair and sector, the chord: inside when nx * u + ny * v < level
        self.buckets = _buckets(npairs)
        self.planes = (
            np.zeros(npairs * self.buckets),
            np.zeros(npairs * self.buckets),
            np.full(npairs * self.buckets, -np.inf),
        )
        # per pair and sector, the frame of the edge the whole sector faces, if any
        # (_edge_frames; kind 0 for none)
        cells = npairs * self.buckets
        self.frames: Frames = (
            np.zeros(cells, np.int8),
            *(np.zeros(cells) for _ in range(6)),
        )  # type: ignore[assignment]
        # pairs without a table: their vertices, for exact location
        self.loose = GroupSet.empty()
        self.locator = Locator.build(self.loose, npairs)

    def refresh(self, hull: GroupSet, pairs: IntArray) -> None:
        """Recompute the guide of ``pairs`` from their current hull vertices."""
        if not len(pairs):
            return
        self.version += 1
        self.stamp[pairs] = self.version
        vx, vy, count = _padded(hull, pairs)
        poly = _Polygons(vx, vy, count)
        with np.errstate(all="ignore"):
            lo_x, hi_x = np.nanmin(vx, axis=1), np.nanmax(vx, axis=1)
            lo_y, hi_y = np.nanmin(vy, axis=1), np.nanmax(vy, axis=1)
            sx, sy = hi_x - lo_x, hi_y - lo_y
            # far from underflow and overflow, where the float bounds below hold
            top = np.maximum(np.nanmax(np.abs(vx), axis=1), np.nanmax(np.abs(vy), axis=1))
            ok = (count >= 3) & (sx > _TINY) & (sy > _TINY) & (top < _HUGE)
            cx = np.where(ok, np.nanmean(vx, axis=1), 0.0)
            cy = np.where(ok, np.nanmean(vy, axis=1), 0.0)
            ok &= poly.strictly_inside(cx, cy)
            self.square[:, pairs] = self._square(poly, ok, lo_x, hi_x, lo_y, hi_y)
            mid_x, mid_y = (lo_x + hi_x) / 2, (lo_y + hi_y) / 2
            # the transposed polygon (x and y swapped, order reversed to stay CCW)
            flipped = _Polygons(
                _roll_real(vy[:, ::-1], count), _roll_real(vx[:, ::-1], count), count
            )
            for k, fraction in enumerate(FRACTIONS):
                low, high = mid_y - fraction * sy / 2, mid_y + fraction * sy / 2
                left, right = poly.span(low, high)
                self.wide[k][:, pairs] = _valid(np.stack([left, right, low, high]), ok)
                low, high = mid_x - fraction * sx / 2, mid_x + fraction * sx / 2
                bottom, top = flipped.span(low, high)
                self.tall[k][:, pairs] = _valid(np.stack([low, high, bottom, top]), ok)
            self._table(poly, pairs, ok, (cx, cy), (sx, sy))
        self.ok[pairs] = ok
        self.cx[pairs] = cx
        self.cy[pairs] = cy
        self.sx[pairs] = np.where(ok, sx, 1.0)
        self.sy[pairs] = np.where(ok, sy, 1.0)
        self.ix[pairs] = 1 / self.sx[pairs]
        self.iy[pairs] = 1 / self.sy[pairs]
        self._relocate(hull, pairs, ok)

    def _relocate(self, hull: GroupSet, pairs: IntArray, ok: BoolArray) -> None:
        """Keep the vertices of the pairs left without a table (``~ok``) for location."""
        npairs = len(self.ok)
        redone = np.zeros(npairs, bool)
        redone[pairs] = True
        loose = np.zeros(npairs, bool)
        loose[pairs[~ok]] = True
        if not loose.any() and not len(self.loose):
            return
        kept = self.loose.take(np.flatnonzero(~redone[self.loose.group]))
        fresh = hull.take(np.flatnonzero(loose[hull.group]))
        self.loose = GroupSet.concat([kept, fresh])
        self.locator = Locator.build(self.loose, npairs)

    @staticmethod
    def _square(
        poly: _Polygons,
        ok: BoolArray,
        lo_x: FloatArray,
        hi_x: FloatArray,
        lo_y: FloatArray,
        hi_y: FloatArray,
    ) -> FloatArray:
        """The larger certified box of the hull's shape about two centres, ``(4, pairs)``."""
        vx, vy, wx, wy = poly.vx, poly.vy, poly.wx, poly.wy
        dx = wx - vx
        dy = wy - vy
        hx = (hi_x - lo_x) / 2
        hy = (hi_y - lo_y) / 2
        room = np.abs(dx) * hy[:, None] + np.abs(dy) * hx[:, None]
        centres = (((lo_x + hi_x) / 2, (lo_y + hi_y) / 2), (np.nanmean(vx, 1), np.nanmean(vy, 1)))
        best = _empty_boxes(vx.shape[0])
        best_area = np.zeros(vx.shape[0])
        for cx, cy in centres:
            reach = dx * (cy[:, None] - vy) - dy * (cx[:, None] - vx)
            scale = np.where(poly.real, reach / room, np.inf).min(axis=1)
            good = ok & np.isfinite(scale) & (scale > 0)
            scale = np.where(good, scale * (1 - 1e-6), 0.0)
            box = np.stack([cx - scale * hx, cx + scale * hx, cy - scale * hy, cy + scale * hy])
            box = poly.certified(box, good)
            area = np.where(box[0] <= box[1], (box[1] - box[0]) * (box[3] - box[2]), 0.0)
            better = area > best_area
            best[:, better] = box[:, better]
            best_area = np.where(better, area, best_area)
        return best

    def _table(
        self,
        poly: _Polygons,
        pairs: IntArray,
        ok: BoolArray,
        centre: tuple[FloatArray, FloatArray],
        span: tuple[FloatArray, FloatArray],
    ) -> None:
        """Write the polar tables of ``pairs`` (rows of ``poly``), by cache-sized blocks."""
        nx, ny, level = (plane.reshape(-1, self.buckets) for plane in self.planes)
        frames = [plane.reshape(-1, self.buckets) for plane in self.frames]
        nx[pairs] = 0.0
        ny[pairs] = 0.0
        level[pairs] = -np.inf
        frames[0][pairs] = 0
        rows = np.flatnonzero(ok)
        step = max(1, _TABLE_BLOCK // self.buckets)
        for first in range(0, len(rows), step):
            mine = rows[first : first + step]
            chords, (which, faced) = _chords(poly, mine, centre, span, self.buckets)
            target = pairs[mine]
            nx[target], ny[target], level[target] = chords
            for plane, values in zip(frames, faced, strict=True):
                plane[target[which]] = np.asarray(values)

    def discards(self, pair: IntArray, x: FloatArray, y: FloatArray) -> BoolArray:
        """Where the sample ``(x, y)`` of ``pair`` is certainly no new vertex: strictly
        inside its hull by the table, or (pairs without one) in the closed hull and none of
        its vertices, by exact location."""
        found = self.inside(pair, x, y)
        if len(self.loose):
            found |= self.locator.covered(pair, x, y)
        return found

    def inside(self, pair: IntArray, x: FloatArray, y: FloatArray) -> BoolArray:
        """Where the sample ``(x, y)`` of ``pair`` is certainly no new vertex: strictly
        inside its hull by its sector's chord, or, in a sector facing one edge, on that edge's
        inner side or its line by the edge's frame (then in the closed hull and none of its
        vertices, see :func:`_edge_frames`)."""
        return self._lookup(
            x,
            y,
            (self.cx.take(pair), self.cy.take(pair), self.ix.take(pair), self.iy.take(pair)),
            pair * self.buckets,
            self.planes,
            self.frames,
        )

    def inside_run(self, pair: int, x: FloatArray, y: FloatArray) -> BoolArray:
        """:meth:`inside` for samples of one pair (the same arithmetic, with the pair's
        centre and scales as scalars and its own table)."""
        lo, hi = pair * self.buckets, (pair + 1) * self.buckets
        return self._lookup(
            x,
            y,
            (self.cx[pair], self.cy[pair], self.ix[pair], self.iy[pair]),
            None,
            tuple(plane[lo:hi] for plane in self.planes),  # type: ignore[arg-type]
            tuple(plane[lo:hi] for plane in self.frames),  # type: ignore[arg-type]
        )

    def _lookup(
        self,
        x: FloatArray,
        y: FloatArray,
        centre: tuple[FloatArray | np.float64, ...],
        offset: IntArray | None,
        planes: tuple[FloatArray, FloatArray, FloatArray],
        frames: Frames,
    ) -> BoolArray:
        cx, cy, ix, iy = centre
        with np.errstate(all="ignore"):
            u = (x - cx) * ix
            v = (y - cy) * iy
            # the diamond angle, shifted by 4 to stay positive, wrapped to a sector
            p = v / (np.abs(u) + np.abs(v))
            turn = np.where(u >= 0, p, 2 - p)
            turn += 4
            turn *= self.buckets / 4
            cell = turn.astype(np.int64)
            cell &= self.buckets - 1
            if offset is not None:
                cell += offset
            nx, ny, level = planes
            result: BoolArray = nx.take(cell) * u + ny.take(cell) * v < level.take(cell)
            miss = np.flatnonzero(~result)
            if len(miss):
                cell = cell.take(miss)
                sel = np.flatnonzero(frames[0].take(cell))
                if len(sel):
                    miss, cell = miss.take(sel), cell.take(sel)
                    faced = tuple(plane.take(cell) for plane in frames)
                    sign, decided = frame_orientation(faced, x.take(miss), y.take(miss))
                    result[miss[decided & (sign >= 0)]] = True
        return result


def _chords(
    poly: _Polygons,
    rows: IntArray,
    centre: tuple[FloatArray, FloatArray],
    span: tuple[FloatArray, FloatArray],
    buckets: int,
) -> tuple[
    tuple[FloatArray, FloatArray, FloatArray],
    tuple[IntArray, Frames],
]:
    """The polar tables of ``rows`` of ``poly`` (see the module docstring), as the planes
    ``(nx, ny, level)``, ``(rows, buckets)`` each: inside when ``nx * u + ny * v < level``;
    and the frames of the edges the sectors face, for the rows with any
    (:func:`_edge_frames`)."""
    width = poly.vx.shape[1]
    k = len(rows)
    cx, cy = centre[0][rows], centre[1][rows]
    sx, sy = span[0][rows], span[1][rows]
    cnt = poly.count[rows]
    real = poly.real[rows]
    au = (poly.vx[rows] - cx[:, None]) * (1 / sx[:, None])
    av = (poly.vy[rows] - cy[:, None]) * (1 / sy[:, None])
    angle = np.where(real, diamond(au, av), np.inf)
    order = np.argsort(angle, axis=1)
    angle = np.take_along_axis(angle, order, axis=1)
    au = np.take_along_axis(au, order, axis=1)
    av = np.take_along_axis(av, order, axis=1)
    col = np.arange(width)[None, :]
    nxt = np.where(col + 1 < cnt[:, None], col + 1, 0)
    # outward normal of each edge (not normalised) and its offset from c
    nu = np.take_along_axis(av, nxt, axis=1) - av
    nv = au - np.take_along_axis(au, nxt, axis=1)
    offset = au * nu + av * nv
    # the edge each sector bound crosses: bound j belongs to the last vertex at or
    # before it (wrapping round to the last vertex)
    first_bound = np.clip(np.ceil(angle * (buckets / 4)), 0, buckets).astype(np.int64)
    marks = np.zeros((k, buckets + 1), np.int64)
    rr, cc = np.nonzero(real)
    np.add.at(marks, (rr, first_bound[rr, cc]), 1)
    edge = np.cumsum(marks[:, :buckets], axis=1) - 1
    edge = np.where(edge < 0, (cnt - 1)[:, None], edge)
    faced = _edge_frames(poly, rows, order, angle, edge, buckets)
    # every edge line supports the polygon, so a ray leaves it at the nearest one; the
    # bound's own edge and both neighbours cover an assignment off by one at a vertex.
    # With the edges wrapped round (column c + 1 holds edge c, column 0 the last one),
    # the edges at shifts -1, 0, +1 are columns edge + 0, 1, 2.
    ray_u, ray_v = _rays(buckets)
    ext = np.arange(width + 2)[None, :] - 1
    ext = np.where(ext < 0, (cnt - 1)[:, None], ext % cnt[:, None])
    wrap = [np.take_along_axis(a, ext, axis=1).ravel() for a in (nu, nv, offset)]
    flat = (np.arange(k) * (width + 2))[:, None] + edge
    reach = np.full((k, buckets), np.inf)
    for shift in range(3):
        eu, ev, eo = (a[shift:].take(flat) for a in wrap)
        across = eu * ray_u
        across += ev * ray_v
        hit = np.divide(eo, across, out=np.full_like(across, np.inf), where=across > 0)
        np.minimum(reach, hit, out=reach)
    # only for hulls whose edges all keep clear of c (in normalised units): then a
    # ray grazing a vertex meets the neighbouring edge right there, never far away
    clear = np.where(real, offset / np.hypot(nu, nv), np.inf).min(axis=1) >= _CLEAR
    reach = np.where(clear[:, None] & np.isfinite(reach), reach, 0.0) * (1 - _SHRINK)
    # chords between consecutive bounds (pulled inwards by the shrink)
    px = reach * ray_u
    py = reach * ray_v
    qx = np.roll(px, -1, axis=1)
    qy = np.roll(py, -1, axis=1)
    tx = qy - py
    ty = px - qx
    level = tx * px + ty * py
    usable = (reach > 0) & (np.roll(reach, -1, axis=1) > 0) & np.isfinite(level)
    chords = (
        np.where(usable, tx, 0.0),
        np.where(usable, ty, 0.0),
        np.where(usable, level, -np.inf),
    )
    return chords, faced


def _edge_frames(
    poly: _Polygons,
    rows: IntArray,
    order: IntArray,
    angle: FloatArray,
    edge: IntArray,
    buckets: int,
) -> tuple[IntArray, Frames]:
    """``(which, frames)``: the rows (positions in ``rows``) with an edge of a frame, and
    for each and each sector, the frame (:func:`edge_frames`) of the one edge the whole
    sector faces, if any (kind 0 otherwise), ``(len(which), buckets)`` each.

    Sector ``j`` faces edge ``e`` when no vertex's (diamond) angle lies within ``_MARGIN``
    of the sector (``edge`` names the edge crossing each sector's first bound). A sample
    the table places in sector ``j`` then lies, whatever the rounding of its angle, on a
    ray from the centre (strictly inside) that leaves the hull through ``e``, strictly
    between ``e``'s ends: on ``e``'s inner side or on its line (an orientation of at least
    zero, the hull being counter-clockwise), it is in the closed hull and none of its
    vertices, so no vertex of any later hull. Samples of exact relations crowd such
    edges, and the table's chords, drawn a little inside, leave them all.
    """
    width = angle.shape[1]
    vx = np.take_along_axis(poly.vx[rows], order, axis=1)
    vy = np.take_along_axis(poly.vy[rows], order, axis=1)
    real = np.isfinite(angle)
    cnt = real.sum(axis=1)
    col = np.arange(width)[None, :]
    nxt = np.where(col + 1 < cnt[:, None], col + 1, 0)
    wx = np.take_along_axis(vx, nxt, axis=1)
    wy = np.take_along_axis(vy, nxt, axis=1)
    kind, *rest = edge_frames(vx, vy, wx, wy)
    kind = np.where(real, kind, 0).astype(np.int8)
    # most hulls of noisy data have no edge of a simple slope: nothing to do for them
    which = np.flatnonzero(kind.any(axis=1))
    k = len(which)
    kind, angle, edge, real = kind[which], angle[which], edge[which], real[which]
    rest = [part[which] for part in rest]
    with np.errstate(all="ignore"):
        # sectors with a vertex within the margin of them: j in [A - 1 - m, A + m]
        scaled = np.where(real, angle, 0.0) * (buckets / 4)
        lowest = np.ceil(scaled - 1 - _MARGIN).astype(np.int64)
        highest = np.floor(scaled + _MARGIN).astype(np.int64)
    near = np.zeros((k, buckets), bool)
    rr, cc = np.nonzero(real)
    for step in range(3):
        sector = lowest[rr, cc] + step
        hit = sector <= highest[rr, cc]
        near[rr[hit], sector[hit] % buckets] = True
    facing = edge.astype(np.int64)
    faced_kind = np.where(near, 0, np.take_along_axis(kind, facing, axis=1)).astype(np.int8)
    return which, (  # type: ignore[return-value]
        faced_kind,
        *(np.take_along_axis(part, facing, axis=1) for part in rest),
    )


def diamond(u: FloatArray, v: FloatArray) -> FloatArray:
    """The "diamond angle" of ``(u, v)`` in ``[0, 4)``: monotone in the angle, no trig."""
    with np.errstate(all="ignore"):
        p = v / (np.abs(u) + np.abs(v))
        out: FloatArray = np.where(u >= 0, np.where(p >= 0, p, 4 + p), 2 - p)
    return out


def _buckets(npairs: int) -> int:
    """A power of two, at most ``BUCKETS``, at least 16, within the ``_TABLE`` budget."""
    size = BUCKETS
    while size > 16 and _CELL * size * npairs > _TABLE:
        size //= 2
    return size


@functools.cache
def _rays(buckets: int) -> tuple[FloatArray, FloatArray]:
    """Directions of the sector bounds: the "diamond angle" ``4 * j / buckets``."""
    d = 4.0 * np.arange(buckets) / buckets
    quarter = np.floor(d)
    f = d - quarter
    u = np.select([quarter == 0, quarter == 1, quarter == 2], [1 - f, -f, f - 1], f)
    v = np.select([quarter == 0, quarter == 1, quarter == 2], [f, 1 - f, -f], f - 1)
    return u, v


def _valid(box: FloatArray, ok: BoolArray) -> FloatArray:
    """``box`` where it is a proper box of a guided pair, else empty."""
    good = ok & np.isfinite(box).all(axis=0) & (box[0] <= box[1]) & (box[2] <= box[3])
    out: FloatArray = box.copy()
    out[0::2, ~good] = np.inf
    out[1::2, ~good] = -np.inf
    return out


def _roll_real(values: FloatArray, count: IntArray) -> FloatArray:
    """Shift each row's first ``count`` entries so that the reversed padding comes last."""
    width = values.shape[1]
    col = np.arange(width)[None, :]
    source = (col + (width - count)[:, None]) % width
    return np.take_along_axis(values, source, axis=1)
