"""The value checks of one program point, compiled into a few vectorised operations.

Every invariant over a point's values (Daikon's families, polygons, and the bounds of the
time-related families, which are checked on the window values the engine computes) is
grouped with its kind into arrays: bounds as ``lo``/``hi`` vectors, relations as index
pairs, linear and ternary relations as coefficient vectors, polygons as stacked
half-planes ``A x <= b``. Checking a sample costs a handful of numpy operations whatever
the number of invariants; the violations are built only when one of them fails.

A missing value (NaN) breaks nothing: inference skipped it too. The checks do not wrap
themselves in ``np.errstate`` (it costs more than a check): callers run the engine with
floating-point warnings off (``np.errstate(all="ignore")`` around a replay, ``np.seterr``
in a monitor node), since NaN and inf samples are expected input. Every check reads its
invariant the way inference built it, so the samples an invariant was inferred from never
violate it: linear and ternary relations allow their stated tolerance plus the rounding
of evaluating ``a*x + b`` in float64, array averages and deviations a few ulps (the
monitor's summation order may differ from the translator's).
"""

from __future__ import annotations

from typing import Any, Callable, Dict, FrozenSet, List, Mapping, Sequence, Set, Tuple

import numpy as np

from .polygons import PolygonChecks
from .violation import Violation, show

_STAT_SLACK = 1e-12
"""Relative allowance on bounds of array averages and deviations."""

Found = List[Violation]
_count = np.count_nonzero
"""Faster than ``ndarray.any`` on small boolean arrays."""


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
                # the tolerance covers inference's data (its rounding term is 1e-14 of the
                # magnitudes); a quarter more covers the float64 rounding of this check
                linear.append(
                    (
                        tuple(index[n] for n in names),
                        tuple(float(c) for c in coefficients),
                        1.25 * float(params["tolerance"]) + 1e-300,
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
        self.polygon_checks = PolygonChecks(self.polygons, edges)
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
        # pairs: d = x - y (its sign is exact); violated when sign * d > limit
        rows = []
        for kind, found in sorted(pairs.items()):
            for first, second, inv in found:
                if kind == "==":
                    rows += [(first, second, 1.0, 0.0, inv), (first, second, -1.0, 0.0, inv)]
                else:  # "<" is broken by d >= 0, i.e. d > -(smallest subnormal)
                    rows.append((first, second, 1.0, -5e-324 if kind == "<" else 0.0, inv))
        self.pair_first = _ints([r[0] for r in rows])
        self.pair_second = _ints([r[1] for r in rows])
        self.pair_sign = _floats([r[2] for r in rows])
        self.pair_limit = _floats([r[3] for r in rows])
        self.pair_inv = [r[4] for r in rows]
        self.pair_count = len({id(r[4]) for r in rows})
        # linear and ternary relations as y - a*x - b*z - c with a padded third term
        padded = [
            (at + (at[0],) * (3 - len(at)), co[:-1] + (0.0,) * (3 - len(co)) + co[-1:], tol, inv)
            for at, co, tol, inv in linear
        ]
        self.linear_at = _ints([p[0] for p in padded]).reshape(len(padded), 3).T.copy()
        self.linear_coefficients = _floats([p[1] for p in padded]).reshape(len(padded), 3).T
        self.linear_tolerance = _floats([p[2] for p in padded])
        self.linear_inv = [p[3] for p in padded]

    @property
    def size(self) -> int:
        """How many invariants these checks hold."""
        return (
            len(self.bounds_inv)
            + len(self.one_of_inv)
            + len(self.nonzero_inv)
            + self.pair_count
            + len(self.linear_inv)
            + len(self.polygons)
            + len(self.string_sets)
        )

    def check(self, time: float, point: str, row: Any, strings: Sequence[Any] = ()) -> Found:
        """The violations of one sample (``row``: float64 values in ``index`` order)."""
        found: Found = []
        if len(self.bounds_at):
            x = row.take(self.bounds_at)
            bad = (x < self.bounds_lo) | (x > self.bounds_hi)
            if _count(bad):
                for k in bad.nonzero()[0].tolist():
                    inv = self.bounds_inv[k]
                    lo, hi = float(self.bounds_lo[k]), float(self.bounds_hi[k])
                    expected = f"[{show(lo)}, {show(hi)}]"
                    found.append(_violation(time, point, inv, float(x[k]), expected))
        if self.polygon_checks.count:
            candidates = self.polygon_checks.candidates(row)
            if len(candidates):
                for owner in self.polygon_checks.broken(row, candidates).tolist():
                    inv = self.polygons[owner]
                    first, second = inv["variables"]
                    observed = (float(row[self.index[first]]), float(row[self.index[second]]))
                    found.append(
                        Violation(
                            time,
                            point,
                            inv["id"],
                            "polygon",
                            inv["kind"],
                            "({}, {}) inside a {}-gon".format(
                                first, second, len(inv["params"]["b"])
                            ),
                            observed,
                            "inside the polygon",
                        )
                    )
        if len(self.one_of_at):
            x = row.take(self.one_of_at)
            bad = ~(x[:, None] == self.one_of_values).any(axis=1) & ~np.isnan(x)
            if _count(bad):
                for k in bad.nonzero()[0].tolist():
                    inv = self.one_of_inv[k]
                    expected = "one of " + show(set(inv["params"]["values"]))
                    found.append(_violation(time, point, inv, float(x[k]), expected))
        if len(self.nonzero_at):
            bad = row.take(self.nonzero_at) == 0
            if _count(bad):
                for k in bad.nonzero()[0].tolist():
                    found.append(_violation(time, point, self.nonzero_inv[k], 0.0, "!= 0"))
        if len(self.pair_first):
            d = row.take(self.pair_first) - row.take(self.pair_second)
            bad = d * self.pair_sign > self.pair_limit
            if _count(bad):
                reported = set()
                for k in bad.nonzero()[0].tolist():
                    inv = self.pair_inv[k]
                    if id(inv) in reported:
                        continue
                    reported.add(id(inv))
                    observed = (float(row[self.pair_first[k]]), float(row[self.pair_second[k]]))
                    found.append(_violation(time, point, inv, observed, inv["kind"]))
        if len(self.linear_inv):
            at, co = self.linear_at, self.linear_coefficients
            residual = row.take(at[0]) - co[0] * row.take(at[1]) - co[1] * row.take(at[2])
            residual -= co[2]
            bad = np.abs(residual) > self.linear_tolerance
            if _count(bad):
                for k in bad.nonzero()[0].tolist():
                    inv = self.linear_inv[k]
                    seen = tuple(float(row[self.index[n]]) for n in inv["variables"])
                    expected = "within {} of the relation".format(show(inv["params"]["tolerance"]))
                    found.append(_violation(time, point, inv, seen, expected))
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
            # inference skips window values that are not finite (an infinite sample, an
            # overflowing square): they break nothing here either
            bad = ((values < lo) | (values > hi)) & np.isfinite(values)
            if _count(bad):
                for k in bad.nonzero()[0].tolist():
                    inv = invs[k]
                    if inv["id"] in cleared:
                        continue
                    expected = f"[{show(float(lo[k]))}, {show(float(hi[k]))}]"
                    found.append(_violation(time, point, inv, float(values[k]), expected))
        return found
