"""Non-zero ``x != 0`` of integer variables (Daikon's NonZero).

Subjects: variables typed ``int`` (an unsigned or bool range that excludes 0 is stated by
its bounds). The state keeps count, minimum, maximum (``common.Extremes``), whether 0 was
seen and the distinct values up to 3: all exact under any chunking.

Reported, following Daikon, only when it says more than the bounds and one-of do and zero
would have been likely to appear by chance:

* 0 was never seen and ``min < 0 < max`` (otherwise the bounds imply it);
* the one-of invariant is not reported (a set without 0 implies it);
* confidence ``1 - (1 - 1/r)**n`` exceeds the limit, ``r = max - min + 1`` the number of
  integers in the range and ``n`` the samples: the chance that ``n`` uniform draws from
  the range all miss 0 is small.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any

import numpy as np

from imrosc.infer.builders import States, builds
from imrosc.infer.core import FinalizeContext, Invariant, Samples, Variable
from imrosc.infer.daikon.chunk import view
from imrosc.infer.daikon.common import Distinct, Extremes
from imrosc.ir import Tunables
from imrosc.runtime.families import NON_ZERO, ONE_OF
from imrosc.translate.points import PointSpec


class NonZeroState:
    """Mergeable state of the non-zero family at one point."""

    family = NON_ZERO

    def __init__(self, variables: Sequence[Variable], *, one_of: bool) -> None:
        self.variables = tuple(v for v in variables if v.type == "int" and v.derived is None)
        self.extremes = Extremes(len(self.variables))
        self.zero = [False] * len(self.variables)
        self.distinct = Distinct(len(self.variables)) if one_of else None

    def update(self, samples: Samples) -> None:
        """Consume one chunk."""
        if not self.variables or len(samples) == 0:
            return
        chunk = view(samples)
        names = [v.name for v in self.variables]
        columns = chunk.columns(names)
        summaries = [chunk.summary(name) for name in names]
        self.extremes.update(summaries)
        for i, column in enumerate(columns):
            inside = summaries[i].lo <= 0 <= summaries[i].hi
            self.zero[i] = self.zero[i] or (inside and bool(np.any(column == 0)))
        if self.distinct is not None:
            self.distinct.update(columns, summaries)

    def end_run(self) -> None:
        """Nothing spans runs."""

    def merge(self, other: Any) -> None:
        """Absorb a state whose samples come after ours."""
        if not isinstance(other, NonZeroState):
            raise TypeError(f"cannot merge {type(other).__name__} into non-zero")
        self.extremes.merge(other.extremes)
        self.zero = [a or b for a, b in zip(self.zero, other.zero, strict=True)]
        if self.distinct is not None and other.distinct is not None:
            self.distinct.merge(other.distinct)

    def finalize(self, context: FinalizeContext) -> list[Invariant]:
        """The justified non-zero invariants."""
        found: list[Invariant] = []
        for i, variable in enumerate(self.variables):
            count = int(self.extremes.count[i])
            lo, hi = float(self.extremes.lo[i]), float(self.extremes.hi[i])
            if count == 0 or self.zero[i] or not lo < 0 < hi:
                continue
            if self.distinct is not None and self.distinct.reported(i, context):
                continue
            span = hi - lo + 1
            if math.isinf(span):
                continue
            value = -math.expm1(count * math.log1p(-1.0 / span))
            if not value > context.tunables.confidence:
                continue
            found.append(
                Invariant(
                    family=self.family,
                    kind="!=0",
                    point=context.point,
                    variables=(variable.name,),
                    params={},
                    text=f"{variable.name} != 0",
                    samples=count,
                    confidence=value,
                    condition=context.condition,
                    runs=context.runs,
                )
            )
        return found


@builds(NON_ZERO)
def _states(point: PointSpec, tunables: Tunables, enabled: frozenset[str]) -> States:
    return [NonZeroState(point.variables, one_of=ONE_OF in enabled)]
