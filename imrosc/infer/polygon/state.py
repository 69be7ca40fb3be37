"""The polygon family (thesis 3.4.2, Algorithms 5, 6 and 10): a convex hull per variable pair.

State per pair: the strict vertices of the convex hull of every sample seen so far (exact
predicates; collinear points on edges are not vertices), each with the position of its
first occurrence among the pair's samples, and the number of samples. Samples where either
variable is NaN or infinite are skipped. Because the vertex set is a function of the point
set, folding chunks, re-chunking and merging states of runs processed apart all give the
same vertices bit for bit; the first occurrences are bookkept the same way, so the samples
since the hull last changed are exact too (the hull last changed at the first occurrence
of its latest final vertex).

Finalize (Algorithm 10 plus the confidence rule of section 3.5): a pair yields a polygon
when its hull has at least 3 vertices and a non-negligible area (``area / box_area >
1e-9``; thinner hulls are lines, which the linear family covers), when ``area / box_area``
does not exceed ``drop_ratio`` (independent variables fill their bounding box, and the
bounds family already says as much), and when ``1 - 2**-n`` exceeds the confidence limit,
``n`` being the samples since the hull last changed.
"""

from __future__ import annotations

import threading
import weakref
from collections.abc import Collection, Sequence
from typing import Any

import numpy as np
import numpy.typing as npt

from imrosc.infer.builders import States, builds
from imrosc.infer.core import FinalizeContext, FloatArray, Invariant, Samples, Variable, confidence
from imrosc.infer.polygon.candidates import Chunk, candidates, expanding, heads, seeds
from imrosc.infer.polygon.guide import Guide
from imrosc.infer.polygon.hull import GroupSet, IntArray, hulls
from imrosc.infer.polygon.locate import Locator
from imrosc.infer.polygon.text import polygon_text
from imrosc.ir import Tunables
from imrosc.runtime.families import POLYGON
from imrosc.translate.points import PointSpec

_REFRESH_AT = 512
"""A guide letting more candidates than this through is rebuilt from the new hull."""
_STALE = 8
"""A guide is rebuilt after its hull changed this many times."""
_EXTREMES = 16
"""Rows of each variable's least and greatest values that seed a pair without a hull."""
_HEAD = 512
"""Rows per block whose extremes give a pair whose guide fits badly a head start."""

_LOCATE_AT = 4096
"""Candidates of a chunk beyond which those in their current hull are located and dropped."""
_LOCATE_BLOCK = 1 << 17
"""Candidates located together (bounds the temporaries of exact location)."""

THIN_RATIO = 1e-9
"""Hulls whose area is at most this fraction of their bounding box are lines, not polygons."""

_UNIT = 2.0**-53

BATCH_VALUES = 1 << 22
"""Values (rows x variables, 32 MiB of float64) of chunks a state holds back and folds at
once. Folding has a cost per fold besides the one per row: every pair whose hull a chunk
touches is hulled again with all its current vertices, its guide rebuilt, its plan costed,
so chunks of a few thousand rows (a bag's, or a condition's share of one) pay it over and
over. The bound keeps the fold's temporaries, which grow with its rows, to some hundred MB.
It holds for the process: a state whose update finds the values held back by all polygon
states (a bag's points, conditions and time segments each have one) past its ``batch`` folds
its own, so they stay within about the bound plus a chunk."""

_HELD: weakref.WeakKeyDictionary[PolygonState, int] = weakref.WeakKeyDictionary()
"""Values each polygon state of the process holds back (a state that is gone holds none)."""
_HELD_LOCK = threading.Lock()
"""Guards :data:`_HELD`: a Dask worker with several threads infers bags side by side."""


def polygon_variables(variables: Sequence[Variable]) -> tuple[Variable, ...]:
    """Numeric, non-derived variables, the trigger topic's and the input topics' alike.

    Time-typed variables (stamps) are left out: their hull spans the recording's clock.
    """
    return tuple(v for v in variables if v.numeric and v.derived is None and v.type != "time")


def half_planes(vertices: FloatArray) -> tuple[FloatArray, FloatArray, FloatArray]:
    """``(A, b, tight)`` with ``A @ p <= b`` for every point of the hull of
    counter-clockwise ``vertices``, one row per edge, each row scaled so its larger
    coefficient is +-1.

    ``b`` includes a margin of ``2**-50 * (|a| max|x| + |b| max|y|)``, more than the
    rounding of ``a * x + b * y`` for any point of the hull, so every sample passes the
    float64 check with no further tolerance; ``tight`` is ``b`` without it.
    """
    nxt = np.roll(vertices, -1, axis=0)
    a = nxt[:, 1] - vertices[:, 1]
    b = vertices[:, 0] - nxt[:, 0]
    scale = np.maximum(np.abs(a), np.abs(b))
    a = a / scale
    b = b / scale
    reach = a[:, None] * vertices[None, :, 0] + b[:, None] * vertices[None, :, 1]
    top = reach.max(axis=1)
    magnitude = np.abs(a) * np.abs(vertices[:, 0]).max() + np.abs(b) * np.abs(vertices[:, 1]).max()
    return np.stack([a, b], axis=1), top + 8 * _UNIT * magnitude, top


def _all_half_planes(
    hull: GroupSet, starts: IntArray, ends: IntArray
) -> tuple[FloatArray, FloatArray, FloatArray]:
    """:func:`half_planes` of the hulls at ``[starts, ends)`` at once, the same arithmetic
    element by element: ``(a, b, offsets)`` per edge, the hulls' edges one after the
    other (edge ``k`` of a hull leaves its vertex ``k``)."""
    count = ends - starts
    first = np.cumsum(count) - count  # each hull's first edge
    poly = np.repeat(np.arange(len(count)), count)
    vertex = starts[poly] + np.arange(len(poly)) - first[poly]
    vx, vy = hull.x[vertex], hull.y[vertex]
    nxt = np.arange(1, len(poly) + 1)
    nxt[first + count - 1] = first
    a = vy[nxt] - vy
    b = vx - vx[nxt]
    scale = np.maximum(np.abs(a), np.abs(b))
    a = a / scale
    b = b / scale
    # every edge against every vertex of its hull
    size = count[poly]
    edge = np.repeat(np.arange(len(poly)), size)
    other = (
        np.repeat(first[poly], size)
        + np.arange(len(edge))
        - np.repeat(np.cumsum(size) - size, size)
    )
    reach = a[edge] * vx[other] + b[edge] * vy[other]
    top = np.maximum.reduceat(reach, np.cumsum(size) - size)
    wide = np.maximum.reduceat(np.abs(vx), first)[poly]
    tall = np.maximum.reduceat(np.abs(vy), first)[poly]
    magnitude = np.abs(a) * wide + np.abs(b) * tall
    return a, b, top + 8 * _UNIT * magnitude


def _changed(before: GroupSet, after: GroupSet, groups: IntArray) -> IntArray:
    """Which of ``groups`` have other vertices in ``after`` than in ``before``."""
    if not len(groups):
        return groups
    size = int(groups.max()) + 1
    differ = np.bincount(before.group, minlength=size) != np.bincount(after.group, minlength=size)
    # groups of equal size line up row for row (both sets are sorted by group)
    rb = np.flatnonzero(~differ[before.group])
    ra = np.flatnonzero(~differ[after.group])
    mismatch = (
        (before.x[rb] != after.x[ra])
        | (before.y[rb] != after.y[ra])
        | (before.at[rb] != after.at[ra])
    )
    differ[after.group[ra][mismatch]] = True
    changed: IntArray = groups[differ[groups]]
    return changed


class PolygonState:
    """Convex hulls of every pair of a point's numeric variables."""

    family = POLYGON

    def __init__(self, variables: Sequence[Variable], batch: int = BATCH_VALUES) -> None:
        self.variables = tuple(variables)
        # pending values (rows x variables) at which held-back chunks are folded (0: each
        # chunk as it comes)
        self.batch = batch
        self._pending: list[FloatArray] = []
        self._pending_values = 0
        self.names = tuple(v.name for v in self.variables)
        self.discrete = tuple(v.type in ("int", "uint", "bool") for v in self.variables)
        first, second = np.triu_indices(len(self.names), 1)
        self.pi: IntArray = first.astype(np.int64)
        self.pj: IntArray = second.astype(np.int64)
        self._count: IntArray = np.zeros(len(self.pi), np.int64)
        self._hull = GroupSet.empty()
        self._guide: Guide | None = Guide(len(self.pi))
        self.stale = np.zeros(len(self.pi), np.int64)

    @property
    def hull(self) -> GroupSet:
        """Every pair's strict hull vertices, the held-back chunks folded in first."""
        self._flush()
        return self._hull

    @property
    def count(self) -> IntArray:
        """Per pair, the samples seen (where both variables are present)."""
        self._flush()
        return self._count

    @property
    def guide(self) -> Guide:
        """The filters of the current hulls, rebuilt from them after a copy."""
        self._flush()  # a no-op within a fold: the pending chunks went before it began
        if self._guide is None:
            self._guide = Guide(len(self.pi))
            drawn = np.unique(self._hull.group)
            self._guide.refresh(self._hull, drawn)
            self.stale[drawn] = 0
        return self._guide

    def freeze(self) -> None:
        """No samples will come before it is finalized (it may still absorb merges): the
        guide goes, and merges no longer refresh it."""
        self._flush()
        self._guide = None

    def __getstate__(self) -> dict[str, Any]:
        """The hulls and their support without the guide, a cache many times their size:
        a state sent from a worker (or copied) is merged and finalized, which needs none."""
        self._flush()
        state = dict(self.__dict__)
        state["_guide"] = None
        return state

    def _matrix(self, samples: Samples) -> FloatArray:
        values = np.empty((len(self.names), len(samples)))
        for k, name in enumerate(self.names):
            values[k] = samples.column(name)
        values[~np.isfinite(values)] = np.nan
        return values

    def _absorb(self, extra: GroupSet, added: IntArray, refresh: bool = False) -> None:
        """Fold ``extra`` (``at`` relative to the old counts) into the hulls (``refresh``:
        rebuild the guide of every pair whose hull changed)."""
        if len(extra):
            extra.at = extra.at + self._count[extra.group]
            touched = np.zeros(len(self.pi), bool)
            touched[extra.group] = True
            mine = touched[self._hull.group]
            before = self._hull.take(np.flatnonzero(mine))
            kept = self._hull.take(np.flatnonzero(~mine))
            fresh = hulls(GroupSet.concat([before, extra]))
            self._hull = GroupSet.concat([kept, fresh])
            if self._guide is not None:  # none after a copy: rebuilt if samples come again
                self._refresh(self._guide, before, fresh, touched, extra, refresh)
        self._count += added

    def _refresh(
        self,
        guide: Guide,
        before: GroupSet,
        fresh: GroupSet,
        touched: npt.NDArray[np.bool_],
        extra: GroupSet,
        refresh: bool,
    ) -> None:
        """A guide from an older hull stays valid (it lies inside the new one): refresh it
        only where asked, where it lets many samples through or has gone stale."""
        changed = _changed(before, fresh, np.flatnonzero(touched))
        self.stale[changed] += 1
        many = np.bincount(extra.group, minlength=len(self.pi)) > _REFRESH_AT
        redo = changed[
            many[changed] | ~guide.ok[changed] | (self.stale[changed] >= _STALE) | refresh
        ]
        guide.refresh(self._hull, redo)
        self.stale[redo] = 0

    def update(self, samples: Samples) -> None:
        """Take a chunk: held back until ``batch`` values are pending in this state and the
        process's other polygon states together, then folded with the others this state
        holds (:meth:`_fold`). The vertices are a function of the point set, so they do not
        depend on how the samples were grouped; anything that reads the state folds the
        pending chunks first."""
        if len(samples) == 0 or not len(self.pi):
            return
        values = self._matrix(samples)
        self._pending.append(values)
        self._pending_values += values.size
        with _HELD_LOCK:
            _HELD[self] = self._pending_values
            held = sum(_HELD.values())
        if held >= self.batch:
            self._flush()

    def _flush(self) -> None:
        """Fold the held-back chunks, as one."""
        if not self._pending:
            return
        values = self._pending[0] if len(self._pending) == 1 else np.concatenate(self._pending, 1)
        self._pending = []  # the parts go before the fold's temporaries come
        self._pending_values = 0
        with _HELD_LOCK:
            _HELD.pop(self, None)
        self._fold(values)

    def _fold(self, values: FloatArray) -> None:
        """Fold a chunk: prefilter, then the exact hull of the survivors and the vertices.

        Pairs whose guide fits the chunk badly (no hull yet, or a variable drifting into
        new ground) first absorb likely vertices: for pairs without a hull, the rows of
        each variable's extreme values and a sample; then, per block of 512 rows the guide
        cannot place inside, the rows of both variables' extremes in the block. That hull,
        inside the final one, refines their guide before the whole chunk is filtered.
        """
        chunk = Chunk(values, self.discrete)
        nothing = np.zeros(len(self.pi), np.int64)
        todo = expanding(chunk, self.pi, self.pj, self.guide)
        bare = todo & ~self.guide.ok & (self.guide.locator.slot < 0)  # no usable hull yet
        if bare.any():
            found = seeds(chunk, self.pi, self.pj, self.guide, bare, _EXTREMES)
            found.at = chunk.valid_rank(self.pi, self.pj, found.group, found.at)
            self._absorb(found, nothing)
            todo &= expanding(chunk, self.pi, self.pj, self.guide)
        if todo.any():
            found = heads(chunk, self.pi, self.pj, self.guide, todo, _HEAD)
            found.at = chunk.valid_rank(self.pi, self.pj, found.group, found.at)
            self._absorb(found, nothing, refresh=True)
        found = candidates(chunk, self.pi, self.pj, self.guide)
        found.at = chunk.valid_rank(self.pi, self.pj, found.group, found.at)
        self._absorb(self._uncovered(self._new_places(found)), chunk.valid_counts(self.pi, self.pj))

    def _uncovered(self, found: GroupSet) -> GroupSet:
        """``found`` without the samples located exactly in their pair's closed hull and
        none of its vertices: no vertex of any later hull. The guide only discards what lies
        strictly inside by a float margin, so samples on an edge (exact relations put many
        there: ``t = a - 2*m + 1``, ``ab = |n|``, ``mx = max(n1, n2)``) reach this; locating
        them here spares the hull computation rounds over them."""
        if len(found) < _LOCATE_AT:
            return found
        locator = Locator.build(self._hull, len(self.pi))
        keep = np.empty(len(found), bool)
        for first in range(0, len(found), _LOCATE_BLOCK):  # bounded temporaries
            part = slice(first, first + _LOCATE_BLOCK)
            keep[part] = ~locator.covered(found.group[part], found.x[part], found.y[part])
        return found.take(np.flatnonzero(keep))

    def _new_places(self, found: GroupSet) -> GroupSet:
        """``found`` (``at`` relative to the old counts) without the samples that already
        are vertices: the head start of a chunk puts its likely vertices in the hulls
        before the chunk is filtered, which finds those samples again. A sample that is a
        vertex with its ``at`` changes nothing; dropping it spares re-hulling every pair it
        alone touched. (Recent vertices are those with ``at`` at least the old count.)"""
        if not len(found) or not len(self._hull):
            return found
        base = self._count[self._hull.group]
        recent = np.flatnonzero(self._hull.at >= base)
        if not len(recent):
            return found
        width = int(max(found.at.max(), self._hull.at[recent].max() - base[recent].min())) + 1
        vertex = self._hull.group[recent] * width + (self._hull.at[recent] - base[recent])
        again = np.isin(found.group * width + found.at, vertex)
        return found.take(np.flatnonzero(~again))

    def end_run(self) -> None:
        """Hulls do not depend on runs; the held-back chunks are folded (a state at rest
        holds none)."""
        self._flush()

    def merge(self, other: Any) -> None:
        """Absorb a state whose runs all come after ours."""
        if not isinstance(other, PolygonState) or other.names != self.names:
            raise TypeError("can only merge polygon states of the same variables")
        self._flush()
        theirs = other.hull
        extra = GroupSet(theirs.group, theirs.x, theirs.y, theirs.at.copy())
        self._absorb(extra, other.count)

    def finalize(self, context: FinalizeContext) -> list[Invariant]:
        """The polygons that pass Algorithm 10 and the confidence rule."""
        found: list[Invariant] = []
        self._flush()
        groups, starts, ends = self._hull.bounds()
        if not len(groups):
            return found
        hull = self._hull
        nxt = np.arange(1, len(hull) + 1)
        nxt[ends - 1] = starts
        with np.errstate(all="ignore"):
            twice = np.add.reduceat(hull.x * hull.y[nxt] - hull.y * hull.x[nxt], starts)
            area = 0.5 * np.abs(twice)
            box_area = (
                np.maximum.reduceat(hull.x, starts) - np.minimum.reduceat(hull.x, starts)
            ) * (np.maximum.reduceat(hull.y, starts) - np.minimum.reduceat(hull.y, starts))
            ratio = area / box_area
        since = self._count[groups] - np.maximum.reduceat(hull.at, starts)
        keep = (ends - starts >= 3) & (area > 0) & (box_area > 0) & np.isfinite(ratio)
        keep &= (ratio > THIN_RATIO) & (ratio <= context.tunables.drop_ratio)
        chosen = [k for k in np.flatnonzero(keep).tolist() if context.justified(int(since[k]))]
        if not chosen:
            return found
        index = np.array(chosen, np.int64)
        planes = _all_half_planes(hull, starts[index], ends[index])
        a, b, offsets = (values.tolist() for values in planes)
        vx, vy = hull.x.tolist(), hull.y.tolist()
        edge = 0
        for k in chosen:
            n = int(since[k])
            group, lo, hi = int(groups[k]), int(starts[k]), int(ends[k])
            x = self.names[int(self.pi[group])]
            y = self.names[int(self.pj[group])]
            mine = slice(edge, edge + hi - lo)
            edge += hi - lo
            normals = [[ca, cb] for ca, cb in zip(a[mine], b[mine], strict=True)]
            vertices = [[px, py] for px, py in zip(vx[lo:hi], vy[lo:hi], strict=True)]
            found.append(
                Invariant(
                    family=self.family,
                    kind="hull",
                    point=context.point,
                    variables=(x, y),
                    params={
                        "x": x,
                        "y": y,
                        "vertices": vertices,
                        "A": normals,
                        "b": offsets[mine],
                        "area": float(area[k]),
                        "box_area": float(box_area[k]),
                        "ratio": float(ratio[k]),
                    },
                    text=polygon_text(x, y, vertices),
                    samples=int(self._count[group]),
                    confidence=confidence(n),
                    condition=context.condition,
                    runs=context.runs,
                )
            )
        return found


def make_states(
    variables: Sequence[Variable], tunables: Tunables, families: Collection[str]
) -> list[PolygonState]:
    """The polygon state of one point, if enabled and the point has two numeric variables."""
    del tunables  # the chunk size of Algorithm 6 does not change the (exact) result
    chosen = polygon_variables(variables)
    if POLYGON not in set(families) or len(chosen) < 2:
        return []
    return [PolygonState(chosen)]


@builds(POLYGON)
def _states(point: PointSpec, tunables: Tunables, enabled: frozenset[str]) -> States:
    return list(make_states(point.variables, tunables, enabled))
