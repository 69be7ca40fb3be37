"""How a program point pairs its samples: the one record every stage shares.

The translator's point makes it (``imrosc.translate.points.PointSpec.pairing``, with the
conditions inference discovered), the invariants file holds it in each point
(``imrosc.invariants``), and whatever checks the file reads it back (the engine, replay, and
the monitor backends, which watch the names in it):

* ``inputs``: the input topics whose latest message joins each sample of a publish point;
* ``params``: the parameters whose latest values join it (publish and call points);
* ``events``: a temporal point's events, ``[id, kind, name]`` (``kind`` ``publish`` or
  ``call``, ``name`` the topic or service);
* ``filter``: the conditions of a conditional point, each a declared condition (``id``,
  ``topic``, ``expression``, ``fields``: the variable each field path of the expression
  names) or a discovered one (``variable`` and ``value``: the sample's own variable equals it).

:meth:`Pairing.to_json` and :meth:`Pairing.from_json` are its codec (the JSON keys are the
ones above; a missing key is empty). Python 3.8 and the standard library: monitor packages
carry a copy of the runtime.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, List, Mapping, Optional, Tuple, TypedDict

EventSource = Tuple[str, str, str]
"""``(id, kind, name)``: an event of a temporal point and where it happens."""


class FilterEntry(TypedDict, total=False):
    """A condition as the file holds it (``points.<key>.filter[]``)."""

    id: str
    topic: str
    expression: Mapping[str, Any]
    fields: List[List[Any]]
    variable: str
    value: Any


class PairingEntry(TypedDict, total=False):
    """The pairing keys of a point of the invariants file (inference writes all four; a
    missing one reads as empty)."""

    inputs: List[str]
    params: List[str]
    events: List[List[str]]
    filter: List[FilterEntry]


@dataclass(frozen=True)
class Filter:
    """One condition of a conditional point: declared (``topic``, ``expression`` over the
    ``fields``) or discovered (``variable == value``)."""

    id: Optional[str] = None
    topic: Optional[str] = None
    expression: Mapping[str, Any] = field(default_factory=dict)
    fields: Tuple[Tuple[Tuple[Any, ...], str], ...] = ()
    """``(path, variable)``: the variable of the topic's message each field path names."""
    variable: Optional[str] = None
    value: Any = None

    @property
    def declared(self) -> bool:
        """Whether it is a ``<condition>`` of the configuration (else a discovered one)."""
        return self.variable is None

    @classmethod
    def from_json(cls, entry: Mapping[str, Any]) -> Filter:
        return cls(
            entry.get("id"),
            entry.get("topic"),
            entry.get("expression") or {},
            tuple((tuple(path), name) for path, name in entry.get("fields", ())),
            entry.get("variable"),
            entry.get("value"),
        )

    def to_json(self) -> FilterEntry:
        if not self.declared:
            return {"variable": self.variable or "", "value": self.value}
        return {
            "id": self.id or "",
            "topic": self.topic or "",
            "expression": self.expression,
            "fields": [[list(path), name] for path, name in self.fields],
        }


@dataclass(frozen=True)
class Pairing:
    """Where a point's samples come from besides its trigger, and which it checks."""

    inputs: Tuple[str, ...] = ()
    params: Tuple[str, ...] = ()
    events: Tuple[EventSource, ...] = ()
    filters: Tuple[Filter, ...] = ()

    @classmethod
    def from_json(cls, point: Mapping[str, Any]) -> Pairing:
        """The pairing of a point of the invariants file (its other keys are ignored)."""
        return cls(
            tuple(point.get("inputs", ())),
            tuple(point.get("params", ())),
            tuple((ident, kind, name) for ident, kind, name in point.get("events", ())),
            tuple(Filter.from_json(entry) for entry in point.get("filter", ())),
        )

    def to_json(self) -> PairingEntry:
        return {
            "inputs": list(self.inputs),
            "params": list(self.params),
            "events": [list(event) for event in self.events],
            "filter": [condition.to_json() for condition in self.filters],
        }
