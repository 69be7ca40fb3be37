"""Bounds of numeric arrays through their derived variables (Daikon's sequence
invariants plus the thesis' average/standard deviation extension, section 3.4).

Subjects: the translator's derived variables ``len(a)``, ``avg(a)``, ``std(a)``, ``min(a)``
and ``max(a)``. Bookkeeping and justification are those of ``bounds`` (``common.Extremes``).

* ``len``: ``len(scan.ranges) >= 1``, ``len(a) == 720``, ... (``len >= 0`` is not stated);
* ``avg`` and ``std``: ``0.12 <= std(scan.ranges) <= 1.41`` (``std >= 0`` is not stated);
* ``min``: its lower bound is the elements' lower bound, ``scan.ranges[] elements >= 0.1``;
* ``max``: its upper bound is the elements' upper bound, ``scan.ranges[] elements <= 30``.

The invariants are bounds on the derived variable itself (``params`` ``min``/``max``), so
a checker evaluates them like any bound. When an array's element bounds coincide (every
element is the same constant, as in an unused covariance matrix) its ``avg`` and ``std``
bounds are implied and not reported.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

from imrosc.infer.builders import States, builds
from imrosc.infer.core import FinalizeContext, Invariant, Samples, Variable
from imrosc.infer.daikon.bounds import bound_invariant
from imrosc.infer.daikon.chunk import view
from imrosc.infer.daikon.common import Extremes
from imrosc.ir import Tunables
from imrosc.runtime.families import ARRAY
from imrosc.translate.points import PointSpec


def element_name(variable: Variable) -> str:
    """The array a derived variable describes: ``min(scan.ranges)`` -> ``scan.ranges``."""
    prefix = f"{variable.derived}("
    if variable.name.startswith(prefix) and variable.name.endswith(")"):
        return variable.name[len(prefix) : -1]
    return variable.path or variable.name


class ArrayState:
    """Mergeable state of the array family at one point."""

    family = ARRAY

    def __init__(self, variables: Sequence[Variable]) -> None:
        self.variables = tuple(v for v in variables if v.derived is not None and v.numeric)
        self.extremes = Extremes(len(self.variables))

    def update(self, samples: Samples) -> None:
        """Consume one chunk."""
        if not self.variables or len(samples) == 0:
            return
        chunk = view(samples)
        self.extremes.update([chunk.summary(v.name) for v in self.variables])

    def end_run(self) -> None:
        """Nothing spans runs."""

    def merge(self, other: Any) -> None:
        """Absorb a state whose samples come after ours."""
        if not isinstance(other, ArrayState):
            raise TypeError(f"cannot merge {type(other).__name__} into array")
        self.extremes.merge(other.extremes)

    def finalize(self, context: FinalizeContext) -> list[Invariant]:
        """The justified array invariants."""
        found: list[tuple[Variable, Invariant]] = []
        for i, variable in enumerate(self.variables):
            derived = variable.derived
            subject = None
            lower = upper = True
            if derived == "min":
                upper = False
                subject = f"{element_name(variable)}[] elements"
            elif derived == "max":
                lower = False
                subject = f"{element_name(variable)}[] elements"
            invariant = bound_invariant(
                self.family,
                variable,
                self.extremes,
                i,
                context,
                lower=lower,
                upper=upper,
                subject=subject,
                skip_zero_lower=derived in ("len", "std"),
            )
            if invariant is not None:
                found.append((variable, invariant))
        lows = {_array(v): inv.params["min"] for v, inv in found if v.derived == "min"}
        highs = {_array(v): inv.params["max"] for v, inv in found if v.derived == "max"}
        constant = {key for key, low in lows.items() if highs.get(key) == low}
        return [
            invariant
            for variable, invariant in found
            if not (variable.derived in ("avg", "std") and _array(variable) in constant)
        ]


def _array(variable: Variable) -> tuple[str, str]:
    return variable.topic, element_name(variable)


@builds(ARRAY)
def _states(point: PointSpec, tunables: Tunables, enabled: frozenset[str]) -> States:
    return [ArrayState(point.variables)]
