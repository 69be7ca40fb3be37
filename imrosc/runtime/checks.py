"""The value checks of one program point, compiled into a few vectorised operations.

Every invariant over a point's values (Daikon's families, polygons, and the bounds of the
time-related families, which are checked on the window values the engine computes) is
grouped with its kind into arrays: bounds, orderings, equalities and linear and ternary
relations as linear forms (one matrix-vector product, :class:`_Forms`), one-of sets,
polygons as lookup tables and half-planes ``A x <= b`` (:mod:`.polygons`). Checking a
sample costs a handful of numpy operations whatever the number of invariants; the
violations are built only when one of them fails. Where numba is importable, one compiled
call over the same tables first clears the samples that break nothing (:mod:`.compiled`);
numpy's operations then run only for the others.

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

import math
from typing import Any, Callable, Dict, FrozenSet, List, Mapping, Optional, Sequence, Set, Tuple

import numpy as np

from .compiled import Kernel, Tables, compile_checks, numba_module, pack
from .families import (
    ARRAY,
    BOUNDS,
    COMPILED,
    EQUALITY,
    FAMILIES,
    FREQUENCY,
    FUNCTION,
    LINEAR,
    MEAN,
    NON_ZERO,
    ONE_OF,
    ORDER,
    POLYGON,
    RATE,
    STEP,
    STRING_ONE_OF,
    TERNARY,
    VARIANCE,
)
from .fast import count_nonzero as _count
from .polygons import PolygonChecks
from .violation import Violation, show

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


class _Held:
    """The invariants of one point by how :class:`Checks` checks them (what the collectors
    put where)."""

    def __init__(
        self, index: Mapping[str, int], strings: Mapping[str, int], stats: FrozenSet[str]
    ) -> None:
        self.index = index
        self.strings = strings
        self.stats = stats
        """Variables that are array statistics (their bounds get a relative allowance)."""
        self.bounds: List[Tuple[int, float, float, Mapping[str, Any]]] = []
        self.finite: List[Tuple[int, Mapping[str, Any]]] = []
        self.one_of: List[Tuple[int, List[float], Mapping[str, Any]]] = []
        self.nonzero: List[Tuple[int, Mapping[str, Any]]] = []
        self.pairs: Dict[str, List[Tuple[int, int, Mapping[str, Any]]]] = {
            "==": [],
            "<": [],
            "<=": [],
        }
        self.linear: List[Tuple[Tuple[int, ...], Tuple[float, ...], float, Mapping[str, Any]]] = []
        self.edges: List[Tuple[int, int, float, float, float, int]] = []
        self.polygons: List[Mapping[str, Any]] = []
        self.string_sets: List[Tuple[int, FrozenSet[str], Mapping[str, Any]]] = []
        self.functions: List[Tuple[str, Tuple[int, ...], Mapping[str, Any]]] = []

    def numeric(self, names: Sequence[str]) -> bool:
        """Whether every variable of ``names`` is in the sample vector."""
        return all(n in self.index for n in names)


Collector = Callable[[_Held, Mapping[str, Any]], None]
COLLECTORS: Dict[str, Collector] = {}
"""The collector of each value family: puts one invariant where its check reads it
(registered with :func:`collects`; a test holds them to the catalog's value families)."""


BESIDE_KERNEL: FrozenSet[str] = frozenset({STRING_ONE_OF, FUNCTION})
"""The value families :meth:`Checks.check` checks on every sample after the compiled kernel
(or numpy) answered; every other one is checked in :meth:`Checks._numeric`, which the kernel
replaces only where the catalog says it knows the family (:attr:`Family.compiled`)."""


def collects(*names: str) -> Callable[[Collector], Collector]:
    """Register the decorated function as the collector of the catalog's value families
    ``names``."""
    for name in names:
        family = FAMILIES.get(name)
        if family is None or family.check != "value":
            raise ValueError(f"{name!r} is no value family of the catalog")

    def register(function: Collector) -> Collector:
        for name in names:
            COLLECTORS[name] = function
        return function

    return register


@collects(BOUNDS, ARRAY)
def _bounds(held: _Held, inv: Mapping[str, Any]) -> None:
    name, params = inv["variables"][0], inv["params"]
    if name not in held.index:
        return
    lo = _number(params.get("min", "-inf"))
    hi = _number(params.get("max", "inf"))
    if name in held.stats:
        lo -= abs(lo) * _STAT_SLACK
        hi += abs(hi) * _STAT_SLACK
    held.bounds.append((held.index[name], lo, hi, inv))
    if params.get("finite") and inv["family"] == BOUNDS:
        held.finite.append((held.index[name], inv))


@collects(ONE_OF)
def _one_of(held: _Held, inv: Mapping[str, Any]) -> None:
    name = inv["variables"][0]
    if name in held.index:
        values = [_number(v) for v in inv["params"]["values"]]
        held.one_of.append((held.index[name], values, inv))


@collects(NON_ZERO)
def _non_zero(held: _Held, inv: Mapping[str, Any]) -> None:
    name = inv["variables"][0]
    if name in held.index:
        held.nonzero.append((held.index[name], inv))


@collects(EQUALITY, ORDER)
def _pairs(held: _Held, inv: Mapping[str, Any]) -> None:
    names = inv["variables"]
    if held.numeric(names):
        for other in names[1:]:
            held.pairs[inv["kind"]].append((held.index[names[0]], held.index[other], inv))


@collects(LINEAR, TERNARY)
def _linear(held: _Held, inv: Mapping[str, Any]) -> None:
    names, params = inv["variables"], inv["params"]
    if not held.numeric(names):
        return
    coefficients = (
        (params["a"], params["b"])
        if inv["family"] == LINEAR
        else (params["a"], params["b"], params["c"])
    )
    # the tolerance covers inference's data (its rounding term is 1e-14 of the
    # magnitudes); a quarter more covers the float64 rounding of this check
    held.linear.append(
        (
            tuple(held.index[n] for n in names),
            tuple(float(c) for c in coefficients),
            1.25 * float(params["tolerance"]) + 1e-300,
            inv,
        )
    )


@collects(POLYGON)
def _polygon(held: _Held, inv: Mapping[str, Any]) -> None:
    names, params = inv["variables"], inv["params"]
    if not held.numeric(names):
        return
    owner = len(held.polygons)
    held.polygons.append(inv)
    for (a, b), c in zip(params["A"], params["b"]):
        held.edges.append((held.index[names[0]], held.index[names[1]], a, b, c, owner))


@collects(STRING_ONE_OF)
def _string_one_of(held: _Held, inv: Mapping[str, Any]) -> None:
    name = inv["variables"][0]
    if name in held.strings:
        values = frozenset(inv["params"]["values"])
        held.string_sets.append((held.strings[name], values, inv))


@collects(FUNCTION)
def _function_of(held: _Held, inv: Mapping[str, Any]) -> None:
    names = inv["variables"]
    if held.numeric(names):
        held.functions.append((inv["kind"], tuple(held.index[n] for n in names), inv))


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
        compile: bool = True,
        lazy: bool = False,
    ) -> None:
        self.index = index
        self.string_index = strings
        self.cleared: Set[str] = set()
        held = _Held(index, strings, frozenset(stats))
        collected: Set[str] = set()
        for inv in invariants:
            collect = COLLECTORS.get(inv["family"])
            if collect is not None:
                collect(held, inv)
                collected.add(inv["family"])
        self.families = frozenset(collected)
        """The value families of the invariants given (a collector may hold none of them:
        a variable missing from the samples)."""
        self.polygons = held.polygons
        self.string_sets = held.string_sets
        self.functions = held.functions
        """``z == max(x, y)``, ``z == min(x, y)``, ``y == |x|``: kind, variables' places."""
        self.finite_at = _ints([f[0] for f in held.finite])
        """Variables whose bounds say they are never NaN nor infinite."""
        self.finite_inv = [f[1] for f in held.finite]
        self._compile(
            held.bounds, held.one_of, held.nonzero, held.pairs, held.linear, held.edges, lazy
        )
        if compile:
            self.compile()

    def _compile(
        self,
        bounds: List[Tuple[int, float, float, Mapping[str, Any]]],
        one_of: List[Tuple[int, List[float], Mapping[str, Any]]],
        nonzero: List[Tuple[int, Mapping[str, Any]]],
        pairs: Dict[str, List[Tuple[int, int, Mapping[str, Any]]]],
        linear: List[Tuple[Tuple[int, ...], Tuple[float, ...], float, Mapping[str, Any]]],
        edges: List[Tuple[int, int, float, float, float, int]],
        lazy: bool = False,
    ) -> None:
        self.polygon_checks = PolygonChecks(self.polygons, edges, lazy)
        self.polygon_words = [
            (inv, self.index[inv["variables"][0]], self.index[inv["variables"][1]], _inside(inv))
            for inv in self.polygons
        ]
        """Per polygon: the invariant, its variables' places and what a violation expected."""
        self.bounds_inv = [b[3] for b in bounds]
        self.one_of_at = _ints([o[0] for o in one_of])
        table = np.full((len(one_of), max([len(o[1]) for o in one_of] + [1])), np.nan)
        for row, (_, values, _) in enumerate(one_of):
            table[row, : len(values)] = values
        self.one_of_values = table
        self.one_of_inv = [o[2] for o in one_of]
        self.one_of_expected = [
            "one of " + show(set(inv["params"]["values"])) for _, _, inv in one_of
        ]
        """What each one-of violation expected (worded once)."""
        # a few sets: one membership test each beats four array operations
        self.one_of_few = (
            [(at, frozenset(values), k) for k, (at, values, _) in enumerate(one_of)]
            if len(one_of) <= _FEW_SETS
            else None
        )
        self.nonzero_at = _ints([n[0] for n in nonzero])
        self.nonzero_inv = [n[1] for n in nonzero]
        self.forms = _Forms(len(self.index))
        for at, lo, hi, inv in bounds:
            if hi < math.inf:
                self.forms.add(inv, [(at, 1.0)], hi, "<= " + show(hi))
            if lo > -math.inf:
                self.forms.add(inv, [(at, -1.0)], -lo, ">= " + show(lo))
        for kind, found in sorted(pairs.items()):
            for first, second, inv in found:
                terms = [(first, 1.0), (second, -1.0)]
                if kind == "==":
                    self.forms.add(inv, terms, 0.0, "==")
                    self.forms.add(inv, [(first, -1.0), (second, 1.0)], 0.0, "==")
                else:  # x - y (its sign is exact) > 0; "<" is broken by x - y >= 0
                    self.forms.add(inv, terms, -5e-324 if kind == "<" else 0.0, kind)
        for places, co, tolerance, inv in linear:
            # y - a*x (- b*z) - c, within the tolerance on either side
            terms = [(places[0], 1.0)] + [(i, -c) for i, c in zip(places[1:], co[:-1])]
            terms.append((self.forms.one, -co[-1]))
            expected = "within {} of the relation".format(show(inv["params"]["tolerance"]))
            self.forms.add(inv, terms, tolerance, expected)
            self.forms.add(inv, [(i, -w) for i, w in terms], tolerance, expected)
        polygons = self.polygon_checks
        guards = [(int(v), float(polygons.low[v]), float(polygons.high[v])) for v in polygons.used]
        self.forms.freeze(guards)
        self.pair_count = len(
            {id(inv) for inv, _ in self.forms.owners} - {id(b) for b in self.bounds_inv}
        )
        self.linear_inv = [item[3] for item in linear]
        self._clears: Optional[Kernel] = None
        """The checks compiled by numba (:mod:`.compiled`): whether a sample breaks
        nothing; ``None`` without numba."""
        self._tables = Tables(None, None, None)

    def compilable(self) -> bool:
        """Whether numba is importable and knows every family of these checks (a family
        given to them that the catalog does not mark compiled is checked by numpy, even
        where :meth:`numeric_families` does not hold it)."""
        known = self.numeric_families() <= COMPILED and self.families - BESIDE_KERNEL <= COMPILED
        return numba_module() is not None and known

    def compile(self) -> bool:
        """Compile the checks with numba (:func:`.compiled.compile_checks`) unless done:
        whether the compiled kernel now clears the samples. Another thread may check
        samples meanwhile (numpy's path): the tables are in place before the kernel."""
        if self._clears is not None:
            return True
        if not self.compilable():
            return False
        tables = self.tables()
        kernel = compile_checks(tables, len(self.index))
        if kernel is None:
            return False
        self._tables = tables
        self._clears = kernel
        return True

    @property
    def compiled(self) -> bool:
        """Whether the compiled kernel clears the samples (else numpy checks each)."""
        return self._clears is not None

    def numeric_families(self) -> Set[str]:
        """The families of the invariants :meth:`_numeric` checks. The compiled kernel
        clears a sample only where it knows them all (a family it does not know would be
        cleared unchecked): else numpy checks every sample."""
        held = list(self.bounds_inv) + self.one_of_inv + self.nonzero_inv + self.polygons
        held += [inv for inv, _ in self.forms.owners]
        return {inv["family"] for inv in held}

    def tables(self) -> Tables:
        """These checks as the compiled kernel reads them (:func:`.compiled.pack`)."""
        grids, shapes, shift = self.polygon_checks.compiled()
        sets = [
            (at, [_number(v) for v in inv["params"]["values"]])
            for at, inv in zip(self.one_of_at.tolist(), self.one_of_inv)
        ]
        return pack(
            self.forms.moved(),
            grids,
            shapes,
            self.polygon_checks.bits,
            shift,
            sets,
            self.nonzero_at.tolist(),
        )

    @property
    def size(self) -> int:
        """How many invariants these checks hold."""
        return (
            len(self.bounds_inv)
            + len(self.one_of_inv)
            + len(self.nonzero_inv)
            + self.pair_count
            + len(self.polygons)
            + len(self.string_sets)
            + len(self.functions)
        )

    def check(self, time: float, point: str, row: Any, strings: Sequence[Any] = ()) -> Found:
        """The violations of one sample (``row``: float64 values in ``index`` order)."""
        clears = self._clears
        if clears is not None and clears(row, *self._tables):
            found: Found = []  # the common case, answered by one compiled call
        else:
            found = self._numeric(time, point, row)
        if len(self.finite_at):
            x = row.take(self.finite_at)
            total = x.sum()
            if not math.isfinite(total):  # NaN or inf among them: a bound misses NaN (and inf
                # beyond a one-sided bound): the finiteness its params state catches them
                flagged = {v.invariant for v in found}
                for k in np.flatnonzero(~np.isfinite(x)).tolist():
                    inv = self.finite_inv[k]
                    if inv["id"] not in flagged:
                        found.append(_violation(time, point, inv, float(x[k]), _FINITE))
        for at, values, inv in self.string_sets:
            value = strings[at]
            if value not in values:
                expected = "one of " + ", ".join(sorted(f'"{v}"' for v in values))
                found.append(_violation(time, point, inv, value, expected))
        for kind, places, inv in self.functions:
            found += _function(time, point, kind, [row.item(k) for k in places], inv)
        if found and self.cleared:
            found = [v for v in found if v.invariant not in self.cleared]
        return found

    def _numeric(self, time: float, point: str, row: Any) -> Found:
        """The violations of ``row`` found by numpy."""
        found: Found = []
        forms = self.forms
        in_range = None
        dense = forms.dense
        if dense is not None:
            # one product gives every form, the polygons' range guards and the sum of the
            # sample: finite exactly when every value is (NaN and inf need the exact path)
            out = dense.dot(row)
            total = out.item(-1)
            if total - total == 0:
                bad = out > forms.dense_limit
                in_range = True
                if _count(bad):
                    hits = bad.nonzero()[0]
                    if hits[0] < forms.size:
                        z = np.concatenate((row, _TAIL))
                        found += forms.violations(time, point, z, hits[hits < forms.size])
                    in_range = not _count(forms.dense_guard.take(hits))
            else:
                found += forms.gathered(time, point, row)
        elif forms.size:
            found += forms.gathered(time, point, row)
        if self.polygon_checks.count:
            for owner in self.polygon_checks.broken(row, in_range):
                inv, first, second, expected = self.polygon_words[owner]
                observed = (float(row.item(first)), float(row.item(second)))
                found.append(_violation(time, point, inv, observed, expected))
        if self.one_of_few is not None:
            for at, held, k in self.one_of_few:
                number = row.item(at)
                if number not in held and not math.isnan(number):  # NaN breaks nothing
                    found.append(self._not_one_of(time, point, k, number))
        elif len(self.one_of_at):
            x = row.take(self.one_of_at)
            held = (x[:, None] == self.one_of_values).any(axis=1)
            if _count(held) < len(held):  # NaN holds nothing, yet breaks nothing either
                bad = ~held & ~np.isnan(x)
                for k in bad.nonzero()[0].tolist():
                    found.append(self._not_one_of(time, point, k, float(x[k])))
        if len(self.nonzero_at):
            bad = row.take(self.nonzero_at) == 0
            if _count(bad):
                for k in bad.nonzero()[0].tolist():
                    found.append(_violation(time, point, self.nonzero_inv[k], 0.0, "!= 0"))
        return found

    def rehearse(self, row: Any) -> None:
        """Check ``row`` again, keeping nothing, the polygons' lookup included (it would
        otherwise answer from its memory of the last sample's cells)."""
        self.polygon_checks.forget()
        self.check(0.0, "", row)

    def _not_one_of(self, time: float, point: str, k: int, observed: float) -> Violation:
        return _violation(time, point, self.one_of_inv[k], observed, self.one_of_expected[k])


_TAIL = np.array([0.0, 1.0])
"""Appended to a sample: the zero that pads short forms and the one of constants."""
_WIDTH = 4
_ONES = np.ones(_WIDTH)
_FINITE = "a finite value (never NaN nor infinite in training)"
_FEW_SETS = 8
"""Up to this many one-of invariants are tested one by one."""
_DENSE_CELLS = 2**15
"""Largest dense form matrix (rows times sample width) worth one matrix-vector product;
larger points gather their forms."""


class _Forms:
    """Linear forms ``w . z > limit`` of up to four terms over the sample ``z`` extended by
    ``(0, 1)``: bounds, orderings, equalities and linear and ternary relations together.

    Two ways to evaluate them, with the same answers. Dense (a point of modest size): one
    matrix-vector product over the sample, the constant term moved into the limit, with
    extra rows for the polygons' range guards and one that sums the sample; a term
    ``w * x`` is exact for ``w`` of 1 and -1 and the other terms add zeros, so a bound is
    the value itself and a difference ``x - y`` is rounded once (its sign exact); linear
    and ternary relations allow for any summation order in their tolerance. It needs
    every value finite (``0 * inf`` is NaN). Gathered (a sample with NaN or inf, a large
    point): the terms taken from ``z``, padding terms reading the zero slot (``x + 0 + 0 +
    0``, exact, infinities kept)."""

    def __init__(self, width: int) -> None:
        self.zero = width
        self.one = width + 1
        self.rows: List[Tuple[List[Tuple[int, float]], float]] = []
        self.owners: List[Tuple[Mapping[str, Any], str]] = []
        self.dense: Any = None
        self.dense_limit: Any = None
        self.dense_guard: Any = None
        """Rows of ``dense`` that fire when a value leaves a polygon grid's range."""

    def add(
        self, inv: Mapping[str, Any], terms: List[Tuple[int, float]], limit: float, expected: str
    ) -> None:
        self.rows.append((terms, limit))
        self.owners.append((inv, expected))

    def freeze(self, guards: Sequence[Tuple[int, float, float]] = ()) -> None:
        """Build the arrays; ``guards`` are the polygons' variables and their ranges."""
        self.size = len(self.rows)
        at = np.full((self.size, _WIDTH), self.zero, dtype=np.int64)
        weights = np.zeros((self.size, _WIDTH))
        for k, (terms, _) in enumerate(self.rows):
            for j, (index, weight) in enumerate(terms):
                at[k, j] = index
                weights[k, j] = weight
        self.at = at
        self.weights = weights
        self.words = [self._words(k) for k in range(self.size)]
        self.limit = np.asarray([limit for _, limit in self.rows], dtype=np.float64)
        # a bound that is at least as tight as a guard serves as that guard (firing more
        # often only sends a violating sample down the exact path)
        tight: Dict[Tuple[int, float], Tuple[int, float]] = {}
        for k, (terms, bound) in enumerate(self.rows):
            if len(terms) == 1 and terms[0][1] in (1.0, -1.0) and terms[0][0] < self.zero:
                key = (terms[0][0], terms[0][1])
                if key not in tight or bound < tight[key][1]:
                    tight[key] = (k, bound)
        guarding: List[int] = []
        extra: List[Tuple[int, float, float]] = []
        for index, low, high in guards:
            for weight, end in ((1.0, high), (-1.0, -low)):
                found = tight.get((index, weight))
                if found is not None and found[1] <= end:
                    guarding.append(found[0])
                else:
                    extra.append((index, weight, end))
        height = self.size + len(extra) + 1
        if height == 1 or height * self.zero > _DENSE_CELLS:
            return
        dense = np.zeros((height, self.zero))
        limit = np.empty(height)
        for k, (terms, moved) in enumerate(self.moved()):
            for index, weight in terms:
                dense[k, index] += weight
            limit[k] = moved
        for k, (index, weight, bound) in enumerate(extra):
            dense[self.size + k, index] = weight
            limit[self.size + k] = bound
        dense[-1] = 1.0
        limit[-1] = math.inf
        guard = np.zeros(height, dtype=bool)
        guard[guarding] = True
        guard[self.size : self.size + len(extra)] = True
        self.dense = dense
        self.dense_limit = limit
        self.dense_guard = guard

    def _words(self, k: int) -> Tuple[Mapping[str, Any], Tuple[int, ...], bool, str]:
        """How a violation of form ``k`` is worded: its invariant, the places of ``z`` it
        observes, whether it observes one value (a bound), and what it expected."""
        inv, expected = self.owners[k]
        places = [int(i) for i, w in zip(self.at[k], self.weights[k]) if w != 0]
        family = inv["family"]
        if family in (BOUNDS, ARRAY):
            lo = inv["params"].get("min", "-inf")
            hi = inv["params"].get("max", "inf")
            return inv, (places[0],), True, f"[{show(_number(lo))}, {show(_number(hi))}]"
        if family in (LINEAR, TERNARY):
            count = len(inv["variables"])
            return inv, tuple(int(i) for i in self.at[k][:count]), False, expected
        return inv, tuple(places[:2]), False, expected

    def moved(self) -> List[Tuple[List[Tuple[int, float]], float]]:
        """The forms over the sample alone, as the dense product reads them: each form's
        terms on the sample's values and its limit less its constant."""
        moved = []
        for terms, bound in self.rows:
            constant = sum([weight for index, weight in terms if index == self.one], 0.0)
            kept = [(index, weight) for index, weight in terms if index < self.zero]
            moved.append((kept, bound - constant))
        return moved

    def gathered(self, time: float, point: str, row: Any) -> Found:
        """The violations of ``row`` (any values), the terms gathered."""
        z = np.concatenate((row, _TAIL))
        # the four products summed by a product with ones (a third cheaper than .sum(axis=1))
        bad = np.dot(z.take(self.at) * self.weights, _ONES) > self.limit
        if not _count(bad):
            return []
        return self.violations(time, point, z, bad.nonzero()[0])

    def violations(self, time: float, point: str, z: Any, broken: Any) -> Found:
        """The violations of the forms at ``broken`` (indices) on ``z``."""
        found: Found = []
        seen = set()
        words = self.words
        value = z.item
        for k in broken.tolist():
            inv, places, single, expected = words[k]
            if id(inv) in seen:  # an equality or relation has a form for each side
                continue
            seen.add(id(inv))
            observed: Any = value(places[0]) if single else tuple(value(i) for i in places)
            found.append(_violation(time, point, inv, observed, expected))
        return found


def _function(
    time: float, point: str, kind: str, values: List[float], inv: Mapping[str, Any]
) -> Found:
    """The violation of ``z == max(x, y)`` (``min``; ``y == |x|``) by ``values`` (``[z, x,
    y]``, ``[y, x]``), if any: the functions are exact in float64; NaN breaks nothing."""
    if any(math.isnan(v) for v in values):
        return []
    if kind == "abs":
        expected = abs(values[1])
    else:
        expected = max(values[1], values[2]) if kind == "max" else min(values[1], values[2])
    if values[0] + 0.0 == expected + 0.0:
        return []
    names = inv["variables"]
    shown = f"|{names[1]}|" if kind == "abs" else f"{kind}({names[1]}, {names[2]})"
    return [_violation(time, point, inv, tuple(values), f"== {shown} = {show(expected)}")]


def _violation(
    time: float, point: str, inv: Mapping[str, Any], observed: Any, expected: str
) -> Violation:
    return Violation(
        time, point, inv["id"], inv["family"], inv["kind"], inv["text"], observed, expected
    )


def _inside(polygon: Mapping[str, Any]) -> str:
    """What a polygon's violation expected: ``inside the 4-vertex polygon of (x, y)``."""
    first, second = polygon["variables"]
    count = len(polygon["params"]["vertices"])
    return f"inside the {count}-vertex polygon of ({first}, {second})"


class WindowChecks:
    """The bounds of a point's frequency, variance, rate, mean and step invariants."""

    def __init__(self, invariants: Sequence[Mapping[str, Any]], tracked: Sequence[str]) -> None:
        position = {name: k for k, name in enumerate(tracked)}
        self.frequency: List[Mapping[str, Any]] = []
        self.per_variable: Dict[str, List[Tuple[int, Mapping[str, Any]]]] = {
            VARIANCE: [],
            RATE: [],
            STEP: [],
            MEAN: [],
        }
        self.window = 0.0
        for inv in invariants:
            family = inv["family"]
            if family == FREQUENCY:
                self.frequency.append(inv)
            elif family in self.per_variable and inv["variables"][0] in position:
                self.per_variable[family].append((position[inv["variables"][0]], inv))
            else:
                continue
            self.window = float(inv["params"]["window"])
        self.recovered = max([_number(i["params"]["min"]) for i in self.frequency], default=0.0)
        """The frequency at which no lower bound is broken: a silence is over."""
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
        silent: bool = False,
    ) -> Found:
        """Violations of one defined window; ``derived(family)`` gives its values. With
        ``silent`` (a silence already reported) a frequency below a minimum is not."""
        found: Found = []
        for inv in self.frequency:
            lo, hi = _number(inv["params"]["min"]), _number(inv["params"]["max"])
            low = frequency < lo and not silent
            if (low or frequency > hi) and inv["id"] not in cleared:
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
