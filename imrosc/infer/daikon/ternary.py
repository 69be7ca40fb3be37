"""Ternary relations ``z = a*x + b*y + c`` among triples of numeric variables.

Daikon's LinearTernary, with the same machinery as ``linear``: candidates are the triples
``x < y < z`` of a point's numeric, non-derived variables; the float screen drops a triple
as soon as some chunk shows one of its variables cannot take part with a nonzero
coefficient (``screen``), and survivors keep exact moment matrices. ``finalize`` accepts a
triple iff some orientation's exact least-squares fit, rounded to floats, has an exact sum
of squared residuals at most ``tolerance**2`` with::

    tolerance = 1e-9 * (max z - min z) + 1e-14 * (max|z| + |a| max|x| + |b| max|y| + |c|)

and prints the last variable as the dependent one unless a coefficient then needs more than
4 significant digits, when the orientation with the fewest digits is printed; coefficients
are the shortest decimals that still hold.

A variable with 2 or 3 distinct values (a mode: ``t = a - 2*m + 1`` with ``m`` in ``{-1, 0,
2}``) takes part only beside two variables with more than 3 values each, and only once two
of its levels each show more than 3 distinct points of the other two (``levels``: on a
level the relation is a line, held to Daikon's rule for lines); at most one such variable
per triple.

Suppressed: triples with a constant variable, a non-leader of an equality class, a variable
with at most 3 distinct values but as above, a variable linearly related to an earlier one
(``y = 2*x + 3`` makes every relation of ``y`` one of ``x``: the state tracks linear pairs
itself), or a pair that is itself linear (the linear family reports it, Daikon's rule);
fits where a printed coefficient of ``x`` or ``y`` is zero; unjustified support
(confidence ``1 - 2**-n``, ``n`` the joint samples).
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np
import numpy.typing as npt

from imrosc.infer.builders import States, builds
from imrosc.infer.core import FinalizeContext, Invariant, Samples, Variable, confidence
from imrosc.infer.daikon.chunk import view
from imrosc.infer.daikon.exact import Fit, Moments, choose
from imrosc.infer.daikon.levels import LevelSupport
from imrosc.infer.daikon.linear import LinearState, best_pair_fit
from imrosc.infer.daikon.relation import RelationState, relation_text
from imrosc.ir import Tunables
from imrosc.runtime.families import TERNARY
from imrosc.translate.points import PointSpec

_ORIENTATIONS = ((2, (0, 1)), (1, (0, 2)), (0, (1, 2)))


class TernaryState(RelationState):
    """Mergeable state of the ternary family at one point."""

    family = TERNARY
    width = 3

    def __init__(self, variables: Sequence[Variable]) -> None:
        super().__init__(variables)
        self.pairs = LinearState(variables)
        self.support = LevelSupport()

    def update(self, samples: Samples) -> None:
        """Consume one chunk (and track linear pairs, to relate only their leaders, and the
        levels of variables with few values so far)."""
        self.pairs.update(samples)
        super().update(samples)
        few = [not overflow for overflow in self.distinct.overflow]
        if self.live is not None and len(self.live) and any(few):
            self.support.update(view(samples).columns(self.names), self.live, few)

    def merge(self, other: Any) -> None:
        """Absorb a state whose samples come after ours."""
        super().merge(other)
        self.pairs.merge(other.pairs)
        self.support.merge(other.support)

    def _members_usable(
        self, members: list[int], usable: npt.NDArray[np.bool_], few: npt.NDArray[np.bool_]
    ) -> bool:
        """All members usable, or one with few values supported by its levels beside two
        usable ones."""
        if all(usable[v] for v in members):
            return True
        rest = [k for k, v in enumerate(members) if not usable[v]]
        if len(rest) != 1 or not few[members[rest[0]]]:
            return False
        triple = (members[0], members[1], members[2])
        return self.support.supported(triple, rest[0])

    def finalize(self, context: FinalizeContext) -> list[Invariant]:
        """The justified ternary relations."""
        usable = self.usable(context)
        counts = np.array(self.distinct.count)
        overflow = np.array(self.distinct.overflow, dtype=bool)
        few = self.leaders(context) & ~overflow & (counts >= 2)
        linked = {(first, second) for first, second, _ in self.pairs.relations(context)}
        for v in range(len(self.names)):
            if any(usable[u] and (u, v) in linked for u in range(v)):
                usable[v] = False
        found: list[Invariant] = []
        for candidate, moments in sorted(self.moments.items()):
            members = list(candidate)
            if not self._members_usable(members, usable, few):
                continue
            if not context.justified(moments.count):
                continue
            spread, magnitude = self.scales(members)
            if _has_linear_pair(moments, spread, magnitude):
                continue
            fit = _best_fit(moments, spread, magnitude)
            if fit is None:
                continue
            a, b, intercept = fit.coefficients
            dependent = self.names[members[fit.dependent]]
            x = self.names[members[fit.independents[0]]]
            y = self.names[members[fit.independents[1]]]
            found.append(
                Invariant(
                    family=self.family,
                    kind="ternary",
                    point=context.point,
                    variables=(dependent, x, y),
                    params={"a": a, "b": b, "c": intercept, "tolerance": fit.tolerance},
                    text=relation_text(dependent, [(a, x), (b, y)], intercept),
                    samples=moments.count,
                    confidence=confidence(moments.count),
                    condition=context.condition,
                    runs=context.runs,
                )
            )
        return found


def _has_linear_pair(moments: Moments, spread: list[float], magnitude: list[float]) -> bool:
    for first, second in ((0, 1), (0, 2), (1, 2)):
        pair = moments.restrict([first, second])
        scale = [spread[first], spread[second]], [magnitude[first], magnitude[second]]
        if best_pair_fit(pair, *scale) is not None:
            return True
    return False


def _best_fit(moments: Moments, spread: list[float], magnitude: list[float]) -> Fit | None:
    fits = []
    for dependent, independents in _ORIENTATIONS:
        fit = Fit(moments, dependent, independents, spread, magnitude)
        if fit.accepted and 0 not in fit.coefficients[:2]:
            fits.append(fit)
    return choose(fits)


@builds(TERNARY)
def _states(point: PointSpec, tunables: Tunables, enabled: frozenset[str]) -> States:
    return [TernaryState(point.variables)]
