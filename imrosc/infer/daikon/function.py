"""Functions of numeric variables: ``z == max(x, y)``, ``z == min(x, y)``, ``y == |x|``.

Daikon's FunctionBinary (``Maximum``, ``Minimum``) and FunctionUnary (``Abs``): relations
no linear form states, such as a command saturated by a limit, the larger of two sensor
readings, or a magnitude. Subjects are the numeric, non-derived variables; every triple
``(z, x, y)`` with ``x < y`` (and every pair ``(y, x)``) is a candidate until a sample breaks
it: a sample tests a candidate when none of its variables is NaN there, and breaks it when
the equality is false (``max``, ``min`` and ``abs`` are exact in float64: no tolerance).

Per result variable the state holds the candidates no sample has broken yet, sparsely, and
per candidate the samples that tested it and that told its two cases apart (``z == x`` with
``x`` strictly above ``y`` and ``z == y`` with ``y`` above ``x`` for ``max``, below for
``min``; a negative and a positive ``x`` for ``abs``). Before the first sample where the
result variable is known every candidate is alive; that sample's row settles most of them
at once: a candidate whose variables are all known there and none equals the result (for
``abs``, none's magnitude) is broken, so only those with a variable in the row's set of
equal-or-unknown variables are kept and tested further. Every count is a sum over samples
and a candidate dies at its first breaking sample, so chunking and merging give the same
state, bit for bit.

``finalize`` reports a candidate that is alive, tested on a justified number of samples
(``1 - 2**-n``) and met both of its cases: one case alone is an equality, an order or a
negation, which the other families report.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
import numpy.typing as npt

from imrosc.infer.builders import States, builds
from imrosc.infer.core import FinalizeContext, Invariant, Samples, Variable, confidence
from imrosc.infer.daikon.common import unary_variables
from imrosc.ir import Tunables
from imrosc.runtime.families import FUNCTION
from imrosc.translate.points import PointSpec

BoolArray = npt.NDArray[np.bool_]
IntArray = npt.NDArray[np.int64]

BLOCK = 256
"""Rows of a chunk's first block: each block tests only the candidates the earlier ones
left alive, each twice as long as the one before (up to ``_LARGEST_BLOCK``), so that
candidates most chunks break die early and the true functions take few blocks."""
_LARGEST_BLOCK = 8192
SEED_ROWS = 256
"""Rows where the result is known that are searched for the one that settles the most."""
KINDS = ("max", "min", "abs")


@dataclass
class Candidates:
    """The live candidates of one result variable and one kind, sorted by ``(x, y)``
    (``y`` is -1 for ``abs``), with their counts."""

    x: IntArray
    y: IntArray
    tested: IntArray
    first: IntArray
    second: IntArray

    @staticmethod
    def of(x: IntArray, y: IntArray) -> Candidates:
        zeros = np.zeros(len(x), np.int64)
        return Candidates(x, y, zeros, zeros.copy(), zeros.copy())

    def keep(self, mask: BoolArray) -> Candidates:
        return Candidates(
            self.x[mask], self.y[mask], self.tested[mask], self.first[mask], self.second[mask]
        )

    def codes(self, size: int) -> IntArray:
        return self.x * (size + 1) + (self.y + 1)


class FunctionState:
    """Mergeable state of the function family at one point."""

    family = FUNCTION

    def __init__(self, variables: Sequence[Variable]) -> None:
        self.variables = unary_variables(variables)
        self.names = tuple(v.name for v in self.variables)
        self.live: dict[tuple[str, int], Candidates] = {}
        """Per kind and result variable once a sample knew it; absent: every candidate."""

    def update(self, samples: Samples) -> None:
        if len(samples) == 0 or len(self.names) < 2:
            return
        values = np.empty((len(self.names), len(samples)))
        for k, name in enumerate(self.names):
            values[k] = samples.column(name)
        values += 0.0  # -0.0 counts as 0.0
        missing = np.isnan(values)
        for kind in KINDS:
            for z in range(len(self.names)):
                found = self.live.get((kind, z))
                if found is None:
                    found = self._seed(kind, z, values, missing)
                    if found is None:
                        continue
                if len(found.x):
                    found = self._test(kind, z, found, values, missing)
                self.live[(kind, z)] = found

    def _seed(self, kind: str, z: int, values: Any, missing: Any) -> Candidates | None:
        """Every candidate of result ``z`` that the chunk's first rows knowing ``z`` do not
        settle (``None``: no row knows ``z``)."""
        (known,) = np.nonzero(~missing[z])
        if not len(known):
            return None
        rows = known[:SEED_ROWS]
        seen = np.abs(values[:, rows]) if kind == "abs" else values[:, rows]
        open_ = (seen == values[z, rows]) | missing[:, rows]
        open_[z] = False
        row = int(np.argmin(open_.sum(axis=0)))
        (keys,) = np.nonzero(open_[:, row])
        n = len(self.names)
        if kind == "abs":
            return Candidates.of(keys.astype(np.int64), np.full(len(keys), -1, np.int64))
        pairs = {(min(a, b), max(a, b)) for a in keys.tolist() for b in range(n) if b not in (a, z)}
        ordered = sorted(pairs)
        x = np.array([p[0] for p in ordered], np.int64)
        y = np.array([p[1] for p in ordered], np.int64)
        return Candidates.of(x, y)

    def _test(self, kind: str, z: int, found: Candidates, values: Any, missing: Any) -> Candidates:
        """The candidates the chunk leaves alive, their counts updated."""
        rows = values.shape[1]
        alive = np.ones(len(found.x), bool)
        whole = not missing.any()  # every row tested: no masks
        start, size = 0, BLOCK
        while start < rows:
            live = np.flatnonzero(alive)
            if not len(live):
                break
            block = slice(start, min(start + size, rows))
            start, size = start + size, min(2 * size, _LARGEST_BLOCK)
            zv = values[z, block]
            xv = values[found.x[live], block]
            if kind == "abs":
                result = np.abs(xv)
                first, second = xv < 0, xv > 0
            else:
                yv = values[found.y[live], block]
                if kind == "max":
                    result, first, second = np.maximum(xv, yv), xv > yv, yv > xv
                else:
                    result, first, second = np.minimum(xv, yv), xv < yv, yv < xv
                first &= zv == xv
                second &= zv == yv
            wrong = result != zv
            if whole:
                tested: int | IntArray = len(zv)
            else:
                lost = missing[found.x[live], block] | missing[z, block]
                if kind != "abs":
                    lost |= missing[found.y[live], block]
                first &= ~lost
                second &= ~lost
                wrong &= ~lost
                tested = (~lost).sum(axis=1)
            broken = wrong.any(axis=1)
            found.tested[live] += tested
            found.first[live] += first.sum(axis=1)
            found.second[live] += second.sum(axis=1)
            alive[live[broken]] = False
        return found.keep(alive)

    def end_run(self) -> None:
        """Functions do not depend on runs."""

    def merge(self, other: Any) -> None:
        """Absorb a state of the same point whose runs come after ours."""
        if not isinstance(other, FunctionState) or other.names != self.names:
            raise TypeError("can only merge function states of the same variables")
        size = len(self.names)
        for key, theirs in other.live.items():
            mine = self.live.get(key)
            if mine is None:
                self.live[key] = theirs.keep(np.ones(len(theirs.x), bool))  # a copy
                continue
            _, a, b = np.intersect1d(
                mine.codes(size), theirs.codes(size), assume_unique=True, return_indices=True
            )
            kept = mine.keep(np.isin(np.arange(len(mine.x)), a))
            order = np.argsort(a)
            kept.tested += theirs.tested[b[order]]
            kept.first += theirs.first[b[order]]
            kept.second += theirs.second[b[order]]
            self.live[key] = kept

    def finalize(self, context: FinalizeContext) -> list[Invariant]:
        """The functions alive, justified and seen in both of their cases."""
        found: list[Invariant] = []
        names = self.names
        for (kind, z), live in sorted(self.live.items()):
            chosen = (live.first > 0) & (live.second > 0)
            xs, ys, counts = live.x[chosen], live.y[chosen], live.tested[chosen]
            for x, y, samples in zip(xs.tolist(), ys.tolist(), counts.tolist(), strict=True):
                if not context.justified(samples):
                    continue
                at: tuple[int, ...] = (z, x) if kind == "abs" else (z, x, y)
                if kind == "abs":
                    text = f"{names[z]} == |{names[x]}|"
                else:
                    text = f"{names[z]} == {kind}({names[x]}, {names[y]})"
                found.append(
                    Invariant(
                        family=self.family,
                        kind=kind,
                        point=context.point,
                        variables=tuple(names[k] for k in at),
                        params={},
                        text=text,
                        samples=samples,
                        confidence=confidence(samples),
                        condition=context.condition,
                        runs=context.runs,
                    )
                )
        return found


@builds(FUNCTION)
def _states(point: PointSpec, tunables: Tunables, enabled: frozenset[str]) -> States:
    return [FunctionState(point.variables)]
