"""Order ``x < y`` and ``x <= y`` between numeric variables (Daikon's IntLessThan etc.).

Subjects: pairs of non-constant numeric, non-derived variables that lead their equality
class (``x == y`` belongs to the equality family). The state keeps exact comparison flags
of every pair (``pairs.PairFlags`` in order mode): a pair dies once it saw both ``x < y``
and ``x > y``; NaN rows are skipped; exact under any chunking.

Reported: ``x < y`` when no joint sample had ``x >= y``, ``x <= y`` when some had
``x == y`` and none ``x > y`` (printed with ``<``, the smaller variable first), with
justified support (``1 - 2**-n``, ``n`` the joint samples). Suppressed when the bounds
already imply it (``max x < min y``, or ``max x <= min y`` for ``<=``) and the bounds family
is on. ``!=`` between pairs is never reported (Daikon's float ``!=`` is mostly noise).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from imrosc.infer.builders import States, builds
from imrosc.infer.core import FinalizeContext, Invariant, Variable, confidence
from imrosc.infer.daikon.pairs import PairRelationState
from imrosc.ir import Tunables
from imrosc.runtime.families import BOUNDS, ORDER
from imrosc.translate.points import PointSpec


class OrderState(PairRelationState):
    """Mergeable state of the order family at one point."""

    family = ORDER
    mode = "order"

    def __init__(self, variables: Sequence[Variable], *, bounds: bool) -> None:
        super().__init__(variables)
        self.bounds = bounds

    def finalize(self, context: FinalizeContext) -> list[Invariant]:
        """The justified order relations."""
        size = len(self.variables)
        classes = self.classes(context)
        leaders = np.zeros(size, dtype=bool)
        for members in classes:
            leaders[members[0]] = True
        flags = self.flags
        lo, hi = self.extremes.lo, self.extremes.hi
        found: list[Invariant] = []
        for p in np.flatnonzero(flags.alive() & (flags.lt ^ flags.gt)):
            i, j = int(flags.first[p]), int(flags.second[p])
            if not (leaders[i] and leaders[j]):
                continue
            count = int(flags.count[p])
            if not context.justified(count):
                continue
            small, large = (i, j) if flags.lt[p] else (j, i)
            strict = not bool(flags.eq[p])
            if self.bounds and (hi[small] < lo[large] or (not strict and hi[small] <= lo[large])):
                continue
            kind = "<" if strict else "<="
            names = (self.variables[small].name, self.variables[large].name)
            found.append(
                Invariant(
                    family=self.family,
                    kind=kind,
                    point=context.point,
                    variables=names,
                    params={},
                    text=f"{names[0]} {kind} {names[1]}",
                    samples=count,
                    confidence=confidence(count),
                    condition=context.condition,
                    runs=context.runs,
                )
            )
        return found


@builds(ORDER)
def _states(point: PointSpec, tunables: Tunables, enabled: frozenset[str]) -> States:
    return [OrderState(point.variables, bounds=BOUNDS in enabled)]
