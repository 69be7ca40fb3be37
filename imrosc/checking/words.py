"""The value violations of many samples of a point at once, as :meth:`Checks.check` words them.

:class:`ChunkPoint <imrosc.checking.points.ChunkPoint>` flags the samples of a chunk that may
break a value invariant; :meth:`RowChecks.violations` then finds and words the violations of
all of them in a few array operations, with the engine's answers, in the engine's order
(forms by row, polygons, one-of sets, non-zero values, finiteness, string sets, functions)
and the engine's words:

* bounds, orderings and equalities (forms of one or two terms of weight 1 or -1): ``x``,
  ``-x`` and ``x - y`` are rounded at most once whatever the order of summation, so their
  value, and so whether they break, is the engine's bit for bit (its dense product or its
  gathered terms alike);
* polygons: the plain half-plane test ``a*x + b*y > c`` of every edge at finite
  coordinates, which is the answer of the engine's lookup tables
  (:mod:`imrosc.runtime.polygons`);
* one-of sets, non-zero values, finiteness, string sets and functions: the same comparisons,
  per column.

A linear or ternary relation's value depends on the order of its summation (the engine's
matrix product): a sample that comes within the chunk's margin of such a relation's
tolerance is checked by the engine itself (:meth:`Checks.check`), as are all the samples of a
point whose checks are compiled by numba (the compiled kernel clears samples first).
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np
import numpy.typing as npt

from imrosc.runtime.checks import _FINITE, Checks, _function
from imrosc.runtime.violation import Violation

FloatArray = npt.NDArray[np.float64]
BoolArray = npt.NDArray[np.bool_]
_SINGLE, _PAIR, _ZERO = 0, 1, 2
"""How a column's violation observes its sample: one value, two values, the literal 0.0."""


class RowChecks:
    """The value checks of one point over a matrix of its samples."""

    def __init__(self, checks: Checks) -> None:
        self.checks = checks
        forms = checks.forms
        self.relations: list[int] = []
        plain: list[int] = []
        for k, (terms, _) in enumerate(forms.rows):
            simple = len(terms) <= 2 and all(
                index < forms.zero and weight in (1.0, -1.0) for index, weight in terms
            )
            (plain if simple else self.relations).append(k)
        self.plain = plain
        """The forms whose value is the engine's bit for bit (the others: :attr:`relations`)."""
        width = len(checks.index)
        self.width = width
        at = np.full((len(plain), 2), width, dtype=np.int64)  # the zero slot pads
        weights = np.zeros((len(plain), 2))
        for j, k in enumerate(plain):
            for t, (index, weight) in enumerate(forms.rows[k][0]):
                at[j, t] = index
                weights[j, t] = weight
        self.form_at = at
        self.form_weights = weights
        self.form_limit = np.asarray([forms.rows[k][1] for k in plain], dtype=np.float64)
        groups: dict[int, list[int]] = {}
        for j, k in enumerate(plain):
            groups.setdefault(id(forms.owners[k][0]), []).append(j)
        self.repeats = [group for group in groups.values() if len(group) > 1]
        """The forms of each invariant with several (an equality's two sides, each pair of
        an equality of more variables): a violation is worded once, by its first form
        broken."""
        # what each column of the broken matrix words: the invariant, how it observes,
        # the places it reads, what it expected
        columns: list[tuple[Any, int, int, int, str]] = []
        for k in plain:
            inv, places, single, expected = forms.words[k]
            if single:
                columns.append((inv, _SINGLE, places[0], 0, expected))
            else:
                columns.append((inv, _PAIR, places[0], places[1], expected))
        self.polygons = []
        for inv, first, second, expected in checks.polygon_words:
            columns.append((inv, _PAIR, first, second, expected))
            a = np.asarray([row[0] for row in inv["params"]["A"]], dtype=np.float64)
            b = np.asarray([row[1] for row in inv["params"]["A"]], dtype=np.float64)
            c = np.asarray(inv["params"]["b"], dtype=np.float64)
            self.polygons.append((first, second, a, b, c))
        self.one_of = []
        sets = zip(checks.one_of_at.tolist(), checks.one_of_inv, strict=True)
        for k, (at_k, inv) in enumerate(sets):
            held = checks.one_of_values[k]
            self.one_of.append((at_k, held[~np.isnan(held)]))
            columns.append((inv, _SINGLE, at_k, 0, checks.one_of_expected[k]))
        for at_k, inv in zip(checks.nonzero_at.tolist(), checks.nonzero_inv, strict=True):
            columns.append((inv, _ZERO, at_k, 0, "!= 0"))
        self.columns = [
            (inv["id"], inv["family"], inv["kind"], inv["text"], how, first, second, expected)
            for inv, how, first, second, expected in columns
        ]
        self.firsts = np.asarray([c[5] for c in self.columns], dtype=np.int64)
        self.seconds = np.asarray([c[6] for c in self.columns], dtype=np.int64)
        self.strings = [
            (at_k, held, "one of " + ", ".join(sorted(f'"{v}"' for v in held)), inv)
            for at_k, held, inv in checks.string_sets
        ]

    def may_relate(self, values: FloatArray) -> BoolArray:
        """The samples a relation might break (checked by the engine itself): the chunk's
        margin, as :meth:`ChunkPoint._may_break` flags them."""
        flagged = np.zeros(len(values), dtype=bool)
        forms = self.checks.forms
        zero, one = forms.zero, forms.one
        for k in self.relations:
            terms, limit = forms.rows[k]
            total = np.zeros(len(values))
            scale = np.zeros(len(values))
            for index, weight in terms:
                if index == zero:
                    continue
                term = weight * (values[:, index] if index != one else np.ones(len(values)))
                total = total + term
                scale = scale + np.abs(term)
            flagged |= total > limit - (1e-12 * scale + 1e-300)
        return flagged

    def broken(self, values: FloatArray) -> BoolArray:
        """Per sample and column: the forms, polygons, one-of sets and non-zero values it
        breaks (a form of an invariant already broken by an earlier form left out)."""
        count = len(values)
        parts: list[BoolArray] = []
        if len(self.plain):
            z = np.concatenate((values, np.zeros((count, 1))), axis=1)
            at, weights = self.form_at, self.form_weights
            total = z[:, at[:, 0]] * weights[:, 0] + z[:, at[:, 1]] * weights[:, 1]
            forms = total > self.form_limit
            for group in self.repeats:
                seen = forms[:, group[0]].copy()
                for j in group[1:]:
                    broken = forms[:, j]
                    forms[:, j] = broken & ~seen
                    seen |= broken
            parts.append(forms)
        for first, second, a, b, c in self.polygons:
            x = values[:, first, None]
            y = values[:, second, None]
            outside = np.asarray(np.asarray(a * x + b * y > c).any(axis=1), dtype=bool)
            # as the engine: a NaN or infinite coordinate breaks no polygon (its hull was
            # built from finite samples; an inf would reach past an edge)
            outside &= np.isfinite(x[:, 0]) & np.isfinite(y[:, 0])
            parts.append(outside[:, None])
        for at_k, known in self.one_of:
            x = values[:, at_k]
            parts.append((~np.isin(x, known) & ~np.isnan(x))[:, None])
        at_nonzero = self.checks.nonzero_at
        if len(at_nonzero):
            parts.append(values[:, at_nonzero] == 0)
        if not parts:
            return np.zeros((count, 0), dtype=bool)
        return np.concatenate(parts, axis=1)

    def violations(
        self,
        times: Sequence[float],
        point: str,
        values: FloatArray,
        texts: Sequence[npt.NDArray[Any]],
    ) -> list[list[Violation]]:
        """The violations of each sample (``values``: one row per sample), those of
        :meth:`Checks.check` in its order."""
        checks = self.checks
        count = len(values)
        found: list[list[Violation]] = [[] for _ in range(count)]
        rows, cols = np.nonzero(self.broken(values))
        if len(rows):
            first = values[rows, self.firsts[cols]].tolist()
            second = values[rows, self.seconds[cols]].tolist()
            columns = self.columns
            for row, col, x, y in zip(rows.tolist(), cols.tolist(), first, second, strict=True):
                ident, family, kind, text, how, _, _, expected = columns[col]
                observed = x if how == _SINGLE else (x, y) if how == _PAIR else 0.0
                found[row].append(
                    Violation(times[row], point, ident, family, kind, text, observed, expected)
                )
        if len(checks.finite_at):
            x = values[:, checks.finite_at]
            for row, k in zip(*np.nonzero(~np.isfinite(x)), strict=True):
                inv = checks.finite_inv[k]
                if all(v.invariant != inv["id"] for v in found[row]):
                    found[row].append(_word(times[row], point, inv, float(x[row, k]), _FINITE))
        for at_k, held, expected, inv in self.strings:
            column = texts[at_k]
            for row in range(count):
                value = column[row]
                if value not in held:
                    found[row].append(_word(times[row], point, inv, value, expected))
        for kind, places, inv in checks.functions:
            z = values[:, places[0]]
            if kind == "abs":
                expect = np.abs(values[:, places[1]])
            elif kind == "max":
                expect = np.maximum(values[:, places[1]], values[:, places[2]])
            else:
                expect = np.minimum(values[:, places[1]], values[:, places[2]])
            for row in np.flatnonzero(z != expect).tolist():
                taken = [float(values[row, k]) for k in places]
                found[row] += _function(times[row], point, kind, taken, inv)
        if checks.cleared:
            cleared = checks.cleared
            found = [[v for v in row if v.invariant not in cleared] for row in found]
        return found


def _word(time: float, point: str, inv: Any, observed: Any, expected: str) -> Violation:
    return Violation(
        time, point, inv["id"], inv["family"], inv["kind"], inv["text"], observed, expected
    )
