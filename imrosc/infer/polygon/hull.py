"""Exact convex hulls of many small point groups at once.

A *group set* is four flat arrays ``(group, x, y, at)`` sorted by ``group``: the points of
every group (a variable pair) one after the other, ``at`` the point's first-occurrence
position in its group's sample sequence. :func:`hulls` returns the strict vertices of each
group's convex hull (collinear points on an edge and repeated points are not vertices),
counter-clockwise from the lexicographically smallest one, each with the smallest ``at``
among the points at that place. The vertex set is a function of the point *set*, so
``hull(A | B) == hull(hull(A) | hull(B))`` exactly: this is what makes the polygon family's
states mergeable bit for bit.

Method: a level-synchronous quickhull across all groups (every round splits every open
edge at its farthest outside point; exact orientation decides what is outside, so it only
ever discards points inside a triangle of data points). The farthest point is found in
floating point; where another point might be as far (within the rounding bound), or where
a distance overflowed (coordinates near 1e300), the pick may not be a vertex, and such
groups are settled by Andrew's monotone chain, run in lock-step across groups on the few
points quickhull kept.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from imrosc.infer.core import FloatArray
from imrosc.infer.polygon.predicates import orientation, turn

IntArray = npt.NDArray[np.int64]
_BIG = np.iinfo(np.int64).max
_ERR = 8 * 2.0**-53
_TINY = 2.0**-900


@dataclass
class GroupSet:
    """Points of many groups, sorted by group."""

    group: IntArray
    x: FloatArray
    y: FloatArray
    at: IntArray

    def __len__(self) -> int:
        return len(self.group)

    @staticmethod
    def empty() -> GroupSet:
        """No points."""
        return GroupSet(np.empty(0, np.int64), np.empty(0), np.empty(0), np.empty(0, np.int64))

    def take(self, index: IntArray) -> GroupSet:
        """The points at ``index`` (which keeps the group order if sorted)."""
        return GroupSet(self.group[index], self.x[index], self.y[index], self.at[index])

    @staticmethod
    def concat(parts: list[GroupSet]) -> GroupSet:
        """All points of ``parts``, re-sorted by group (stable: order within a group kept)."""
        parts = [p for p in parts if len(p)]
        if not parts:
            return GroupSet.empty()
        group = np.concatenate([p.group for p in parts])
        order = np.argsort(group, kind="stable")
        return GroupSet(
            group[order],
            np.concatenate([p.x for p in parts])[order],
            np.concatenate([p.y for p in parts])[order],
            np.concatenate([p.at for p in parts])[order],
        )

    def bounds(self) -> tuple[IntArray, IntArray, IntArray]:
        """``(groups, starts, ends)`` of the non-empty groups."""
        if not len(self):
            e = np.empty(0, np.int64)
            return e, e, e
        change = np.flatnonzero(np.diff(self.group)) + 1
        starts = np.concatenate([[0], change]).astype(np.int64)
        ends = np.concatenate([change, [len(self)]]).astype(np.int64)
        return self.group[starts], starts, ends


def _segments(keys: IntArray) -> tuple[IntArray, IntArray]:
    """Starts of the runs of equal ``keys`` and, per element, its run number."""
    change = np.flatnonzero(np.diff(keys)) + 1
    starts = np.concatenate([[0], change]).astype(np.int64)
    run = np.zeros(len(keys), np.int64)
    run[change] = 1
    return starts, np.cumsum(run)


def _lex_extreme(pts: GroupSet, starts: IntArray, run: IntArray, largest: bool) -> IntArray:
    """Index of each group's lexicographic min (or max) point, smallest ``at`` on ties."""
    sign = -1.0 if largest else 1.0
    x = pts.x * sign
    y = pts.y * sign
    bx = np.minimum.reduceat(x, starts)
    on = x == bx[run]
    by = np.minimum.reduceat(np.where(on, y, np.inf), starts)
    on &= y == by[run]
    best = np.minimum.reduceat(np.where(on, pts.at, _BIG), starts)
    on &= pts.at == best[run]
    position = np.arange(len(pts), dtype=np.int64)
    return np.minimum.reduceat(np.where(on, position, _BIG), starts)


def _quickhull(pts: GroupSet) -> tuple[GroupSet, IntArray, IntArray]:
    """Quickhull: each group's extreme points, in chain order where that is certain.

    Returns the points found, their place in the counter-clockwise order (0: the
    lexicographic minimum, 1: the lower chain, 2: the maximum, 3: the upper chain) and the
    groups that must be settled by the monotone chain: where a split point was picked
    among (nearly) equally far candidates, it may not be a vertex after all.
    """
    if not len(pts):
        e = np.empty(0, np.int64)
        return pts, e, e
    starts, run = _segments(pts.group)
    lo = _lex_extreme(pts, starts, run, largest=False)
    hi = _lex_extreme(pts, starts, run, largest=True)
    distinct = (pts.x[hi] != pts.x[lo]) | (pts.y[hi] != pts.y[lo])
    keep = [lo, hi[distinct]]
    stages = [np.zeros(len(lo), np.int64), np.full(int(distinct.sum()), 2, np.int64)]
    suspect = np.zeros(int(pts.group.max()) + 1, bool)
    # initial edges per group: lo -> hi (points right of it) and hi -> lo
    ax, ay = pts.x[lo][run], pts.y[lo][run]
    bx, by = pts.x[hi][run], pts.y[hi][run]
    side = orientation(ax, ay, bx, by, pts.x, pts.y)
    below = side < 0
    above = side > 0
    sel = np.flatnonzero(below | above)
    key = np.where(below, 2 * run, 2 * run + 1)[sel]
    chain = np.where(below, 1, 3)[sel]
    # per point: its edge's start (s) and end (e)
    sx = np.where(below, ax, bx)[sel]
    sy = np.where(below, ay, by)[sel]
    ex = np.where(below, bx, ax)[sel]
    ey = np.where(below, by, ay)[sel]
    px, py, pat, pgroup = pts.x[sel], pts.y[sel], pts.at[sel], pts.group[sel]
    found: list[GroupSet] = []
    found_stage: list[IntArray] = []
    while len(key):
        order = np.argsort(key, kind="stable")
        key, pat, pgroup, chain = (
            key.take(order),
            pat.take(order),
            pgroup.take(order),
            chain.take(order),
        )
        sx, sy, ex, ey = sx.take(order), sy.take(order), ex.take(order), ey.take(order)
        px, py = px.take(order), py.take(order)
        seg, seg_run = _segments(key)
        with np.errstate(all="ignore"):
            t1 = (sy - py) * (ex - px)
            t2 = (sx - px) * (ey - py)
            dist = t1 - t2
            err = _ERR * (np.abs(t1) + np.abs(t2))
        # a distance that overflowed says nothing: its segment picks among the rest (or
        # any point) and its group is settled by the monotone chain
        lost = ~np.isfinite(dist) | ~np.isfinite(err)
        if lost.any():
            suspect[pgroup[lost]] = True
            dist = np.where(lost, -np.inf, dist)
            err = np.where(lost, 0.0, err)
        far = np.maximum.reduceat(dist, seg)
        top = dist == far[seg_run]
        best = np.minimum.reduceat(np.where(top, pat, _BIG), seg)
        top &= pat == best[seg_run]
        pick = np.minimum.reduceat(np.where(top, np.arange(len(pat)), _BIG), seg)
        cx, cy = px.take(pick), py.take(pick)
        qx, qy = cx.take(seg_run), cy.take(seg_run)
        # could another point be at least as far? then the pick may be no vertex
        other = (px != qx) | (py != qy)
        rival = np.maximum.reduceat(np.where(other, dist + err, -np.inf), seg)
        suspect[pgroup[pick][(rival >= far - err[pick]) | (far < _TINY)]] = True
        found.append(GroupSet(pgroup[pick], cx, cy, pat[pick]))
        found_stage.append(chain[pick])
        first = orientation(sx, sy, qx, qy, px, py) < 0
        rest = np.flatnonzero(~first)
        second = np.zeros(len(px), bool)
        if len(rest):
            second[rest] = (
                orientation(qx[rest], qy[rest], ex[rest], ey[rest], px[rest], py[rest]) < 0
            )
        live = np.flatnonzero(first | second)
        f = first.take(live)
        key = 2 * seg_run.take(live) + np.where(f, 0, 1)
        sx, sy, ex, ey = sx.take(live), sy.take(live), ex.take(live), ey.take(live)
        qx, qy = qx.take(live), qy.take(live)
        sx, sy, ex, ey = (
            np.where(f, sx, qx),
            np.where(f, sy, qy),
            np.where(f, qx, ex),
            np.where(f, qy, ey),
        )
        px, py, pat, pgroup = px.take(live), py.take(live), pat.take(live), pgroup.take(live)
        chain = chain.take(live)
    out = [pts.take(np.concatenate(keep)), *found]
    stage = np.concatenate(stages + found_stage)
    merged = GroupSet(
        np.concatenate([g.group for g in out]),
        np.concatenate([g.x for g in out]),
        np.concatenate([g.y for g in out]),
        np.concatenate([g.at for g in out]),
    )
    return merged, stage, np.flatnonzero(suspect).astype(np.int64)


def _chain(pts: GroupSet) -> GroupSet:
    """Monotone chain in lock-step; ``pts`` must hold no repeated point within a group.

    Up to ``_CHAIN_ONE_BY_ONE`` points go group by group in Python (:func:`_chains`)."""
    if not len(pts):
        return pts
    order = np.lexsort((pts.y, pts.x, pts.group))
    pts = pts.take(order.astype(np.int64))
    if len(pts) <= _CHAIN_ONE_BY_ONE:
        return pts.take(_chains(pts))
    groups, starts, ends = pts.bounds()
    count = ends - starts
    width = int(count.max())
    ng = len(groups)
    halves: list[tuple[IntArray, IntArray]] = []
    for reverse in (False, True):
        stack = np.zeros((ng, width), np.int64)
        size = np.zeros(ng, np.int64)
        for k in range(width):
            act = np.flatnonzero(count > k)
            q = (ends[act] - 1 - k) if reverse else (starts[act] + k)
            cur, cq = act, q
            while len(cur):
                ok = size[cur] >= 2
                cur, cq = cur[ok], cq[ok]
                if not len(cur):
                    break
                p1 = stack[cur, size[cur] - 2]
                p2 = stack[cur, size[cur] - 1]
                turn = orientation(pts.x[p1], pts.y[p1], pts.x[p2], pts.y[p2], pts.x[cq], pts.y[cq])
                pop = turn <= 0
                cur, cq = cur[pop], cq[pop]
                size[cur] -= 1
            stack[act, size[act]] = q
            size[act] += 1
        halves.append((stack, size))
    (lower, nl), (upper, nu) = halves
    single = count == 1
    take_l = np.where(single, 1, nl - 1)
    take_u = np.where(single, 0, nu - 1)
    total = take_l + take_u
    out = np.empty(int(total.sum()), np.int64)
    offsets = np.concatenate([[0], np.cumsum(total)[:-1]])
    # ragged copy: per group, lower[:take_l] then upper[:take_u]
    rows_l = np.repeat(np.arange(ng), take_l)
    cols_l = np.arange(len(rows_l)) - np.repeat(np.cumsum(take_l) - take_l, take_l)
    out[np.repeat(offsets, take_l) + cols_l] = lower[rows_l, cols_l]
    rows_u = np.repeat(np.arange(ng), take_u)
    cols_u = np.arange(len(rows_u)) - np.repeat(np.cumsum(take_u) - take_u, take_u)
    out[np.repeat(offsets + take_l, take_u) + cols_u] = upper[rows_u, cols_u]
    return pts.take(out)


_CHAIN_ONE_BY_ONE = 8192
"""Points settled by the monotone chain below which it runs group by group in Python: a
few hundred points of a few dozen groups (the usual doubtful groups) cost a lock-step's
thousands of numpy calls on arrays of a few dozen elements."""


def _chains(pts: GroupSet) -> IntArray:
    """:func:`_chain` on points sorted by group, ``x`` and ``y``, group by group: the rows
    of the vertices, the same exact turns (:func:`~imrosc.infer.polygon.predicates.turn`)."""
    out: list[int] = []
    xs, ys = pts.x.tolist(), pts.y.tolist()
    _, starts, ends = pts.bounds()
    for first, stop in zip(starts.tolist(), ends.tolist(), strict=True):
        if stop - first == 1:
            out.append(first)
            continue
        for rows in (range(first, stop), range(stop - 1, first - 1, -1)):
            stack: list[int] = []
            for q in rows:
                qx, qy = xs[q], ys[q]
                while len(stack) >= 2:
                    p1, p2 = stack[-2], stack[-1]
                    if turn(xs[p1], ys[p1], xs[p2], ys[p2], qx, qy) > 0:
                        break
                    stack.pop()
                stack.append(q)
            out.extend(stack[:-1])
    return np.array(out, np.int64)


def hulls(pts: GroupSet) -> GroupSet:
    """The strict hull vertices of every group, counter-clockwise from the lexicographic
    minimum, each carrying the smallest ``at`` of the points at its place."""
    found, stage, suspect = _quickhull(pts)
    if not len(found):
        return found
    doubt = np.zeros(int(found.group.max()) + 1, bool)
    doubt[suspect] = True
    unsure = doubt[found.group]
    sure = np.flatnonzero(~unsure)
    # certain groups: order by chain, the lower one left to right, the upper right to left
    flip = stage[sure] == 3
    kx = np.where(flip, -found.x[sure], found.x[sure])
    ky = np.where(flip, -found.y[sure], found.y[sure])
    order = sure[np.lexsort((ky, kx, stage[sure], found.group[sure]))]
    settled = _chain(found.take(np.flatnonzero(unsure)))
    return GroupSet.concat([found.take(order), settled])
