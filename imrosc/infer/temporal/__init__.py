"""Temporal families (thesis 3.4.4): ordered-pair intervals and user-defined patterns.

A temporal point's samples have one string column ``event`` (the event id of the point's
scope, ``"a"``) and the event's time; the events of a run arrive in time order.
:func:`make_temporal_states` builds the states of the enabled families for one point.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence

from imrosc.infer.builders import States, builds
from imrosc.infer.core import FamilyState
from imrosc.infer.temporal.dfa import Dfa, compile_pattern, dfa_from_json
from imrosc.infer.temporal.interval import IntervalState, format_multiset
from imrosc.infer.temporal.pattern import Machine, PatternState
from imrosc.ir import Tunables
from imrosc.runtime.families import INTERVAL, PATTERN
from imrosc.translate.points import PointSpec

__all__ = [
    "Dfa",
    "IntervalState",
    "Machine",
    "PatternState",
    "compile_pattern",
    "dfa_from_json",
    "format_multiset",
    "make_temporal_states",
]

ConcretePatterns = Sequence[tuple[Mapping[str, str], str]]


def make_temporal_states(
    events: tuple[str, ...],
    patterns: Sequence[tuple[str, ConcretePatterns]],
    max_interval: float,
    max_events: int,
    families: frozenset[str],
) -> list[FamilyState]:
    """The ``interval`` and ``pattern`` states of a temporal point, for the enabled families.

    ``patterns`` lists each ``<pattern>``'s text with its concrete patterns, each a binding
    (placeholder -> event id) and the concrete text (the plan's ``patterns[].concrete``).
    Raise ``ValueError`` for a concrete text that is no pattern over ``events``.
    """
    states: list[FamilyState] = []
    if INTERVAL in families and len(events) >= 2:
        states.append(IntervalState(events, max_interval, max_events))
    if PATTERN in families and patterns:
        state = PatternState(events, patterns)
        if state.machines:
            states.append(state)
    return states


def _point_states(point: PointSpec, enabled: frozenset[str]) -> States:
    patterns = [
        (p["text"], [(c["binding"], c["text"]) for c in p["concrete"]]) for p in point.patterns
    ]
    events = tuple(ident for ident, _, _ in point.events)
    return make_temporal_states(events, patterns, point.max_interval, point.max_events, enabled)


@builds(INTERVAL)
def _intervals(point: PointSpec, tunables: Tunables, enabled: frozenset[str]) -> States:
    return _point_states(point, frozenset({INTERVAL}))


@builds(PATTERN)
def _patterns(point: PointSpec, tunables: Tunables, enabled: frozenset[str]) -> States:
    return _point_states(point, frozenset({PATTERN}))
