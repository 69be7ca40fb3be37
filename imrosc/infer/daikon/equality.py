"""Equality sets ``a == b == c`` of numeric variables (Daikon's equality sets).

Subjects: numeric, non-derived variables that are not constant (a constant is reported by
one-of, and two equal constants are implied by it). The state keeps exact comparison flags
of every pair (``pairs.PairFlags`` in equality mode): a pair dies at its first sample with
``x != y``; NaN rows are skipped.

Classes are greedy cliques of pairs equal on every joint sample with justified support
(``1 - 2**-n``, ``n`` the joint samples), in variable order; a class is reported once, its
first variable leading, and the order, linear and ternary families only relate leaders.
"""

from __future__ import annotations

from imrosc.infer.builders import States, builds
from imrosc.infer.core import FinalizeContext, Invariant, confidence
from imrosc.infer.daikon.common import pair_index
from imrosc.infer.daikon.pairs import PairRelationState
from imrosc.ir import Tunables
from imrosc.runtime.families import EQUALITY
from imrosc.translate.points import PointSpec


class EqualityState(PairRelationState):
    """Mergeable state of the equality family at one point."""

    family = EQUALITY
    mode = "equality"

    def finalize(self, context: FinalizeContext) -> list[Invariant]:
        """One invariant per equality class of two or more variables."""
        size = len(self.variables)
        classes = self.classes(context)
        found: list[Invariant] = []
        for members in classes:
            if len(members) < 2:
                continue
            support = min(
                int(self.flags.count[pair_index(members[0], v, size)]) for v in members[1:]
            )
            names = tuple(self.variables[v].name for v in members)
            found.append(
                Invariant(
                    family=self.family,
                    kind="==",
                    point=context.point,
                    variables=names,
                    params={},
                    text=" == ".join(names),
                    samples=support,
                    confidence=confidence(support),
                    condition=context.condition,
                    runs=context.runs,
                )
            )
        return found


@builds(EQUALITY)
def _states(point: PointSpec, tunables: Tunables, enabled: frozenset[str]) -> States:
    return [EqualityState(point.variables)]
