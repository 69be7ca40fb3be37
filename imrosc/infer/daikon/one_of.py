"""One-of ``x one of {1, 2, 3}`` / ``x == c`` for numeric variables (Daikon's OneOfScalar).

Subjects: numeric, non-derived variables except ``time`` stamps. The state keeps each
variable's distinct values with the position of their first occurrence, up to Daikon's
limit of 3 (``common.Distinct``; more values falsify it for good): exact under any chunking.

Justification: ``n`` counts the samples since the first occurrence of the last new value.
A single value prints as ``x == c``. A bool whose set is {false, true} says nothing and is
not reported.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

from imrosc.infer.builders import States, builds
from imrosc.infer.core import FinalizeContext, Invariant, Samples, Variable
from imrosc.infer.daikon.chunk import view
from imrosc.infer.daikon.common import Distinct, number_text, unary_variables
from imrosc.ir import Tunables
from imrosc.runtime.families import ONE_OF
from imrosc.translate.points import PointSpec


class OneOfState:
    """Mergeable state of the one-of family at one point."""

    family = ONE_OF

    def __init__(self, variables: Sequence[Variable]) -> None:
        self.variables = unary_variables(variables)
        self.distinct = Distinct(len(self.variables))

    def update(self, samples: Samples) -> None:
        """Consume one chunk."""
        if not self.variables or len(samples) == 0:
            return
        chunk = view(samples)
        names = [v.name for v in self.variables]
        self.distinct.update(chunk.columns(names), [chunk.summary(name) for name in names])

    def end_run(self) -> None:
        """Nothing spans runs."""

    def merge(self, other: Any) -> None:
        """Absorb a state whose samples come after ours."""
        if not isinstance(other, OneOfState):
            raise TypeError(f"cannot merge {type(other).__name__} into one-of")
        self.distinct.merge(other.distinct)

    def finalize(self, context: FinalizeContext) -> list[Invariant]:
        """The justified one-of invariants."""
        found: list[Invariant] = []
        for i, variable in enumerate(self.variables):
            if not self.distinct.reported(i, context):
                continue
            values = sorted(self.distinct.values[i])
            if variable.type == "bool" and len(values) == 2:
                continue
            shown = [number_text(v, variable.type) for v in values]
            found.append(self.distinct.invariant(i, variable, self.family, shown, context))
        return found


@builds(ONE_OF)
def _states(point: PointSpec, tunables: Tunables, enabled: frozenset[str]) -> States:
    return [OneOfState(point.variables)]
