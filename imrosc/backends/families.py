"""Which invariant template families apply to which kind of program point (thesis 3.4)."""

from __future__ import annotations

from imrosc import ir

DAIKON = (
    "bounds",
    "one-of",
    "non-zero",
    "equality",
    "order",
    "linear",
    "ternary",
    "string-one-of",
    "array",
)
"""Daikon's default families (thesis 3.4), plus the array average/std extension."""

TIME = ("frequency", "variance", "rate")
"""Time-related families (thesis 3.4.1)."""


def families(point: ir.Point) -> tuple[str, ...]:
    """The template families inference instantiates at ``point``."""
    if isinstance(point, ir.PublishPoint):
        return (*DAIKON, *TIME, "polygon")
    if isinstance(point, ir.CallPoint):
        return (*DAIKON, "polygon")
    if isinstance(point, ir.ParamPoint):
        return ("bounds", "one-of", "string-one-of")
    if isinstance(point, ir.ArchPoint):
        return ("architecture",)
    return ("interval", "pattern") if point.patterns else ("interval",)
