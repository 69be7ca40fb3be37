"""The translator plan (``plan.json``): what the translator reads from the bags for each
program point.

Backend ``plan`` writes it (:mod:`imrosc.backends.plan`; ``imrosc infer`` builds the same in
memory) and the translator reads it (:mod:`imrosc.translate.points`). The format in three
forms kept in step by ``tests/formats/test_plan_job.py``: the typed dictionaries below
(:class:`PlanDocument`), the JSON schema (``plan.schema.json``: :func:`schema`) and what
the backend writes (every example's golden plan follows the schema).
"""

from __future__ import annotations

from typing import Any, Literal, TypedDict

from imrosc import formats

FORMAT = "imrosc-plan"
VERSION = 1


def schema() -> dict[str, Any]:
    """The JSON schema of the format (draft 2020-12)."""
    return formats.schema(formats.PLAN_SCHEMA)


class PlanTopic(TypedDict):
    """A recorded topic the plan knows the type of (``topics.<name>``)."""

    type: str


class PlanCondition(TypedDict):
    """A condition of the project (``conditions[]``)."""

    id: str
    topic: str
    text: str
    discovered: bool


class PointCondition(PlanCondition):
    """The condition of a point, with its expression (the IR's JSON)."""

    expression: dict[str, Any]


class Field(TypedDict):
    """A field of a message type, flattened (``variables.<topic>[]``)."""

    path: str
    type: str
    array: str | None
    length: int | None


class Input(TypedDict):
    """An input topic of a publish point, how many hops from its trigger."""

    topic: str
    hops: int
    explicit: bool


class TopicTrigger(TypedDict):
    topic: str


class ServiceTrigger(TypedDict):
    service: str


class ParamTrigger(TypedDict):
    param: str


class ArchTrigger(TypedDict):
    architecture: list[str]


class EventsTrigger(TypedDict):
    events: list[str]


class Event(TypedDict):
    """An event of a temporal point: its label, ``publish`` or ``call``, and the name."""

    id: str
    event: str
    name: str


class Concrete(TypedDict):
    """A pattern with its letters bound to events."""

    binding: dict[str, str]
    text: str


class Pattern(TypedDict):
    text: str
    canonical: str
    concrete: list[Concrete]


class Thresholds(TypedDict):
    max_interval: float
    max_events: int


class PublishPoint(TypedDict):
    """A publish point: its topic's messages paired with its inputs' and parameters'."""

    key: str
    id: str | None
    kind: Literal["publish"]
    trigger: TopicTrigger
    inputs: list[Input]
    variables: dict[str, list[Field] | Literal["*"]]
    """Per topic, its fields, or ``"*"`` when the build knew no type: every field found."""
    params: list[str]
    condition: PointCondition | None


class CallPoint(TypedDict):
    """A call point: a service's calls, from the ``/imrosc/srvs`` records."""

    key: str
    id: str | None
    kind: Literal["call"]
    trigger: ServiceTrigger
    records: str
    variables: list[str]
    params: list[str]
    condition: PointCondition | None


class ParamPoint(TypedDict):
    """A parameter point: a parameter's values, from the ``/imrosc/params`` records."""

    key: str
    id: str | None
    kind: Literal["param"]
    trigger: ParamTrigger
    records: str
    condition: PointCondition | None


class ArchPoint(TypedDict):
    """An architecture point: graph snapshots, from the ``/imrosc/arch`` records."""

    key: str
    id: str | None
    kind: Literal["arch"]
    trigger: ArchTrigger
    records: str
    condition: PointCondition | None


class TemporalPoint(TypedDict):
    """A temporal point: the events of other points, their intervals and patterns."""

    key: str
    id: str | None
    kind: Literal["temporal"]
    trigger: EventsTrigger
    events: list[Event]
    patterns: list[Pattern]
    thresholds: Thresholds
    condition: PointCondition | None


PlanPoint = PublishPoint | CallPoint | ParamPoint | ArchPoint | TemporalPoint
"""A program point of the plan; its ``kind`` tells which."""

POINT_FORMS: dict[str, type] = {
    "publish": PublishPoint,
    "call": CallPoint,
    "param": ParamPoint,
    "arch": ArchPoint,
    "temporal": TemporalPoint,
}
"""The typed dictionary of each kind of point."""


PlanDocument = TypedDict(
    "PlanDocument",
    {
        "$comment": str,
        "format": str,
        "version": int,
        "project": str,
        "source": str,
        "passes": list[str],
        "topics": dict[str, PlanTopic],
        "conditions": list[PlanCondition],
        "points": list[PlanPoint],
    },
)
"""A translator plan."""
