"""Architecture checks: the publishers, subscribers and servers of a snapshot (Algorithm 7).

For the current set ``S`` of a resource, ``max_*`` is broken by an unexpected node
(``S - max``; observed: the unexpected nodes) and ``min_*`` by a missing one (``min - S``;
observed: ``S``, the expected text names the missing nodes). Reports are edge-triggered: a
broken invariant is reported again only when what breaks it changes.

ROS 1 anonymous node names (``init_node(anonymous=True)``: ``/record_1553088502272947227``,
``/listener_12345_1553088502272``) change from run to run; :func:`node_name` writes each as
its base name and ``_*`` (``/record_*``), in the snapshots and in the invariants alike.

>>> check = ArchChecks([{"id": "i1", "family": "architecture", "kind": "max_pubs",
...     "text": "max_pubs(/t) = {/a}", "variables": ["pubs(/t)"],
...     "params": {"resource": "/t", "nodes": ["/a"]}}], "d")
>>> [v.observed for v in check.check(1.0, {"pub": {"/t": frozenset({"/a", "/b"})}})]
[['/b']]
>>> check.check(2.0, {"pub": {"/t": frozenset({"/a", "/b"})}})
[]
"""

from __future__ import annotations

import re
from typing import Any, Dict, FrozenSet, Iterable, List, Mapping, Optional, Sequence, Tuple

from .families import ARCHITECTURE
from .violation import Violation

Snapshot = Mapping[str, Mapping[str, FrozenSet[str]]]
"""Kind (``pub``, ``sub``, ``srv``) to resource to node names."""

_KINDS = {"pubs": "pub", "subs": "sub", "srvs": "srv"}

ANONYMOUS = re.compile(r"^(.*?[^/_])(?:_\d+)?_\d{10,}$")
"""A ROS 1 anonymous node name: a base, maybe ``_<pid>``, then ``_`` and 10 or more digits
(rospy ``_<pid>_<time in ms>``, roscpp and rosbag ``_<time in ns>``)."""
ANONYMOUS_SUFFIX = "_*"
"""What replaces the numbers of an anonymous name (``*`` is in no ROS name)."""
PLAYERS = frozenset({"/play_*", "/rosbag2_player"})
"""The nodes of ``rosbag play`` (``/play_<time>``, an anonymous name) and ``ros2 bag play``
(:func:`node_name` forms): they publish what a recording holds on behalf of the nodes that
published it then, so no publisher check refuses them."""


def node_name(name: str) -> str:
    """``name``, or the stable form of an anonymous name.

    >>> node_name("/record_1553088502272947227"), node_name("/listener_12345_1553088502272")
    ('/record_*', '/listener_*')
    >>> node_name("/cf1/crazyflie_server"), node_name("/camera_2"), node_name("/id_123456789")
    ('/cf1/crazyflie_server', '/camera_2', '/id_123456789')
    """
    match = ANONYMOUS.match(name)
    return name if match is None else match.group(1) + ANONYMOUS_SUFFIX


def node_names(names: Iterable[str]) -> FrozenSet[str]:
    """The set of :func:`node_name` of ``names``."""
    return frozenset(node_name(name) for name in names)


class ArchChecks:
    """The architecture invariants of one point."""

    def __init__(self, invariants: Sequence[Mapping[str, Any]], point: str) -> None:
        self.point = point
        self.items: List[Tuple[str, str, bool, FrozenSet[str], Mapping[str, Any]]] = []
        for inv in invariants:
            if inv["family"] != ARCHITECTURE:
                continue
            bound, _, noun = inv["kind"].partition("_")
            params = inv["params"]
            self.items.append(
                (_KINDS[noun], params["resource"], bound == "max", node_names(params["nodes"]), inv)
            )
        self.reported: Dict[str, Optional[FrozenSet[str]]] = {}

    def reset(self) -> None:
        """A new run."""
        self.reported = {}

    def check(
        self, time: float, snapshot: Snapshot, kinds: Sequence[str] = ("pub", "sub", "srv")
    ) -> List[Violation]:
        """Violations of ``snapshot``; only the invariants of ``kinds`` are checked.

        A source that tells publishers only (``kinds`` without ``sub``: a bag without
        architecture records, whose publishers are known from their first message) does
        not know a topic it does not list yet: that topic is not checked. Otherwise a
        resource the snapshot does not list has nobody."""
        found: List[Violation] = []
        unlisted_unknown = "sub" not in kinds
        for kind, resource, is_max, nodes, inv in self.items:
            if kind not in kinds:
                continue
            listed = snapshot.get(kind, {}).get(resource)
            if listed is None and unlisted_unknown:
                continue
            current = node_names(listed or ())
            wrong = current - nodes if is_max else nodes - current
            before = self.reported.get(inv["id"])
            self.reported[inv["id"]] = wrong or None
            if not wrong or wrong == before:
                continue
            found.append(self._violation(time, inv, is_max, nodes, current, wrong))
        return found

    def publisher_bounds(self, topic: str) -> List[FrozenSet[str]]:
        """The node sets of the ``max_pubs`` invariants of ``topic`` that name a publisher:
        the publishers each allows (none: this point does not tell who publishes on
        ``topic``). An empty set (the graph learnt no publisher of a topic whose messages
        were recorded: an incomplete graph) tells nobody apart, so it refuses no message."""
        return [nodes for nodes, _ in self._publisher_items(topic)]

    def _publisher_items(self, topic: str) -> List[Tuple[FrozenSet[str], Mapping[str, Any]]]:
        """The ``max_pubs`` invariants of ``topic`` that name a publisher, with their node
        sets."""
        return [
            (nodes, inv)
            for kind, resource, is_max, nodes, inv in self.items
            if kind == "pub" and is_max and resource == topic and nodes
        ]

    def intruder(self, time: float, topic: str, publisher: str) -> List[Violation]:
        """The violations of one message on ``topic`` from ``publisher``: one per
        ``max_pubs`` invariant of ``topic`` that does not allow it (observed: the publisher
        as it named itself). Unlike :meth:`check`, not edge-triggered: every message of an
        unknown publisher breaks the invariant (what the alarms make of that:
        :meth:`.alarms.AlarmTracker.intruder`). An invariant that allows nobody
        (:meth:`publisher_bounds`) refuses nobody.

        >>> check = ArchChecks([{"id": "i1", "family": "architecture", "kind": "max_pubs",
        ...     "text": "max_pubs(/t) = {/a}", "variables": ["pubs(/t)"],
        ...     "params": {"resource": "/t", "nodes": ["/a"]}}], "d")
        >>> [v.observed for v in check.intruder(1.0, "/t", "/b")], check.intruder(1.0, "/t", "/a")
        ([['/b']], [])
        """
        name = node_name(publisher)
        if name in PLAYERS:
            return []
        return [
            self._violation(time, inv, True, nodes, frozenset(), {publisher})
            for nodes, inv in self._publisher_items(topic)
            if name not in nodes
        ]

    def _violation(
        self,
        time: float,
        inv: Mapping[str, Any],
        is_max: bool,
        nodes: FrozenSet[str],
        current: FrozenSet[str],
        wrong: Iterable[str],
    ) -> Violation:
        """``max_*``: observed the unexpected nodes; ``min_*``: observed the nodes there,
        expected naming the missing ones."""
        if is_max:
            observed, expected = sorted(wrong), "only " + _braces(nodes)
        else:
            observed = sorted(current)
            expected = f"at least {_braces(nodes)} (missing {', '.join(sorted(wrong))})"
        return Violation(
            time, self.point, inv["id"], inv["family"], inv["kind"], inv["text"], observed, expected
        )


def _braces(nodes: Iterable[str]) -> str:
    """``{/a, /b}``, sorted."""
    return "{" + ", ".join(sorted(nodes)) + "}"
