"""Which module builds the states of which template family."""

from __future__ import annotations

from imrosc.backends.families import DAIKON, TIME
from imrosc.infer import arch, daikon, polygon, temporal, timed
from imrosc.infer.core import FamilyState
from imrosc.ir import Tunables
from imrosc.translate.points import PointSpec

DAIKON_FAMILIES = frozenset(DAIKON)
TIME_FAMILIES = frozenset(TIME)
FAMILY_GROUPS = {
    "default": DAIKON_FAMILIES,
    "time-related": TIME_FAMILIES,
    "polygon": frozenset({"polygon"}),
    "architecture": frozenset({"architecture"}),
    "temporal": frozenset({"interval", "pattern"}),
}
"""How summaries group families, as the thesis counts them (465 default, 362 time-related, ...)."""


def group_of(family: str) -> str:
    """The summary group of a family."""
    for group, members in FAMILY_GROUPS.items():
        if family in members:
            return group
    return family


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
    states += polygon.make_states(spec.variables, tunables, enabled & {"polygon"})
    return states
