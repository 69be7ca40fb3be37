"""Which invariant template families apply to which kind of program point (thesis 3.4):
the family catalog's (:mod:`imrosc.runtime.families`) for the IR's points."""

from __future__ import annotations

from imrosc import ir
from imrosc.runtime.families import ARCH, CALL, PARAM, PUBLISH, TEMPORAL, for_point


def families(point: ir.Point) -> tuple[str, ...]:
    """The template families inference instantiates at ``point``."""
    if isinstance(point, ir.PublishPoint):
        return point.families or for_point(PUBLISH)
    if isinstance(point, ir.CallPoint):
        return for_point(CALL)
    if isinstance(point, ir.ParamPoint):
        return for_point(PARAM)
    if isinstance(point, ir.ArchPoint):
        return for_point(ARCH)
    return for_point(TEMPORAL, patterns=bool(point.patterns))
