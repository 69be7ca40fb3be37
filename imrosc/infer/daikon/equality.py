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

from collections.abc import Sequence
from typing import Any

from imrosc.infer.core import FinalizeContext, Invariant, Samples, Variable, confidence
from imrosc.infer.daikon.chunk import view
from imrosc.infer.daikon.common import Extremes, equality_classes, pair_index, relation_variables
from imrosc.infer.daikon.pairs import PairFlags


class EqualityState:
    """Mergeable state of the equality family at one point."""

    family = "equality"

    def __init__(self, variables: Sequence[Variable]) -> None:
        self.variables = relation_variables(variables)
        self.extremes = Extremes(len(self.variables))
        self.flags = PairFlags(len(self.variables), "equality")

    def update(self, samples: Samples) -> None:
        """Consume one chunk."""
        if not self.variables or len(samples) == 0:
            return
        chunk = view(samples)
        names = [v.name for v in self.variables]
        summaries = [chunk.summary(name) for name in names]
        self.extremes.update(summaries)
        self.flags.update(chunk.columns(names), summaries)

    def end_run(self) -> None:
        """Nothing spans runs."""

    def merge(self, other: Any) -> None:
        """Absorb a state whose samples come after ours."""
        if not isinstance(other, EqualityState):
            raise TypeError(f"cannot merge {type(other).__name__} into equality")
        self.extremes.merge(other.extremes)
        self.flags.merge(other.flags)

    def finalize(self, context: FinalizeContext) -> list[Invariant]:
        """One invariant per equality class of two or more variables."""
        size = len(self.variables)
        constant = self.extremes.constant()
        eligible = [not bool(constant[v]) for v in range(size)]
        classes = equality_classes(size, self.flags.equal_pairs(context), eligible)
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
