"""Envelopes learnt from a subset of the units, widened by their tolerances.

:class:`Envelopes` reads, once, every limit of the merged invariants and its support in
each unit; :meth:`Envelopes.document` then gives the invariants document learnt from any
subset of the units: the whole set for the file ``imrosc infer`` writes, all units but a
fold's for the held-out replays that set the alarm rule.
"""

from __future__ import annotations

import math
import pickle
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from imrosc.calibrate.limits import (
    MARGINED,
    SETS,
    WIDENED,
    Slot,
    from_scale,
    members,
    merge_sets,
    number,
    polygon_supports,
    raw,
    set_broken,
    slots,
    support,
    to_scale,
    widened,
    with_value,
)
from imrosc.calibrate.text import retext
from imrosc.calibrate.tolerance import maxima_bound, prediction_bound, tolerances, too_many
from imrosc.infer.core import Invariant
from imrosc.infer.engine import Unit
from imrosc.invariants import invariant_id
from imrosc.runtime.families import ARRAY, BOUNDS, INTERVAL, ONE_OF, PATTERN, POLYGON, STEP

Key = tuple[Any, ...]


def key_of(point: str, family: str, variables: Sequence[str], ident: str) -> Key:
    """How a unit's invariant is matched with the merged one: its id for ordered pairs and
    patterns (their variables say nothing), else point, family and variables (so a bound
    that is only an upper bound in one unit still gives its support)."""
    if family in (INTERVAL, PATTERN):
        return (ident,)
    return (point, family, tuple(variables))


@dataclass
class UnitView:
    """One unit's invariants, by :func:`key_of`, and its numeric one-of sets (a variable
    constant in a short unit is a one-of there, not a bound)."""

    params: dict[Key, Mapping[str, Any]] = field(default_factory=dict)
    one_of: dict[tuple[str, str], list[float]] = field(default_factory=dict)

    @classmethod
    def of(cls, unit: Unit) -> UnitView:
        view = cls()
        for invariant in unit.invariants:
            view.add(invariant)
        return view

    def add(self, invariant: Invariant) -> None:
        ident = invariant_id(invariant)
        key = key_of(invariant.point, invariant.family, invariant.variables, ident)
        self.params[key] = invariant.params
        if invariant.family == ONE_OF and len(invariant.variables) == 1:
            values = [v for v in invariant.params.get("values", ()) if isinstance(v, int | float)]
            if values:
                self.one_of[(invariant.point, invariant.variables[0])] = [float(v) for v in values]

    def lookup(self, invariant: Mapping[str, Any]) -> Mapping[str, Any] | None:
        """This unit's params of the merged ``invariant`` (``None``: it has none). A unit
        without the polygon (too few points there to justify one) gives the corners of its
        two variables' ranges: its points reach no further along any direction."""
        found = self.params.get(_key(invariant))
        if found is not None:
            return found
        family, point, variables = invariant["family"], invariant["point"], invariant["variables"]
        if family in (BOUNDS, ARRAY):
            return self.range_of(point, variables[0], family)
        if family == POLYGON and len(variables) == 2:
            x, y = (self.range_of(point, v, BOUNDS) for v in variables)
            if x is not None and y is not None:
                corners = [[a, b] for a in (x["min"], x["max"]) for b in (y["min"], y["max"])]
                return {"vertices": corners}
        return None

    def range_of(self, point: str, variable: str, family: str) -> dict[str, float] | None:
        """The unit's range of a variable: its two-sided bounds, or its one-of values."""
        bounds = self.params.get((point, family, (variable,)))
        if bounds is not None and "min" in bounds and "max" in bounds:
            return {"min": float(bounds["min"]), "max": float(bounds["max"])}
        values = self.one_of.get((point, variable))
        return None if values is None else {"min": min(values), "max": max(values)}


def _key(invariant: Mapping[str, Any]) -> Key:
    return key_of(invariant["point"], invariant["family"], invariant["variables"], invariant["id"])


@dataclass
class _Limits:
    """An invariant's limits: their slots, their values in the merged invariant (in each
    slot's space) and their supports in each unit."""

    slots: list[Slot]
    bases: list[float | None]
    supports: np.ndarray
    """``(limits, units)``: how far each unit reaches along each limit (0 where unknown)."""
    known: np.ndarray
    """``(limits, units)``: whether the unit says anything about the limit."""
    reached: list[bool]
    """Per unit, whether it says anything about any of the limits."""

    @classmethod
    def of(cls, invariant: Mapping[str, Any], found: Sequence[Mapping[str, Any] | None]) -> _Limits:
        """The limits of ``invariant`` given each unit's params of it (``found``)."""
        params = invariant["params"]
        limits = slots(invariant)
        rows: list[list[float | None]]
        if invariant["family"] == POLYGON:
            normals = [params["A"][k] for k in range(len(limits))]  # b's half-planes
            per_unit = [polygon_supports(normals, unit) if normals else None for unit in found]
            rows = [[None if s is None else s[k] for s in per_unit] for k in range(len(limits))]
        else:
            rows = [[support(params, unit, slot) for unit in found] for slot in limits]
        known = np.array([[s is not None for s in row] for row in rows], dtype=bool)
        values = [[0.0 if s is None else s for s in row] for row in rows]
        known = known.reshape(len(limits), len(found))
        reached = [bool(r) for r in np.asarray(known.any(axis=0))]
        return cls(
            limits,
            [to_scale(raw(params, slot), slot) for slot in limits],
            np.array(values, dtype=np.float64).reshape(len(limits), len(found)),
            known,
            reached,
        )


class Envelopes:
    """The limits and sets of a document's invariants, and their supports per unit."""

    def __init__(
        self,
        document: Mapping[str, Any],
        views: Sequence[UnitView],
        budget: float,
        *,
        margins: bool = False,
        step_tail: str = "select",
    ) -> None:
        self.source = document
        self.margins = margins
        """Whether the ranges of one scalar get margins (:meth:`margin`)."""
        self.step_tail = step_tail
        """How a step's margin models the units' largest steps (:meth:`margin`)."""
        self.types, self.integer = _types(document)
        self.budget = budget
        self.count = len(views)
        self.limits: dict[str, _Limits] = {}
        self.drop: set[str] = set()
        self.widened: dict[str, int] = {}
        self.dropped: dict[str, int] = {}
        """Sets that held-out units break, per family."""
        self.unsupported: dict[str, int] = {}
        """Invariants fewer than two units support, per family."""
        self.sets: dict[str, list[frozenset[Any] | None]] = {}
        """Per invariant of a set family, the set each unit holds (``None``: not there)."""
        self.family: dict[str, str] = {}
        """Per widened invariant, its family."""
        for invariant in document["invariants"]:
            family = invariant["family"]
            if family not in WIDENED and family not in SETS:
                continue
            self.family[invariant["id"]] = family
            found = [view.lookup(invariant) for view in views]
            if sum(params is not None for params in found) < 2:
                self._drop(invariant, self.unsupported)
                continue
            if family in SETS:
                self.sets[invariant["id"]] = [
                    None if params is None else members({"family": family, "params": params})
                    for params in found
                ]
            if family in WIDENED:
                self.limits[invariant["id"]] = _Limits.of(invariant, found)
            elif self._unstable(invariant, found):
                self._drop(invariant, self.dropped)
        self.margined = sum(
            1 if self.family[ident] == STEP else len(limits.slots)
            for ident, limits in self.limits.items()
            if ident not in self.drop and self.family.get(ident) in MARGINED
        )
        """The limits with margins in the file (``L``: each margin's level is
        ``budget / 4 / L``, a union bound over them)."""

    @property
    def severe_level(self) -> float:
        """The level of each margin: the severe alarms' quarter of the budget shared among
        the file's limits with margins."""
        return self.budget / 4 / max(1, self.margined)

    def untested(self, units: set[int]) -> set[str]:
        """The invariants about which a unit outside ``units``, replayed against the
        document learnt from ``units``, says nothing: that document holds them only as
        learnt from every unit (the held-out unit included). They are the invariants
        calibration neither widens nor treats as sets (relations), and those no unit of
        ``units`` holds. (A set that some unit of ``units`` holds is tested by
        :meth:`set_breaks`.)"""
        found: set[str] = set()
        for invariant in self.source["invariants"]:
            ident = invariant["id"]
            if ident in self.drop:
                continue
            limits, sets = self.limits.get(ident), self.sets.get(ident)
            if sets is not None:
                if all(sets[u] is None for u in units):
                    found.add(ident)
            elif limits is None or not any(limits.reached[u] for u in units):
                found.add(ident)
        return found

    def set_breaks(self, unit: int, units: set[int]) -> set[str]:
        """The sets that ``unit`` breaks when they are learnt from ``units`` alone."""
        found: set[str] = set()
        for invariant in self.source["invariants"]:
            held = self.sets.get(invariant["id"])
            if held is None or invariant["id"] in self.drop:
                continue
            mine = held[unit]
            others = [their for u in sorted(units) if (their := held[u]) is not None]
            if (
                mine is not None
                and others
                and set_broken(invariant, mine, merge_sets(invariant, others))
            ):
                found.add(invariant["id"])
        return found

    def _drop(self, invariant: Mapping[str, Any], counts: dict[str, int]) -> None:
        self.drop.add(invariant["id"])
        counts[invariant["family"]] = counts.get(invariant["family"], 0) + 1

    def _unstable(
        self, invariant: Mapping[str, Any], found: Sequence[Mapping[str, Any] | None]
    ) -> bool:
        """Whether more held-out units break the set learnt from the other units than
        the budget explains."""
        sets = []
        for params in found:
            if params is not None:
                held = members({"family": invariant["family"], "params": params})
                if held is not None:
                    sets.append(held)
        if len(sets) < 2:
            return False
        breaks = sum(
            set_broken(invariant, held, merge_sets(invariant, sets[:k] + sets[k + 1 :]))
            for k, held in enumerate(sets)
        )
        return too_many(breaks, len(sets), self.budget)

    def document(self, units: set[int], *, final: bool = False) -> dict[str, Any]:
        """The invariants document learnt from ``units``: the merged envelope with the
        final tolerances (``final``), or each limit from those units' supports alone."""
        source = dict(self.source)
        source["invariants"] = [i for i in source["invariants"] if i["id"] not in self.drop]
        out: dict[str, Any] = _copy(source)
        chosen = _indexes(units)
        for invariant in out["invariants"]:
            limits = self.limits.get(invariant["id"])
            if limits is not None and limits.slots:
                integer = invariant["id"] in self.integer
                if self._widen(invariant, limits, chosen, final, integer):
                    retext(invariant, self.types)
                    if final:
                        family = invariant["family"]
                        self.widened[family] = self.widened.get(family, 0) + 1
                if self.margins and invariant["family"] in MARGINED:
                    margin = self.margin(limits, chosen, invariant["family"] == STEP)
                    if margin:
                        invariant["params"] = dict(invariant["params"], margin=margin)
        return out

    def margin(
        self, limits: _Limits, chosen: np.ndarray, shared: bool = False
    ) -> dict[str, list[float]]:
        """Per limit (``max``, ``min``) of a range of one scalar, its margin from the
        ``chosen`` units' supports: ``[centre, limit]``, raw values, the centre the mean of
        the units' extremes, the limit the prediction bound of one more unit's extreme at
        :attr:`severe_level` (in the limit's scale: the logarithm for a variance). A limit
        the units all reach alike (no spread), or fewer than two of them, has none.

        ``shared`` (a step): both limits share one margin, that of the units' largest
        step either way (a jump has no preferred direction). A run's largest step is a
        positive maximum whose spread is multiplicative where jumps are part of normal
        operation (a waypoint switch moves a track error by whatever the geometry gives)
        and additive where steps are sensor noise. Its limit is the bound of the model,
        Gumbel (the law of a maximum of noise, :mod:`.extremes`) or log-normal, that
        predicts the units' largest steps held out in turn the better (:attr:`step_tail`
        ``select``, the default; :func:`.tolerance.maxima_bound`): far narrower than the
        log-normal bound where the units' steps are alike, yet with the exponential tail of
        a maximum, beyond the normal bound; or, with ``larger``, the larger of the normal
        and the log-normal bounds, which reaches as far as a log-normal tail does."""
        found: dict[str, list[float]] = {}
        level = self.severe_level
        supports, known = limits.supports[:, chosen], limits.known[:, chosen]
        if shared and len(limits.slots) == 2:
            both = np.where(known, supports, -np.inf).max(axis=0)
            seen = known.any(axis=0)
            supports = np.vstack([both, both])
            known = np.vstack([seen, seen])
        for slot, row, mask in zip(limits.slots, supports, known, strict=True):
            held = row[mask].tolist()
            if len(held) < 2 or not all(map(math.isfinite, held)):
                continue
            centre = math.fsum(held) / len(held)
            if shared:
                bound = maxima_bound(held, level, select=self.step_tail == "select")
            else:
                bound = prediction_bound(held, level)
            if bound is None or not bound > centre or not math.isfinite(bound):
                continue
            try:
                pair = [from_scale(centre, slot), from_scale(bound, slot)]
            except OverflowError:  # a variance's limit past any float: no margin
                continue
            if all(map(math.isfinite, pair)) and pair[0] != pair[1]:
                found[slot.param] = pair
        return found

    def _widen(
        self,
        invariant: dict[str, Any],
        limits: _Limits,
        chosen: np.ndarray,
        final: bool,
        integer: bool,
    ) -> bool:
        params = dict(invariant["params"])
        moved = False
        supports, known = limits.supports[:, chosen], limits.known[:, chosen]
        # the supports of the units that have one, in the units' order
        held = [row[mask].tolist() for row, mask in zip(supports, known, strict=True)]
        bases = [
            max(row) if not final and row and all(map(math.isfinite, row)) else base
            for row, base in zip(held, limits.bases, strict=True)
        ]
        alpha = self.budget / len(limits.slots)
        counted = [slot.quantum if slot.scale == "count" else 0.0 for slot in limits.slots]
        tols = tolerances(held, bases, alpha, counted)
        if invariant["family"] == POLYGON:
            return self._widen_polygon(invariant, params, bases, tols, final)
        for slot, base, found in zip(limits.slots, bases, tols, strict=True):
            if base is None:
                continue
            tol = 0.0 if found is None else found  # None: one unit alone reaches this limit
            if tol == 0 and final and slot.scale != "count":
                continue  # the envelope as inferred, to the last bit
            value = widened(base, tol, slot)
            if value != raw(params, slot):
                if integer:  # integer variables' bounds stay integers, rounded outward
                    value = float(math.ceil(value) if slot.upper else math.floor(value))
                with_value(params, slot, value)
                moved = True
        invariant["params"] = params
        return moved

    @staticmethod
    def _widen_polygon(
        invariant: dict[str, Any],
        params: dict[str, Any],
        bases: Sequence[float | None],
        tols: Sequence[float | None],
        final: bool,
    ) -> bool:
        """:meth:`_widen`'s loop for a polygon, whose limits are its offsets ``b``: upper
        limits in the values' own scale, moved in one copy of ``b``."""
        offsets = list(params["b"])
        moved = False
        for k, (base, tol) in enumerate(zip(bases, tols, strict=True)):
            if base is None:
                continue
            if not tol and final:
                continue  # the envelope as inferred, to the last bit
            value = base + (tol or 0.0)  # widened() of an upper additive limit
            if value != number(offsets[k]):
                offsets[k] = value
                moved = True
        if moved:
            params["b"] = offsets
            params["vertices"] = vertices(params["A"], offsets, params["vertices"])
        invariant["params"] = params
        return moved


@dataclass(frozen=True)
class FoldDocument:
    """The document learnt from ``units`` alone (:meth:`Envelopes.document`), built where
    it is replayed: in the process (or on the Dask worker) that replays its fold, so that
    the folds' documents are built in parallel and only the envelopes, once, cross to the
    workers."""

    envelopes: Envelopes
    units: frozenset[int]

    def build(self) -> dict[str, Any]:
        return self.envelopes.document(set(self.units))


def _indexes(units: set[int]) -> np.ndarray:
    """The units' indexes in increasing order, to pick their columns of a limit's supports."""
    return np.array(sorted(units), dtype=np.intp)


def _copy(document: dict[str, Any]) -> dict[str, Any]:
    """A deep copy of an invariants document (a tree of dicts, lists and numbers), through
    pickle: several times faster than ``copy.deepcopy`` on thousands of polygons."""
    found: dict[str, Any] = pickle.loads(pickle.dumps(document, pickle.HIGHEST_PROTOCOL))
    return found


def _types(document: Mapping[str, Any]) -> tuple[dict[tuple[str, str], str], set[str]]:
    """Each point's variables' types, and the ids of the bounds of integer variables."""
    types = {}
    for key, point in document["points"].items():
        for variable in point.get("variables", ()):
            types[(key, variable["name"])] = variable["type"]
    integer = {
        invariant["id"]
        for invariant in document["invariants"]
        if invariant["family"] == BOUNDS
        and invariant["variables"]
        and types.get((invariant["point"], invariant["variables"][0])) in ("int", "uint")
    }
    return types, integer


def vertices(
    normals: Sequence[Sequence[float]], offsets: Sequence[float], inside: Sequence[Any]
) -> list[list[float]]:
    """The vertices of ``{x: A x <= b}``, counter-clockwise from the lexicographic minimum
    (as inference gives them), a polygon that contains the points ``inside`` (the vertices
    before widening)."""
    from scipy.spatial import ConvexHull, HalfspaceIntersection, QhullError

    points = np.asarray(inside, dtype=np.float64).reshape(-1, 2)
    a = np.asarray(normals, dtype=np.float64).reshape(-1, 2)
    b = np.asarray(offsets, dtype=np.float64)
    if len(points) < 3 or len(a) < 3:
        return [list(map(float, p)) for p in points]
    centre = points.mean(axis=0)
    try:
        crossing = HalfspaceIntersection(np.column_stack([a, -b]), centre).intersections
        hull = ConvexHull(crossing)
    except (QhullError, ValueError):
        return [list(map(float, p)) for p in points]
    ring = crossing[hull.vertices]  # counter-clockwise
    first = min(range(len(ring)), key=lambda k: (ring[k][0], ring[k][1]))
    return [[float(x), float(y)] for x, y in np.roll(ring, -first, axis=0)]
