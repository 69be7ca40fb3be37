"""String one-of ``mode one of {"a", "b"}`` / ``mode == "a"`` (Daikon's OneOfString).

Subjects: string, non-derived variables; values that are not ``str`` (missing) are skipped.
Same bookkeeping and justification as ``one_of`` with the same limit of 3 values.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

from imrosc.infer.builders import States, builds
from imrosc.infer.core import FinalizeContext, Invariant, Samples, Variable
from imrosc.infer.daikon.common import Distinct, string_text
from imrosc.ir import Tunables
from imrosc.runtime.families import STRING_ONE_OF
from imrosc.translate.points import PointSpec


class StringOneOfState:
    """Mergeable state of the string-one-of family at one point."""

    family = STRING_ONE_OF

    def __init__(self, variables: Sequence[Variable]) -> None:
        self.variables = tuple(v for v in variables if v.type == "string" and v.derived is None)
        self.distinct = Distinct(len(self.variables))

    def update(self, samples: Samples) -> None:
        """Consume one chunk."""
        if not self.variables or len(samples) == 0:
            return
        self.distinct.update_strings([samples.column(v.name) for v in self.variables])

    def end_run(self) -> None:
        """Nothing spans runs."""

    def merge(self, other: Any) -> None:
        """Absorb a state whose samples come after ours."""
        if not isinstance(other, StringOneOfState):
            raise TypeError(f"cannot merge {type(other).__name__} into string-one-of")
        self.distinct.merge(other.distinct)

    def finalize(self, context: FinalizeContext) -> list[Invariant]:
        """The justified string one-of invariants."""
        found: list[Invariant] = []
        for i, variable in enumerate(self.variables):
            if not self.distinct.reported(i, context):
                continue
            values = sorted(self.distinct.values[i])
            shown = [string_text(v) for v in values]
            found.append(self.distinct.invariant(i, variable, self.family, shown, context))
        return found


@builds(STRING_ONE_OF)
def _states(point: PointSpec, tunables: Tunables, enabled: frozenset[str]) -> States:
    return [StringOneOfState(point.variables)]
