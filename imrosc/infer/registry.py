"""Which module builds the states of which template family."""

from __future__ import annotations

from imrosc.infer import arch, daikon, polygon, temporal, timed
from imrosc.infer.core import FamilyState
from imrosc.ir import Tunables
from imrosc.runtime.families import GROUPS, POLYGON, group_of, in_group
from imrosc.translate.points import PointSpec

__all__ = ["DAIKON_FAMILIES", "FAMILY_GROUPS", "TIME_FAMILIES", "group_of", "make_point_states"]

FAMILY_GROUPS = {group: frozenset(in_group(group)) for group in GROUPS}
"""How summaries group families (:data:`imrosc.runtime.families.GROUPS`)."""
DAIKON_FAMILIES = FAMILY_GROUPS["default"]
TIME_FAMILIES = FAMILY_GROUPS["time-related"]


def make_point_states(spec: PointSpec, tunables: Tunables) -> list[FamilyState]:
    """Fresh states of every family the job enables at this point."""
    enabled = frozenset(spec.families)
    if spec.kind == "temporal":
        patterns = [
            (p["text"], [(c["binding"], c["text"]) for c in p["concrete"]]) for p in spec.patterns
        ]
        events = tuple(ident for ident, _, _ in spec.events)
        return temporal.make_temporal_states(
            events, patterns, spec.max_interval, spec.max_events, enabled
        )
    if spec.kind == "arch":
        return arch.make_states(spec.variables, tunables, enabled)
    states: list[FamilyState] = []
    states += daikon.make_states(spec.variables, tunables, enabled & DAIKON_FAMILIES)
    states += timed.make_states(spec.variables, tunables, enabled & TIME_FAMILIES)
    states += polygon.make_states(spec.variables, tunables, enabled & {POLYGON})
    return states
