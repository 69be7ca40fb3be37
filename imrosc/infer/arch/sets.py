"""Architecture invariants: the most and fewest nodes using a resource (thesis 3.4.3, Alg. 7).

An architecture point's samples are snapshots of the ROS graph. Each variable is a set
column named ``pubs(/topic)``, ``subs(/topic)`` or ``srvs(/service)`` holding, per snapshot,
the ``frozenset`` of node names that publish, subscribe or serve (the empty set when the
resource is absent from the snapshot; ``None`` when the snapshot cannot tell, which is no
sample of that resource). Over all snapshots the maximum set is the union and
the minimum set the intersection (Algorithm 7)::

    max_pubs(/a/subject_pose) = {/a/uav}
    min_subs(/a/subject_pose) = {/a/car_ctrl, /a/launch_ctrl, /a/pid_ctrl}

Justification (thesis 3.5): ``1 - 2**-n`` with ``n`` the snapshots since the set last
changed. A set changes when a snapshot adds a node to the union (max) or lacks a node of the
intersection (min); the first snapshot initialises both (``n`` counts it).

Exact merging: per variable the state keeps the snapshot count and, per node ever seen, the
position of the snapshot where it first appeared and of the first snapshot that lacked it.
From those the union, the intersection and both last-change positions follow, and two states
of consecutive runs combine into the state one pass over both would have built.

>>> from imrosc.infer.core import Variable
>>> var = Variable("pubs(/t)", "set")
>>> state = ArchitectureState((var,))
>>> state.observe("pubs(/t)", [frozenset({"/n1"}), frozenset({"/n1", "/n2"})])
>>> [sorted(nodes) for nodes in state.sets("pubs(/t)")]
[['/n1', '/n2'], ['/n1']]
"""

from __future__ import annotations

import re
from collections.abc import Iterable, Sequence
from dataclasses import dataclass, field
from typing import Any

from imrosc.infer.builders import States, builds
from imrosc.infer.core import (
    FamilyState,
    FinalizeContext,
    Invariant,
    Samples,
    Variable,
    confidence,
)
from imrosc.ir import Tunables
from imrosc.runtime.families import ARCHITECTURE
from imrosc.translate.points import PointSpec

__all__ = ["FAMILY", "RESOURCE_KINDS", "ArchitectureState", "make_states", "parse_variable"]

FAMILY = ARCHITECTURE
RESOURCE_KINDS = ("pubs", "subs", "srvs")
"""Variable name prefixes: publishers and subscribers of a topic, servers of a service."""

_NAME = re.compile(r"^(pubs|subs|srvs)\((.+)\)$")


def parse_variable(name: str) -> tuple[str, str] | None:
    """``("pubs", "/t")`` for ``pubs(/t)``; ``None`` for a name that is no resource set."""
    match = _NAME.match(name)
    if match is None:
        return None
    return match.group(1), match.group(2)


@dataclass
class _NodeSets:
    """Snapshot history of one resource, summarised exactly (see the module docstring)."""

    count: int = 0
    first_seen: dict[str, int] = field(default_factory=dict)
    first_absent: dict[str, int] = field(default_factory=dict)

    def add(self, nodes: frozenset[str]) -> None:
        position = self.count
        for node in nodes:
            if node not in self.first_seen:
                self.first_seen[node] = position
                if position > 0:
                    self.first_absent[node] = 0
        for node in self.first_seen:
            if node not in nodes and node not in self.first_absent:
                self.first_absent[node] = position
        self.count += 1

    def merge(self, other: _NodeSets) -> None:
        if other.count == 0:
            return
        offset = self.count
        if offset == 0:
            self.first_seen = dict(other.first_seen)
            self.first_absent = dict(other.first_absent)
            self.count = other.count
            return
        for node, position in other.first_seen.items():
            if node not in self.first_seen:
                self.first_seen[node] = offset + position
                self.first_absent[node] = 0
        for node in self.first_seen:
            if node in self.first_absent:
                continue
            if node not in other.first_seen:
                self.first_absent[node] = offset
            elif node in other.first_absent:
                self.first_absent[node] = offset + other.first_absent[node]
        self.count += other.count

    def maximum(self) -> frozenset[str]:
        return frozenset(self.first_seen)

    def minimum(self) -> frozenset[str]:
        return frozenset(
            node
            for node, position in self.first_seen.items()
            if position == 0 and node not in self.first_absent
        )

    def max_changed(self) -> int:
        """Position of the last snapshot that grew the union."""
        return max(self.first_seen.values(), default=0)

    def min_changed(self) -> int:
        """Position of the last snapshot that shrank the intersection."""
        return max(
            (
                self.first_absent[node]
                for node, position in self.first_seen.items()
                if position == 0 and node in self.first_absent
            ),
            default=0,
        )


def _as_set(value: Any) -> frozenset[str]:
    if value is None:
        return frozenset()
    if isinstance(value, frozenset):
        return value
    if isinstance(value, str):
        raise TypeError(f"architecture cell must be a set of node names, not the string {value!r}")
    return frozenset(str(node) for node in value)


def format_nodes(nodes: Iterable[str]) -> str:
    """``{/n1, /n2}``, sorted."""
    return "{" + ", ".join(sorted(nodes)) + "}"


class ArchitectureState:
    """Minimum and maximum node sets of every resource variable of one architecture point."""

    family = FAMILY

    def __init__(self, variables: Sequence[Variable]) -> None:
        self.names: tuple[str, ...] = tuple(
            v.name for v in variables if v.type == "set" and parse_variable(v.name) is not None
        )
        self.resources: dict[str, _NodeSets] = {name: _NodeSets() for name in self.names}

    def observe(self, name: str, cells: Iterable[Any]) -> None:
        """Add snapshots of one variable (in time order); a ``None`` cell is a snapshot that
        does not know the resource (a bag without records, before any publisher of the
        topic published) and counts for nothing."""
        history = self.resources[name]
        for cell in cells:
            if cell is not None:
                history.add(_as_set(cell))

    def sets(self, name: str) -> tuple[frozenset[str], frozenset[str]]:
        """(maximum, minimum) node sets of a variable so far."""
        history = self.resources[name]
        return history.maximum(), history.minimum()

    def update(self, samples: Samples) -> None:
        for name in self.names:
            if name in samples.columns:
                self.observe(name, samples.column(name).tolist())

    def end_run(self) -> None:
        """Snapshots carry no state from one to the next: nothing to close."""

    def merge(self, other: Any) -> None:
        if not isinstance(other, ArchitectureState):
            raise TypeError(f"cannot merge {type(other).__name__} into ArchitectureState")
        for name in other.names:
            if name not in self.resources:
                self.names = (*self.names, name)
                self.resources[name] = _NodeSets()
            self.resources[name].merge(other.resources[name])

    def finalize(self, context: FinalizeContext) -> list[Invariant]:
        found: list[Invariant] = []
        for name in self.names:
            history = self.resources[name]
            if history.count == 0:
                continue
            parsed = parse_variable(name)
            assert parsed is not None
            kind, resource = parsed
            for bound, nodes, changed in (
                ("max", history.maximum(), history.max_changed()),
                ("min", history.minimum(), history.min_changed()),
            ):
                since = history.count - changed
                if not context.justified(since):
                    continue
                label = f"{bound}_{kind}"
                found.append(
                    Invariant(
                        family=FAMILY,
                        kind=label,
                        point=context.point,
                        variables=(name,),
                        params={"resource": resource, "nodes": sorted(nodes)},
                        text=f"{label}({resource}) = {format_nodes(nodes)}",
                        samples=history.count,
                        confidence=confidence(since),
                        condition=context.condition,
                        runs=context.runs,
                    )
                )
        return found


def make_states(
    variables: Sequence[Variable], tunables: Tunables, families: frozenset[str]
) -> list[FamilyState]:
    """The architecture family's state for a point, if enabled and the point has set variables.

    ``tunables`` is accepted for a uniform factory signature; the family has no tunable.
    """
    del tunables
    if FAMILY not in families:
        return []
    state = ArchitectureState(variables)
    return [state] if state.names else []


@builds(FAMILY)
def _states(point: PointSpec, tunables: Tunables, enabled: frozenset[str]) -> States:
    return make_states(point.variables, tunables, enabled)
