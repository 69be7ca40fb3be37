"""The intermediate representation of a configuration: frozen, typed, JSON round-trippable.

Lowering (``imrosc.lower``) builds a :class:`Project` from a checked configuration; the
passes of ``imrosc.passes`` rewrite it (names resolved, relative topics grouped, conditional
points expanded, temporal events labelled); backends render it. Every node carries the
:class:`Span` of the XML it came from. ``to_json``/``from_json`` (de)serialize the whole tree
with a schema version, so ``imrosc build --emit-ir`` output can be read back.
"""

from __future__ import annotations

import dataclasses
import types
import typing
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any, Literal, TypeVar, Union

IR_VERSION = 1


@dataclass(frozen=True)
class Span:
    """1-based line and column of the element a node comes from."""

    line: int
    column: int


@dataclass(frozen=True)
class Tunables:
    """Inference tunables (``<detect>`` attributes) with the thesis' defaults."""

    window: float = 1.0
    confidence: float = 0.99
    drop_ratio: float = 0.9
    hull_chunk: int = 20
    discrete: int = 10
    budget: float = 0.05
    """Per-run false-alarm budget of calibration (``docs/calibration.md``); 0 turns it off."""
    step_tail: Literal["larger", "select"] = "select"
    """The model of the units' largest steps behind a step's margin (``docs/calibration.md``,
    section 4): ``larger``, the larger of the normal and log-normal bounds; ``select``, the
    bound of the model that predicts the units held out in turn the better."""


@dataclass(frozen=True)
class InputTopic:
    """A topic paired with a publish point: ``hops`` publishers away, or declared explicitly."""

    name: str
    hops: int
    explicit: bool = False


@dataclass(frozen=True)
class PublishPoint:
    """Messages published on ``topic``, paired with the latest message of each input topic."""

    id: str
    topic: str
    span: Span
    relative: int = 0
    explicit_topics: tuple[str, ...] = ()
    params: tuple[str, ...] = ()
    conds: tuple[str, ...] = ()
    condition: str | None = None
    inputs: tuple[InputTopic, ...] = ()
    families: tuple[str, ...] = ()
    """The template families inference instantiates here (``<publish families>``, in catalog
    order); empty: every family of a publish point."""
    kind: Literal["publish"] = "publish"


@dataclass(frozen=True)
class CallPoint:
    """Calls of ``service``: request, response, delay (thesis 3.2, Figure 3.8)."""

    id: str
    service: str
    span: Span
    params: tuple[str, ...] = ()
    conds: tuple[str, ...] = ()
    condition: str | None = None
    kind: Literal["call"] = "call"


@dataclass(frozen=True)
class ParamPoint:
    """A parameter's value over time (its id is optional: only violations need one)."""

    id: str | None
    name: str
    span: Span
    conds: tuple[str, ...] = ()
    condition: str | None = None
    kind: Literal["param"] = "param"


@dataclass(frozen=True)
class ArchPoint:
    """Publisher, subscriber and server sets (thesis 3.4.3); ``kinds`` of pub, sub, srv."""

    id: str
    kinds: tuple[str, ...]
    span: Span
    conds: tuple[str, ...] = ()
    condition: str | None = None
    kind: Literal["arch"] = "arch"


@dataclass(frozen=True)
class EventLabel:
    """A temporal event: the id of a publish or call point and the name it stands for."""

    id: str
    event: Literal["publish", "call"]
    name: str


@dataclass(frozen=True)
class ConcretePattern:
    """A pattern with its placeholders bound to distinct events (Algorithm 9).

    ``binding`` pairs each placeholder with an event id; ``text`` is the pattern over event
    ids only.
    """

    binding: tuple[tuple[str, str], ...]
    text: str


@dataclass(frozen=True)
class PatternSpec:
    """A user pattern as written, canonical, and (after labelling) its concrete orderings."""

    text: str
    canonical: str
    span: Span
    concrete: tuple[ConcretePattern, ...] = ()


@dataclass(frozen=True)
class TemporalPoint:
    """Event orderings among ``events`` (thesis 3.4.4): ordered-pair intervals and patterns."""

    id: str
    events: tuple[str, ...]
    span: Span
    max_interval: float = 2.0
    max_events: int = 10
    patterns: tuple[PatternSpec, ...] = ()
    conds: tuple[str, ...] = ()
    condition: str | None = None
    labels: tuple[EventLabel, ...] = ()
    kind: Literal["temporal"] = "temporal"


Point = PublishPoint | CallPoint | ParamPoint | ArchPoint | TemporalPoint
POINT_TYPES: tuple[type[Any], ...] = (PublishPoint, CallPoint, ParamPoint, ArchPoint, TemporalPoint)


def point_key(point: Point) -> str:
    """The unique name of a point: its id (or parameter name), ``?condition`` if conditional."""
    base = point.id if point.id is not None else getattr(point, "name", "")
    return base if point.condition is None else f"{base}?{point.condition}"


@dataclass(frozen=True)
class Condition:
    """A predicate on the latest message of ``topic`` (thesis 3.6).

    ``expression`` is the JSON form of the parsed ``<value>`` (``imrosc.schema.expression``);
    ``discovered`` marks conditions found during inference rather than declared.
    """

    id: str
    topic: str
    text: str
    expression: Mapping[str, Any]
    span: Span
    discovered: bool = False


@dataclass(frozen=True)
class Detect:
    """Where to learn from and where to write the invariants."""

    inv: str
    bags: tuple[str, ...]
    span: Span
    tunables: Tunables = field(default_factory=Tunables)


@dataclass(frozen=True)
class Onset:
    """When the fault of a ``<fail>`` entry's runs begins: at most one of ``seconds`` (after
    each bag's start), ``topic`` (a label topic: its first non-zero message) and ``file`` (a
    JSON file of onsets per bag); none of them: the onset is unknown."""

    span: Span
    seconds: float | None = None
    topic: str | None = None
    file: str | None = None

    @property
    def given(self) -> bool:
        """Whether the entry says when its fault begins."""
        return self.seconds is not None or self.topic is not None or self.file is not None


@dataclass(frozen=True)
class Check:
    """Classification (success/fail runs, thesis 4.2) or comparison (bags, thesis 5.2)."""

    inv: str
    mode: Literal["classify", "compare"]
    span: Span
    success: tuple[str, ...] = ()
    fail: tuple[str, ...] = ()
    bags: tuple[str, ...] = ()
    threshold: float = 0.5
    beta: float = 1.0
    onsets: tuple[Onset, ...] = ()
    """One per ``fail`` entry, in order (the entry's span; its onset if it gives one)."""
    select: Literal["cover", "fscore"] = "cover"
    """How classification chooses the kept invariants (:mod:`imrosc.selection`)."""
    detector: Literal["none", "logistic"] = "logistic"
    """Whether classification also learns fault detectors (:mod:`imrosc.detectors`) from
    the failed runs with an onset."""


@dataclass(frozen=True)
class Action:
    """Publish ``value`` on a topic or call a service with it (thesis 4.3.2)."""

    id: str
    target: Literal["topic", "service"]
    name: str
    value: Mapping[str, Any]
    span: Span


@dataclass(frozen=True)
class Violation:
    """When an invariant of one of ``points`` breaks, take ``actions``."""

    points: tuple[str, ...]
    actions: tuple[str, ...]
    span: Span


@dataclass(frozen=True)
class AlarmOverrides:
    """The ``<monitor>``'s ``alarm_*`` attributes: the fields of the invariants file's alarm
    rule they replace (``None``: the file's value is kept)."""

    persist: int | None = None
    """Consecutive violating samples of one invariant that raise an alarm."""
    seconds: float | None = None
    """Or consecutive violating samples spanning at least this many seconds."""
    distinct: int | None = None
    """Distinct invariants of a point violated within ``window`` (0: agreement off)."""
    window: float | None = None
    """Seconds of the agreement rule."""
    severe: float | None = None
    """The severity (margins beyond the centre) at which a violation of a family with
    severe alarms alarms at once (0: off)."""

    def given(self) -> dict[str, int | float]:
        """The overridden fields by their name in the rule (``AlarmRule``)."""
        return {
            f.name: v for f in dataclasses.fields(self) if (v := getattr(self, f.name)) is not None
        }


@dataclass(frozen=True)
class Monitor:
    """The monitor to synthesize (thesis 4.3)."""

    inv: str
    span: Span
    launch: str | None = None
    launch_ros2: str | None = None
    period: float = 1.0
    block: tuple[str, ...] = ()
    actions: tuple[Action, ...] = ()
    violations: tuple[Violation, ...] = ()
    alarms: AlarmOverrides = field(default_factory=AlarmOverrides)


@dataclass(frozen=True)
class Project:
    """A whole configuration."""

    name: str
    source: str
    span: Span
    points: tuple[Point, ...] = ()
    conditions: tuple[Condition, ...] = ()
    detect: Detect | None = None
    check: Check | None = None
    monitor: Monitor | None = None
    passes: tuple[str, ...] = ()
    version: int = IR_VERSION

    def point(self, key: str) -> Point:
        """The point called ``key`` (see :func:`point_key`)."""
        for point in self.points:
            if point_key(point) == key:
                return point
        raise KeyError(key)

    def condition(self, ident: str) -> Condition:
        """The condition with id ``ident``."""
        for condition in self.conditions:
            if condition.id == ident:
                return condition
        raise KeyError(ident)


# -- JSON codec ---------------------------------------------------------------------------

T = TypeVar("T")


class IRFormatError(ValueError):
    """A JSON document is not an IR of this version."""


def to_json(value: Any) -> Any:
    """Plain JSON data (dicts, lists, str, numbers, bools, None) for an IR value."""
    if dataclasses.is_dataclass(value) and not isinstance(value, type):
        return {f.name: to_json(getattr(value, f.name)) for f in dataclasses.fields(value)}
    if isinstance(value, tuple | list):
        return [to_json(item) for item in value]
    if isinstance(value, Mapping):
        return {str(key): to_json(item) for key, item in value.items()}
    return value


def _decode(hint: Any, data: Any, where: str) -> Any:
    origin = typing.get_origin(hint)
    if hint is Any:
        return freeze(data)
    if origin is Literal:
        if data not in typing.get_args(hint):
            raise IRFormatError(f"{where}: {data!r} is not one of {typing.get_args(hint)}")
        return data
    if origin in (Union, types.UnionType):
        options = typing.get_args(hint)
        if data is None and type(None) in options:
            return None
        classes = [o for o in options if isinstance(o, type) and dataclasses.is_dataclass(o)]
        if classes and isinstance(data, dict):
            for option in classes:
                if data.get("kind") == _kind_of(option):
                    return _decode(option, data, where)
            raise IRFormatError(f"{where}: unknown kind {data.get('kind')!r}")
        for option in options:
            if option is not type(None):
                return _decode(option, data, where)
    if origin is tuple:
        if not isinstance(data, list):
            raise IRFormatError(f"{where}: expected a list")
        args = typing.get_args(hint)
        if len(args) == 2 and args[1] is Ellipsis:
            return tuple(_decode(args[0], item, f"{where}[{i}]") for i, item in enumerate(data))
        return tuple(
            _decode(a, item, f"{where}[{i}]")
            for i, (a, item) in enumerate(zip(args, data, strict=True))
        )
    if origin in (Mapping, dict) or hint in (Mapping, dict):
        if not isinstance(data, dict):
            raise IRFormatError(f"{where}: expected an object")
        return freeze(data)
    if dataclasses.is_dataclass(hint):
        return from_json(typing.cast(type[Any], hint), data, where)
    if hint is float and isinstance(data, int | float) and not isinstance(data, bool):
        return float(data)
    if isinstance(hint, type) and not isinstance(data, hint):
        raise IRFormatError(f"{where}: expected {hint.__name__}, got {type(data).__name__}")
    return data


def freeze(data: Any) -> Any:
    """JSON data as immutable-enough Python data (lists become tuples)."""
    if isinstance(data, list):
        return tuple(freeze(item) for item in data)
    if isinstance(data, dict):
        return {key: freeze(item) for key, item in data.items()}
    return data


def _kind_of(cls: type[Any]) -> str | None:
    for item in dataclasses.fields(cls):
        if item.name == "kind":
            return typing.cast(str, item.default)
    return None


def from_json(cls: type[T], data: Any, where: str = "$") -> T:
    """Rebuild an IR value of type ``cls`` from :func:`to_json` output."""
    if not isinstance(data, dict):
        raise IRFormatError(f"{where}: expected an object for {cls.__name__}")
    hints = typing.get_type_hints(cls)
    names = {f.name for f in dataclasses.fields(typing.cast(Any, cls))}
    unknown = set(data) - names
    if unknown:
        raise IRFormatError(f"{where}: unknown fields {sorted(unknown)} for {cls.__name__}")
    values = {name: _decode(hints[name], data[name], f"{where}.{name}") for name in data}
    try:
        return cls(**values)
    except TypeError as error:
        raise IRFormatError(f"{where}: {error}") from None


def project_from_json(data: Any) -> Project:
    """Rebuild a :class:`Project`, refusing another IR version."""
    if not isinstance(data, dict) or data.get("version") != IR_VERSION:
        raise IRFormatError(f"not an imrosc IR of version {IR_VERSION}")
    return from_json(Project, data)
