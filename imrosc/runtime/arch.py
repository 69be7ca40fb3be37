"""Architecture checks: the publishers, subscribers and servers of a snapshot (Algorithm 7).

For the current set ``S`` of a resource, ``max_*`` is broken by an unexpected node
(``S - max``) and ``min_*`` by a missing one (``min - S``). Reports are edge-triggered: a
broken invariant is reported again only when what breaks it changes.

>>> check = ArchChecks([{"id": "i1", "family": "architecture", "kind": "max_pubs",
...     "text": "max_pubs(/t) = {/a}", "variables": ["pubs(/t)"],
...     "params": {"resource": "/t", "nodes": ["/a"]}}], "d")
>>> [v.observed for v in check.check(1.0, {"pub": {"/t": frozenset({"/a", "/b"})}})]
[['/b']]
>>> check.check(2.0, {"pub": {"/t": frozenset({"/a", "/b"})}})
[]
"""

from __future__ import annotations

from typing import Any, Dict, FrozenSet, List, Mapping, Optional, Sequence, Tuple

from .violation import Violation

Snapshot = Mapping[str, Mapping[str, FrozenSet[str]]]
"""Kind (``pub``, ``sub``, ``srv``) to resource to node names."""

_KINDS = {"pubs": "pub", "subs": "sub", "srvs": "srv"}


class ArchChecks:
    """The architecture invariants of one point."""

    def __init__(self, invariants: Sequence[Mapping[str, Any]], point: str) -> None:
        self.point = point
        self.items: List[Tuple[str, str, bool, FrozenSet[str], Mapping[str, Any]]] = []
        for inv in invariants:
            if inv["family"] != "architecture":
                continue
            bound, _, noun = inv["kind"].partition("_")
            params = inv["params"]
            self.items.append(
                (_KINDS[noun], params["resource"], bound == "max", frozenset(params["nodes"]), inv)
            )
        self.reported: Dict[str, Optional[FrozenSet[str]]] = {}

    def reset(self) -> None:
        """A new run."""
        self.reported = {}

    def check(
        self, time: float, snapshot: Snapshot, kinds: Sequence[str] = ("pub", "sub", "srv")
    ) -> List[Violation]:
        """Violations of ``snapshot``; only the invariants of ``kinds`` are checked (a bag
        without architecture records tells publishers only)."""
        found: List[Violation] = []
        for kind, resource, is_max, nodes, inv in self.items:
            if kind not in kinds:
                continue
            current = snapshot.get(kind, {}).get(resource, frozenset())
            wrong = current - nodes if is_max else nodes - current
            before = self.reported.get(inv["id"])
            self.reported[inv["id"]] = wrong or None
            if not wrong or wrong == before:
                continue
            expected = ("only " if is_max else "at least ") + ("{" + ", ".join(sorted(nodes)) + "}")
            found.append(
                Violation(
                    time,
                    self.point,
                    inv["id"],
                    inv["family"],
                    inv["kind"],
                    inv["text"],
                    sorted(wrong),
                    expected,
                )
            )
        return found
