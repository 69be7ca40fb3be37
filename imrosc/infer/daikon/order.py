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
from typing import Any

import numpy as np

from imrosc.infer.core import FinalizeContext, Invariant, Samples, Variable, confidence
from imrosc.infer.daikon.chunk import view
from imrosc.infer.daikon.common import Extremes, equality_classes, relation_variables
from imrosc.infer.daikon.pairs import PairFlags


class OrderState:
    """Mergeable state of the order family at one point."""

    family = "order"

    def __init__(self, variables: Sequence[Variable], *, bounds: bool) -> None:
        self.variables = relation_variables(variables)
        self.bounds = bounds
        self.extremes = Extremes(len(self.variables))
        self.flags = PairFlags(len(self.variables), "order")

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
        if not isinstance(other, OrderState):
            raise TypeError(f"cannot merge {type(other).__name__} into order")
        self.extremes.merge(other.extremes)
        self.flags.merge(other.flags)

    def finalize(self, context: FinalizeContext) -> list[Invariant]:
        """The justified order relations."""
        size = len(self.variables)
        constant = self.extremes.constant()
        eligible = [not bool(constant[v]) for v in range(size)]
        classes = equality_classes(size, self.flags.equal_pairs(context), eligible)
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
