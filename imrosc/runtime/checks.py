"""The value checks of one program point, compiled into a few vectorised operations.

Every invariant over a point's values (Daikon's families, polygons, and the bounds of the
time-related families, which are checked on the window values the engine computes) is
grouped with its kind into arrays: bounds as ``lo``/``hi`` vectors, relations as index
pairs, linear and ternary relations as coefficient vectors, polygons as stacked
half-planes ``A x <= b``. Checking a sample costs a handful of numpy operations whatever
the number of invariants; the violations are built only when one of them fails.

A missing value (NaN) breaks nothing: inference skipped it too. Every check reads its
invariant the way inference built it, so the samples an invariant was inferred from never
violate it: linear and ternary relations allow their stated tolerance plus the rounding
of evaluating ``a*x + b`` in float64, array averages and deviations a few ulps (the
monitor's summation order may differ from the translator's).
"""

from __future__ import annotations

from typing import Any, Callable, Dict, FrozenSet, List, Mapping, Sequence, Set, Tuple

import numpy as np

from imrosc.runtime.violation import Violation, show

_ULPS = 8 * 2.0**-52
_STAT_SLACK = 1e-12
"""Relative allowance on bounds of array averages and deviations."""

Found = List[Violation]


def _ints(values: Sequence[Any]) -> Any:
    return np.asarray(values, dtype=np.int64)


def _floats(values: Sequence[Any]) -> Any:
    return np.asarray(values, dtype=np.float64)


def _number(value: Any) -> float:
    if isinstance(value, str):
        return float(value)  # "inf", "-inf", "nan" in the JSON file
    return float(value)


class Checks:
    """The compiled value checks of one point.

    ``invariants`` are the file's invariant objects of this point (any family; the ones
    this class does not check are ignored), ``index`` maps a numeric variable to its
    position in the sample vector, ``strings`` a string variable to its position in the
    list of string values. Derived window values are checked by :meth:`check_windows`.
    """

    def __init__(
        self,
        invariants: Sequence[Mapping[str, Any]],
        index: Mapping[str, int],
        strings: Mapping[str, int],
        stats: Sequence[str] = (),
    ) -> None:
        self.index = index
        self.string_index = strings
        self.cleared: Set[str] = set()
        bounds: List[Tuple[int, float, float, Mapping[str, Any]]] = []
        one_of: List[Tuple[int, List[float], Mapping[str, Any]]] = []
        nonzero: List[Tuple[int, Mapping[str, Any]]] = []
        pairs: Dict[str, List[Tuple[int, int, Mapping[str, Any]]]] = {"==": [], "<": [], "<=": []}
        linear: List[Tuple[Tuple[int, ...], Tuple[float, ...], float, Mapping[str, Any]]] = []
        edges: List[Tuple[int, int, float, float, float, int]] = []
        self.polygons: List[Mapping[str, Any]] = []
        self.string_sets: List[Tuple[int, FrozenSet[str], Mapping[str, Any]]] = []
        slack = set(stats)
        for inv in invariants:
            family, kind, names, params = (
                inv["family"],
                inv["kind"],
                inv["variables"],
                inv["params"],
            )
            if family in ("bounds", "array") and names[0] in index:
                lo = _number(params.get("min", "-inf"))
                hi = _number(params.get("max", "inf"))
                if names[0] in slack:
                    lo -= abs(lo) * _STAT_SLACK
                    hi += abs(hi) * _STAT_SLACK
                bounds.append((index[names[0]], lo, hi, inv))
            elif family == "one-of" and names[0] in index:
                one_of.append((index[names[0]], [_number(v) for v in params["values"]], inv))
            elif family == "non-zero" and names[0] in index:
                nonzero.append((index[names[0]], inv))
            elif family in ("equality", "order") and all(n in index for n in names):
                for other in names[1:]:
                    pairs[kind].append((index[names[0]], index[other], inv))
            elif family in ("linear", "ternary") and all(n in index for n in names):
                coefficients = (
                    (params["a"], params["b"])
                    if family == "linear"
                    else (params["a"], params["b"], params["c"])
                )
                linear.append(
                    (
                        tuple(index[n] for n in names),
                        tuple(float(c) for c in coefficients),
                        float(params["tolerance"]),
                        inv,
                    )
                )
            elif family == "polygon" and all(n in index for n in names):
                owner = len(self.polygons)
                self.polygons.append(inv)
                for (a, b), c in zip(params["A"], params["b"]):
                    edges.append((index[names[0]], index[names[1]], a, b, c, owner))
            elif family == "string-one-of" and names[0] in strings:
                self.string_sets.append((strings[names[0]], frozenset(params["values"]), inv))
        self._compile(bounds, one_of, nonzero, pairs, linear, edges)

    def _compile(
        self,
        bounds: List[Tuple[int, float, float, Mapping[str, Any]]],
        one_of: List[Tuple[int, List[float], Mapping[str, Any]]],
        nonzero: List[Tuple[int, Mapping[str, Any]]],
        pairs: Dict[str, List[Tuple[int, int, Mapping[str, Any]]]],
        linear: List[Tuple[Tuple[int, ...], Tuple[float, ...], float, Mapping[str, Any]]],
        edges: List[Tuple[int, int, float, float, float, int]],
    ) -> None:
        self.bounds_at = _ints([b[0] for b in bounds])
        self.bounds_lo = _floats([b[1] for b in bounds])
        self.bounds_hi = _floats([b[2] for b in bounds])
        self.bounds_inv = [b[3] for b in bounds]
        self.one_of_at = _ints([o[0] for o in one_of])
        table = np.full((len(one_of), max([len(o[1]) for o in one_of] + [1])), np.nan)
        for row, (_, values, _) in enumerate(one_of):
            table[row, : len(values)] = values
        self.one_of_values = table
        self.one_of_inv = [o[2] for o in one_of]
        self.nonzero_at = _ints([n[0] for n in nonzero])
        self.nonzero_inv = [n[1] for n in nonzero]
        self.pairs = {
            kind: (
                _ints([p[0] for p in found]),
                _ints([p[1] for p in found]),
                [p[2] for p in found],
            )
            for kind, found in pairs.items()
            if found
        }
        self.linear: Dict[int, Tuple[Any, Any, Any, List[Mapping[str, Any]]]] = {}
        for arity in (2, 3):
            chosen = [item for item in linear if len(item[0]) == arity]
            if chosen:
                self.linear[arity] = (
                    _ints([item[0] for item in chosen]).reshape(len(chosen), arity),
                    _floats([item[1] for item in chosen]).reshape(len(chosen), arity),
                    _floats([item[2] for item in chosen]),
                    [item[3] for item in chosen],
                )
        self.edge_x = _ints([e[0] for e in edges])
        self.edge_y = _ints([e[1] for e in edges])
        self.edge_a = _floats([e[2] for e in edges])
        self.edge_b = _floats([e[3] for e in edges])
        self.edge_c = _floats([e[4] for e in edges])
        self.edge_owner = _ints([e[5] for e in edges])

    @property
    def size(self) -> int:
        """How many invariants these checks hold."""
        return (
            len(self.bounds_inv)
            + len(self.one_of_inv)
            + len(self.nonzero_inv)
            + sum(len(set(map(id, p[2]))) for p in self.pairs.values())
            + sum(len(v[3]) for v in self.linear.values())
            + len(self.polygons)
            + len(self.string_sets)
        )

    def check(self, time: float, point: str, row: Any, strings: Sequence[Any] = ()) -> Found:
        """The violations of one sample (``row``: float64 values in ``index`` order)."""
        found: Found = []
        if len(self.bounds_at):
            x = row[self.bounds_at]
            bad = (x < self.bounds_lo) | (x > self.bounds_hi)
            if bad.any():
                for k in np.flatnonzero(bad).tolist():
                    inv = self.bounds_inv[k]
                    expected = (
                        f"[{show(float(self.bounds_lo[k]))}, {show(float(self.bounds_hi[k]))}]"
                    )
                    found.append(_violation(time, point, inv, float(x[k]), expected))
        if len(self.one_of_at):
            x = row[self.one_of_at]
            bad = ~(x[:, None] == self.one_of_values).any(axis=1) & ~np.isnan(x)
            if bad.any():
                for k in np.flatnonzero(bad).tolist():
                    inv = self.one_of_inv[k]
                    expected = "one of " + show(set(inv["params"]["values"]))
                    found.append(_violation(time, point, inv, float(x[k]), expected))
        if len(self.nonzero_at):
            bad = row[self.nonzero_at] == 0
            if bad.any():
                for k in np.flatnonzero(bad).tolist():
                    found.append(_violation(time, point, self.nonzero_inv[k], 0.0, "!= 0"))
        for kind, (first, second, invs) in self.pairs.items():
            x, y = row[first], row[second]
            if kind == "==":
                bad = (x != y) & ~np.isnan(x) & ~np.isnan(y)
            elif kind == "<":
                bad = x >= y
            else:
                bad = x > y
            if bad.any():
                for k in np.flatnonzero(bad).tolist():
                    observed = (float(x[k]), float(y[k]))
                    found.append(_violation(time, point, invs[k], observed, kind))
        for at, coefficients, tolerance, invs in self.linear.values():
            values = row[at]
            with np.errstate(all="ignore"):
                terms = values[:, 1:] * coefficients[:, :-1]
                fitted = terms.sum(axis=1) + coefficients[:, -1]
                size = np.abs(terms).sum(axis=1) + np.abs(coefficients[:, -1])
                allowed = tolerance + _ULPS * (size + np.abs(values[:, 0]))
                bad = np.abs(values[:, 0] - fitted) > allowed
            if bad.any():
                for k in np.flatnonzero(bad).tolist():
                    seen = tuple(float(v) for v in values[k])
                    expected = f"within {show(float(tolerance[k]))} of the relation"
                    found.append(_violation(time, point, invs[k], seen, expected))
        if len(self.edge_x):
            with np.errstate(all="ignore"):
                reach = self.edge_a * row[self.edge_x] + self.edge_b * row[self.edge_y]
            bad = reach > self.edge_c
            if bad.any():
                owners = sorted(set(self.edge_owner[bad].tolist()))
                for owner in owners:
                    inv = self.polygons[owner]
                    x, y = inv["variables"]
                    observed = (float(row[self.index[x]]), float(row[self.index[y]]))
                    found.append(_violation(time, point, inv, observed, "inside the polygon"))
        for at, values, inv in self.string_sets:
            value = strings[at]
            if value not in values:
                expected = "one of " + ", ".join(sorted(f'"{v}"' for v in values))
                found.append(_violation(time, point, inv, value, expected))
        if found and self.cleared:
            found = [v for v in found if v.invariant not in self.cleared]
        return found


def _violation(
    time: float, point: str, inv: Mapping[str, Any], observed: Any, expected: str
) -> Violation:
    return Violation(
        time, point, inv["id"], inv["family"], inv["kind"], inv["text"], observed, expected
    )


class WindowChecks:
    """The bounds of a point's frequency, variance and rate invariants."""

    def __init__(self, invariants: Sequence[Mapping[str, Any]], tracked: Sequence[str]) -> None:
        position = {name: k for k, name in enumerate(tracked)}
        self.frequency: List[Mapping[str, Any]] = []
        self.per_variable: Dict[str, List[Tuple[int, Mapping[str, Any]]]] = {
            "variance": [],
            "rate": [],
        }
        self.window = 0.0
        for inv in invariants:
            family = inv["family"]
            if family == "frequency":
                self.frequency.append(inv)
            elif family in self.per_variable and inv["variables"][0] in position:
                self.per_variable[family].append((position[inv["variables"][0]], inv))
            else:
                continue
            self.window = float(inv["params"]["window"])
        self.arrays: Dict[str, Tuple[Any, Any, Any, List[Mapping[str, Any]]]] = {}
        for family, found in self.per_variable.items():
            if found:
                self.arrays[family] = (
                    _ints([f[0] for f in found]),
                    _floats([_number(f[1]["params"]["min"]) for f in found]),
                    _floats([_number(f[1]["params"]["max"]) for f in found]),
                    [f[1] for f in found],
                )

    @property
    def active(self) -> bool:
        """Whether the point has any time-related invariant."""
        return bool(self.frequency or self.arrays)

    def check(
        self,
        time: float,
        point: str,
        frequency: float,
        derived: Callable[[str], Any],
        cleared: Any,
    ) -> Found:
        """Violations of one defined window; ``derived(family)`` gives its values."""
        found: Found = []
        for inv in self.frequency:
            lo, hi = _number(inv["params"]["min"]), _number(inv["params"]["max"])
            if (frequency < lo or frequency > hi) and inv["id"] not in cleared:
                expected = f"[{show(lo)}, {show(hi)}] Hz"
                found.append(_violation(time, point, inv, frequency, expected))
        for family, (at, lo, hi, invs) in self.arrays.items():
            values = derived(family)[at]
            bad = (values < lo) | (values > hi)
            if bad.any():
                for k in np.flatnonzero(bad).tolist():
                    inv = invs[k]
                    if inv["id"] in cleared:
                        continue
                    expected = f"[{show(float(lo[k]))}, {show(float(hi[k]))}]"
                    found.append(_violation(time, point, inv, float(values[k]), expected))
        return found
