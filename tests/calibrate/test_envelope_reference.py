"""The envelopes' documents against the former computation, kept here as the reference.

:class:`Envelopes` computes each unit's polygon supports in one product per (invariant,
unit), picks the supports of a subset of the units by column, computes the tolerances of a
polygon's limits together and copies the document through pickle. The former code took
each support alone (the unit's vertices converted again for every half-plane), each
tolerance alone and ``copy.deepcopy``: the documents must be the same to the byte.
"""

from __future__ import annotations

import copy
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
import pytest
from scipy.spatial import ConvexHull, QhullError

from imrosc.calibrate.envelope import Envelopes, UnitView, key_of, vertices
from imrosc.calibrate.limits import (
    WIDENED,
    Slot,
    polygon_supports,
    raw,
    slots,
    to_scale,
    widened,
    with_value,
)
from imrosc.calibrate.text import retext
from imrosc.calibrate.tolerance import _t_quantile, tolerance, tolerances
from imrosc.infer.polygon.text import polygon_text
from imrosc.invariants import dumps
from imrosc.runtime.families import POLYGON

# -- the former computation ---------------------------------------------------------------


def old_support(
    merged: Mapping[str, Any], unit: Mapping[str, Any] | None, slot: Slot
) -> float | None:
    if unit is None:
        return None
    if slot.param == "b":
        points = np.asarray(unit.get("vertices") or [], dtype=np.float64).reshape(-1, 2)
        if not len(points) or not isinstance(slot.index, int):
            return None
        normal = np.asarray(merged["A"][slot.index], dtype=np.float64)
        return float(np.max(points @ normal))
    return to_scale(raw(unit, slot), slot)


def old_prediction_bound(
    values: Sequence[float], alpha: float, resolution: float = 0.0
) -> float | None:
    n = len(values)
    if n < 2:
        return None
    mean = math.fsum(values) / n
    variance = math.fsum((v - mean) ** 2 for v in values) / (n - 1)
    sd = math.sqrt(variance + resolution * resolution / 12.0)
    if sd == 0:
        return mean
    return mean + _t_quantile(1 - alpha, n - 1) * sd * math.sqrt(1 + 1 / n)


def old_tolerance(
    supports: Sequence[float], base: float, alpha: float, resolution: float = 0.0
) -> float | None:
    finite = [v for v in supports if math.isfinite(v)]
    if not math.isfinite(base) or len(finite) < len(supports):
        return 0.0
    bound = old_prediction_bound(finite, alpha, resolution)
    if bound is None:
        return None
    return max(0.0, bound - max(base, *finite))


@dataclass
class OldLimit:
    slot: Slot
    base: float | None
    supports: list[float | None]


class Old:
    """The former limits, ``document`` and ``untested`` (the sets and what is dropped are
    unchanged: they are read from the new :class:`Envelopes`)."""

    def __init__(self, new: Envelopes, views: Sequence[UnitView]) -> None:
        self.new = new
        self.widened: dict[str, int] = {}
        self.limits: dict[str, list[OldLimit]] = {}
        for invariant in new.source["invariants"]:
            if invariant["family"] not in WIDENED or invariant["id"] in new.drop:
                continue
            found = [view.lookup(invariant) for view in views]
            self.limits[invariant["id"]] = [
                OldLimit(
                    slot,
                    to_scale(raw(invariant["params"], slot), slot),
                    [old_support(invariant["params"], unit, slot) for unit in found],
                )
                for slot in slots(invariant)
            ]

    def untested(self, units: set[int]) -> set[str]:
        found: set[str] = set()
        for invariant in self.new.source["invariants"]:
            ident = invariant["id"]
            if ident in self.new.drop:
                continue
            limits, sets = self.limits.get(ident), self.new.sets.get(ident)
            if sets is not None:
                if all(sets[u] is None for u in units):
                    found.add(ident)
            elif limits is None or all(lim.supports[u] is None for lim in limits for u in units):
                found.add(ident)
        return found

    def document(self, units: set[int], *, final: bool = False) -> dict[str, Any]:
        out = copy.deepcopy(dict(self.new.source))
        kept = []
        for invariant in out["invariants"]:
            if invariant["id"] in self.new.drop:
                continue
            limits = self.limits.get(invariant["id"])
            if limits:
                integer = invariant["id"] in self.new.integer
                if self._widen(invariant, limits, units, final, integer):
                    retext(invariant, self.new.types)
                    if final:
                        family = invariant["family"]
                        self.widened[family] = self.widened.get(family, 0) + 1
            kept.append(invariant)
        out["invariants"] = kept
        return out

    def _widen(
        self,
        invariant: dict[str, Any],
        limits: list[OldLimit],
        units: set[int],
        final: bool,
        integer: bool,
    ) -> bool:
        params = dict(invariant["params"])
        moved = False
        for limit in limits:
            known = [s for u, s in enumerate(limit.supports) if u in units and s is not None]
            base = limit.base
            if not final and known and all(math.isfinite(s) for s in known):
                base = max(known)
            if base is None:
                continue
            counted = limit.slot.quantum if limit.slot.scale == "count" else 0.0
            tol = old_tolerance(known, base, self.new.budget / len(limits), counted)
            if tol is None:
                tol = 0.0
            if tol == 0 and final and limit.slot.scale != "count":
                continue
            value = widened(base, tol, limit.slot)
            if value != raw(params, limit.slot):
                if integer:
                    value = float(math.ceil(value) if limit.slot.upper else math.floor(value))
                with_value(params, limit.slot, value)
                moved = True
        if moved and invariant["family"] == POLYGON:
            params["vertices"] = vertices(params["A"], params["b"], params["vertices"])
        invariant["params"] = params
        return moved


# -- random documents and units -----------------------------------------------------------


def ring(points: np.ndarray) -> list[list[float]] | None:
    """The hull's vertices, counter-clockwise from the lexicographic minimum."""
    try:
        hull = ConvexHull(points)
    except (QhullError, ValueError):
        return None
    found = points[hull.vertices]
    first = min(range(len(found)), key=lambda k: (found[k][0], found[k][1]))
    corners: list[list[float]] = np.roll(found, -first, axis=0).tolist()
    return corners


def draw(rng: np.random.Generator, count: int, scale: float) -> list[np.ndarray]:
    """Each unit's samples of four variables (some integer-valued: ties, exact halves)."""
    found = []
    for _ in range(count):
        size = int(rng.choice([1, 2, 3, 6, 20, 60]))
        centre = rng.normal(0.0, 1.0, 4) * scale
        samples = rng.normal(centre, scale * rng.uniform(0.1, 2.0), size=(size, 4))
        if rng.random() < 0.25:
            samples = np.round(samples * 2) / 2
        found.append(samples)
    return found


def case(seed: int) -> tuple[dict[str, Any], list[UnitView], float]:
    """A random invariants document and its units: polygons (some units without theirs,
    some with one or two vertices), bounds of float and integer variables (some units with
    an upper bound only), variances (zero floors), frequencies, an ordered pair's interval
    and a one-of."""
    rng = np.random.default_rng(seed)
    count = int(rng.integers(2, 10))
    scale = float(10.0 ** rng.integers(-3, 5))
    samples = draw(rng, count, scale)
    names = ["a0", "a1", "a2", "n"]
    kinds = ["float", "float", "float", "int"]
    samples = [np.column_stack([s[:, :3], np.round(s[:, 3])]) for s in samples]
    views = [UnitView() for _ in range(count)]
    invariants: list[dict[str, Any]] = []
    params: dict[str, Any]
    own: dict[str, Any]

    def add(family: str, kind: str, variables: list[str], params: dict[str, Any], text: str) -> str:
        ident = f"{family}-{len(invariants)}"
        invariants.append(
            {
                "id": ident,
                "point": "p",
                "family": family,
                "kind": kind,
                "variables": variables,
                "params": params,
                "text": text,
            }
        )
        return ident

    everything = np.vstack(samples)
    for column, name in enumerate(names):
        low, high = float(everything[:, column].min()), float(everything[:, column].max())
        add("bounds", "range", [name], {"min": low, "max": high}, f"{low} <= {name} <= {high}")
        for view, unit in zip(views, samples, strict=True):
            if rng.random() < 0.8:
                values = unit[:, column]
                params = {"min": float(values.min()), "max": float(values.max())}
                if rng.random() < 0.15:  # only an upper bound here: its limits differ in units
                    del params["min"]
                view.params[key_of("p", "bounds", [name], "")] = params
            elif rng.random() < 0.5:
                view.one_of[("p", name)] = sorted({float(v) for v in unit[:, column][:3]})
    for x, y in ((0, 1), (1, 2), (0, 2)):
        merged = ring(everything[:, [x, y]])
        if merged is None:
            continue
        hull = ConvexHull(everything[:, [x, y]])
        normals = hull.equations[:, :2]
        extra = rng.normal(0.0, 1.0, (int(rng.integers(0, 3)), 2))  # redundant half-planes
        normals = np.vstack([normals, extra / np.linalg.norm(extra, axis=1)[:, None]])
        offsets = (everything[:, [x, y]] @ normals.T).max(axis=0)
        variables = [names[x], names[y]]
        params = {
            "x": variables[0],
            "y": variables[1],
            "A": normals.tolist(),
            "b": offsets.tolist(),
            "vertices": merged,
        }
        add(POLYGON, "hull", variables, params, polygon_text(variables[0], variables[1], merged))
        for view, unit in zip(views, samples, strict=True):
            roll = rng.random()
            if roll < 0.6:
                hull_ring = ring(unit[:, [x, y]])
                if hull_ring is not None:
                    view.params[key_of("p", POLYGON, variables, "")] = {"vertices": hull_ring}
            elif roll < 0.8:  # one or two vertices: a matrix-vector product of 1 or 2 rows
                corners = unit[: int(rng.integers(1, 3)), [x, y]].tolist()
                view.params[key_of("p", POLYGON, variables, "")] = {"vertices": corners}
    for name in names[:2]:
        params = {"min": float(rng.uniform(0.0, 1.0)) * scale, "max": float(rng.uniform(1, 3))}
        ident = add("variance", "range", [name], params, f"0 <= var({name}) <= 1")
        for view in views:
            if rng.random() < 0.9:
                low = 0.0 if rng.random() < 0.15 else float(rng.uniform(0.0, 1.0)) * scale
                own = {"min": low, "max": float(rng.uniform(1, 3))}
                view.params[key_of("p", "variance", [name], ident)] = own
    window = float(rng.choice([0.5, 1.0, 2.0]))
    params = {"min": 18.0, "max": 22.0, "window": window}
    ident = add("frequency", "range", ["/t"], params, "18 <= freq(/t) <= 22")
    for view in views:
        own = {"min": float(rng.integers(16, 20)), "max": float(rng.integers(20, 24))}
        view.params[key_of("p", "frequency", ["/t"], ident)] = {**own, "window": window}
    params = {
        "first": "a",
        "second": "b",
        "min_time": 0.1,
        "max_time": 0.9,
        "min_events": {"c": 1},
        "max_events": {"c": 4},
    }
    ident = add("interval", "interval", ["a", "b"], params, "a -> b")
    for view in views:
        own = {
            "min_time": float(rng.uniform(0.05, 0.3)),
            "max_time": float(rng.uniform(0.5, 1.2)),
            "min_events": {"c": int(rng.integers(0, 3))},
            "max_events": {"c": int(rng.integers(2, 6))},
        }
        if rng.random() < 0.2:
            own["max_events"] = {}  # no count of c: no support of its upper limit
        view.params[key_of("p", "interval", ["a", "b"], ident)] = own
    ident = add("one-of", "values", ["n"], {"values": [0, 1, 2]}, "n one of {0, 1, 2}")
    for view in views:
        own = {"values": [int(v) for v in rng.choice(4, size=2)]}
        view.params[key_of("p", "one-of", ["n"], ident)] = own
    points = {
        "p": {"variables": [{"name": n, "type": t} for n, t in zip(names, kinds, strict=True)]}
    }
    document = {"project": "t", "points": points, "invariants": invariants}
    return document, views, float(rng.choice([0.01, 0.05, 0.2]))


@pytest.mark.parametrize("seed", range(40))
def test_documents_are_the_former_computations_to_the_byte(seed: int) -> None:
    document, views, budget = case(seed)
    new = Envelopes(document, views, budget)
    old = Old(new, views)
    everyone = set(range(len(views)))
    rng = np.random.default_rng(1000 + seed)
    subsets: list[set[int]] = [set(), {0}, everyone - {0}]
    subsets += [{u for u in everyone if rng.random() < 0.6} for _ in range(4)]
    assert dumps(new.document(everyone, final=True)) == dumps(old.document(everyone, final=True))
    assert new.widened == old.widened
    for units in subsets:
        assert dumps(new.document(units)) == dumps(old.document(units)), sorted(units)
        assert new.untested(units) == old.untested(units)
    assert dumps(new.source) == dumps(document)  # the source is left as it was


def test_a_polygons_supports_are_each_normals_alone_to_the_bit() -> None:
    rng = np.random.default_rng(7)
    for _ in range(3000):
        size = int(rng.integers(1, 30))
        points = rng.normal(0.0, 1.0, (size, 2)) * 10.0 ** rng.integers(-4, 7)
        if rng.random() < 0.3:
            points = np.round(points * 4) / 4
        normals = rng.normal(0.0, 1.0, (int(rng.integers(1, 25)), 2)).tolist()
        merged = {"A": normals}
        unit = {"vertices": points.tolist()}
        expected = [
            old_support(merged, unit, Slot("b", k, True, "add")) for k in range(len(normals))
        ]
        assert polygon_supports(normals, unit) == expected
    assert polygon_supports([[1.0, 0.0]], {"vertices": []}) is None
    assert polygon_supports([[1.0, 0.0]], None) is None


def test_tolerances_together_are_each_alone_to_the_bit() -> None:
    rng = np.random.default_rng(11)
    for _ in range(2000):
        rows, units = int(rng.integers(1, 6)), int(rng.integers(0, 12))
        supports = rng.normal(0.0, 1.0, (rows, units)) * 10.0 ** rng.integers(-3, 5)
        if rng.random() < 0.3:
            supports = np.round(supports * 2) / 2  # ties, zero spreads, exact halves
        if rng.random() < 0.2 and units:
            supports[int(rng.integers(rows)), int(rng.integers(units))] = rng.choice(
                [np.inf, -np.inf, np.nan]
            )
        bases: list[float | None] = [
            None
            if rng.random() < 0.1
            else float(rng.choice([np.inf, rng.normal()]))
            if rng.random() < 0.1
            else float(rng.normal())
            for _ in range(rows)
        ]
        resolutions = [float(rng.choice([0.0, 0.5, 1.0])) for _ in range(rows)]
        alpha = float(rng.choice([0.01, 0.05, 0.2]))
        expected = [
            None if base is None else old_tolerance(row, base, alpha, resolution)
            for row, base, resolution in zip(supports.tolist(), bases, resolutions, strict=True)
        ]
        got = tolerances(supports.tolist(), bases, alpha, resolutions)
        assert [repr(v) for v in got] == [repr(v) for v in expected]
        alone = [
            None if base is None else tolerance(row, base, alpha, resolution)
            for row, base, resolution in zip(supports.tolist(), bases, resolutions, strict=True)
        ]
        assert [repr(v) for v in alone] == [repr(v) for v in expected]
