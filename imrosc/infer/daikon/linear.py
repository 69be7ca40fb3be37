"""Linear relations ``y = a*x + b`` between pairs of numeric variables (Daikon's LinearBinary).

Candidates are the pairs ``x < y`` of a point's numeric, non-derived variables (variable
order); the float screen drops most of them on a chunk's first rows and the survivors keep
exact sums (``relation``). ``finalize`` solves least squares exactly, rounds the
coefficients to floats and accepts the relation iff the exact sum of squared residuals is
at most ``tolerance**2``, so that *every* sample lies within the tolerance of the line::

    tolerance = 1e-9 * (max y - min y) + 1e-14 * (max|y| + |a| max|x| + |b|)

(the first term is relative to the dependent variable's spread, the second covers float
rounding of the terms). Both orientations (``y`` on ``x`` and ``x`` on ``y``) are tried; the
later variable is the dependent one unless a coefficient then needs more than 4
significant digits (``y = 0.3333333333333333*x``), when the orientation with the fewest
digits is printed (``x = 3*y``). Coefficients are the shortest decimals (1 to 17
significant digits, zero for the intercept when it fits) for which the relation still
holds exactly within tolerance; the params hold those floats.

Reported only between non-constant leaders of equality classes with more than 3 distinct
values each, with a nonzero slope, not ``y = x`` (that is equality), and with justified
support (confidence ``1 - 2**-n``, ``n`` the joint samples). Exactness holds for any
chunking except for the screen's documented margin (``screen``).
"""

from __future__ import annotations

from imrosc.infer.builders import States, builds
from imrosc.infer.core import FinalizeContext, Invariant, confidence
from imrosc.infer.daikon.exact import Fit, Moments, choose
from imrosc.infer.daikon.relation import RelationState, relation_text
from imrosc.ir import Tunables
from imrosc.runtime.families import LINEAR
from imrosc.translate.points import PointSpec


class LinearState(RelationState):
    """Mergeable state of the linear family at one point."""

    family = LINEAR
    width = 2

    def relations(self, context: FinalizeContext) -> list[tuple[int, int, Fit]]:
        """``(x, y, fit)`` for every accepted pair ``x < y`` (variable indices)."""
        usable = self.usable(context)
        found: list[tuple[int, int, Fit]] = []
        for (first, second), moments in sorted(self.moments.items()):
            if not (usable[first] and usable[second]):
                continue
            if not context.justified(moments.count):
                continue
            fit = best_pair_fit(moments, *self.scales([first, second]))
            if fit is None:
                continue
            slope, intercept = fit.coefficients
            if slope == 1 and intercept == 0:
                continue
            found.append((first, second, fit))
        return found

    def finalize(self, context: FinalizeContext) -> list[Invariant]:
        """The justified linear relations."""
        found: list[Invariant] = []
        for first, second, fit in self.relations(context):
            members = (first, second)
            slope, intercept = fit.coefficients
            dependent = members[fit.dependent]
            independent = members[fit.independents[0]]
            names = (self.names[dependent], self.names[independent])
            found.append(
                Invariant(
                    family=self.family,
                    kind="linear",
                    point=context.point,
                    variables=names,
                    params={"a": slope, "b": intercept, "tolerance": fit.tolerance},
                    text=relation_text(names[0], [(slope, names[1])], intercept),
                    samples=fit.moments.count,
                    confidence=confidence(fit.moments.count),
                    condition=context.condition,
                    runs=context.runs,
                )
            )
        return found


def best_pair_fit(moments: Moments, spread: list[float], magnitude: list[float]) -> Fit | None:
    """The orientation to print among the accepted ones with a nonzero slope (``y`` on
    ``x`` first, see ``exact.choose``)."""
    fits = []
    for dependent, independent in ((1, 0), (0, 1)):
        fit = Fit(moments, dependent, [independent], spread, magnitude)
        if fit.accepted and fit.coefficients[0] != 0:
            fits.append(fit)
    return choose(fits)


@builds(LINEAR)
def _states(point: PointSpec, tunables: Tunables, enabled: frozenset[str]) -> States:
    return [LinearState(point.variables)]
