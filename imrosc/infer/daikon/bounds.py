"""Bounds ``x >= a``, ``x <= b``, ``a <= x <= b`` of numeric variables (Daikon's
LowerBound/UpperBound).

Subjects: numeric, non-derived variables except bools (their range is their type) and
``time`` stamps. The state keeps each variable's count, minimum, maximum and where the
current minimum/maximum first occurred (``common.Extremes``): exact under any chunking.

Variables that follow the leader of an equality class (``x == x_copy``, when the equality
family is on) get no bounds of their own: the leader's bounds and the equality imply them.

A variable of the point's own topic that was never NaN nor infinite in training has
``finite: true`` in its bounds' params: the runtime then reports a NaN or an infinite value
as a violation of the bound (NaN compares false with any number, so it would otherwise pass).

Justification: a bound's ``n`` counts the samples since the first occurrence of its final
value (the sample that set it counts); it is reported when ``1 - 2**-n`` exceeds the
confidence limit. Both bounds justified print as one ``range`` invariant (confidence of
the weaker). Suppressed: bounds of a variable whose one-of invariant is reported (a set of
at most 3 values implies its bounds; when the one-of family is off a constant prints as
``x == c``), ``x >= 0`` of unsigned integers, infinite bounds (no constraint).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any

from imrosc.infer.builders import States, builds
from imrosc.infer.core import FinalizeContext, Invariant, Samples, Variable, confidence
from imrosc.infer.daikon.chunk import view
from imrosc.infer.daikon.common import Distinct, Extremes, equality_classes, number_text
from imrosc.infer.daikon.pairs import PairFlags
from imrosc.ir import Tunables
from imrosc.runtime.families import BOUNDS, EQUALITY, ONE_OF
from imrosc.translate.points import PointSpec


class BoundsState:
    """Mergeable state of the bounds family at one point."""

    family = BOUNDS

    def __init__(self, variables: Sequence[Variable], *, one_of: bool, equality: bool) -> None:
        self.variables = tuple(
            v
            for v in variables
            if v.numeric and v.derived is None and v.type not in ("bool", "time")
        )
        self.extremes = Extremes(len(self.variables))
        self.distinct = Distinct(len(self.variables)) if one_of else None
        self.flags = PairFlags(len(self.variables), "equality") if equality else None

    def update(self, samples: Samples) -> None:
        """Consume one chunk."""
        if not self.variables or len(samples) == 0:
            return
        chunk = view(samples)
        names = [v.name for v in self.variables]
        summaries = [chunk.summary(name) for name in names]
        self.extremes.update(summaries)
        if self.distinct is not None:
            self.distinct.update(chunk.columns(names), summaries)
        if self.flags is not None:
            self.flags.update(chunk.columns(names), summaries)

    def end_run(self) -> None:
        """Nothing spans runs."""

    def merge(self, other: Any) -> None:
        """Absorb a state whose samples come after ours."""
        if not isinstance(other, BoundsState):
            raise TypeError(f"cannot merge {type(other).__name__} into bounds")
        self.extremes.merge(other.extremes)
        if self.distinct is not None and other.distinct is not None:
            self.distinct.merge(other.distinct)
        if self.flags is not None and other.flags is not None:
            self.flags.merge(other.flags)

    def nan_counts(self) -> dict[str, int]:
        """NaN samples skipped per variable."""
        return {v.name: int(n) for v, n in zip(self.variables, self.extremes.nan, strict=True)}

    def finalize(self, context: FinalizeContext) -> list[Invariant]:
        """The justified bounds."""
        found: list[Invariant] = []
        followers: set[int] = set()
        if self.flags is not None:
            constant = self.extremes.constant()
            eligible = [not bool(c) for c in constant]
            classes = equality_classes(
                len(self.variables), self.flags.equal_pairs(context), eligible
            )
            followers = {v for members in classes for v in members[1:]}
        for i, variable in enumerate(self.variables):
            if i in followers:
                continue
            if self.distinct is not None and self.distinct.reported(i, context):
                continue
            invariant = bound_invariant(
                self.family, variable, self.extremes, i, context, lower=True, upper=True
            )
            if invariant is not None:
                found.append(invariant)
        return found


def bound_invariant(
    family: str,
    variable: Variable,
    extremes: Extremes,
    i: int,
    context: FinalizeContext,
    *,
    lower: bool,
    upper: bool,
    subject: str | None = None,
    skip_zero_lower: bool = False,
) -> Invariant | None:
    """The bounds invariant of variable ``i`` (None when nothing is justified)."""
    count = int(extremes.count[i])
    if count == 0:
        return None
    lo, hi = float(extremes.lo[i]), float(extremes.hi[i])
    n_lo = count - int(extremes.lo_first[i])
    n_hi = count - int(extremes.hi_first[i])
    use_lo = lower and context.justified(n_lo) and not math.isinf(lo)
    use_hi = upper and context.justified(n_hi) and not math.isinf(hi)
    if use_lo and lo == 0 and (skip_zero_lower or variable.type == "uint"):
        use_lo = False
    shown = subject if subject is not None else variable.name
    kind_of = variable.type
    # never NaN nor infinite in training: a non-finite value breaks the bound as well (a
    # NaN compares false with any bound); only the point's own fields, since a relative
    # topic's value is missing until its first message
    finite = (
        variable.trigger and int(extremes.nan[i]) == 0 and math.isfinite(lo) and math.isfinite(hi)
    )
    extra = {"finite": True} if finite and family == BOUNDS else {}
    if use_lo and use_hi:
        n = min(n_lo, n_hi)
        if lo == hi:
            text = f"{shown} == {number_text(lo, kind_of)}"
        else:
            text = f"{number_text(lo, kind_of)} <= {shown} <= {number_text(hi, kind_of)}"
        params = {"min": lo, "max": hi, **extra}
        return _make(family, "range", variable, params, text, count, n, context)
    if use_lo:
        text = f"{shown} >= {number_text(lo, kind_of)}"
        return _make(family, "lower", variable, {"min": lo, **extra}, text, count, n_lo, context)
    if use_hi:
        text = f"{shown} <= {number_text(hi, kind_of)}"
        return _make(family, "upper", variable, {"max": hi, **extra}, text, count, n_hi, context)
    return None


def _make(
    family: str,
    kind: str,
    variable: Variable,
    params: dict[str, Any],
    text: str,
    count: int,
    stable: int,
    context: FinalizeContext,
) -> Invariant:
    return Invariant(
        family=family,
        kind=kind,
        point=context.point,
        variables=(variable.name,),
        params=params,
        text=text,
        samples=count,
        confidence=confidence(stable),
        condition=context.condition,
        runs=context.runs,
    )


@builds(BOUNDS)
def _states(point: PointSpec, tunables: Tunables, enabled: frozenset[str]) -> States:
    return [BoundsState(point.variables, one_of=ONE_OF in enabled, equality=EQUALITY in enabled)]
