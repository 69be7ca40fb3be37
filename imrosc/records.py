"""Architecture, parameter and service-call records: what ``imrosc record`` writes into bags.

rosbag records topics only. The recording node of the thesis (section 3.2, Figures 3.4, 3.5
and 3.8) adds what rosbag misses: the node graph, the parameters and the service calls, each
published as a ``std_msgs/msg/String`` message whose ``data`` is one JSON object with
``"version": 1``. The bag's receive time of the message is the record's time.

* :data:`ARCH_TOPIC` carries an :class:`ArchSnapshot`, a full snapshot published whenever the
  graph changes;
* :data:`PARAMS_TOPIC` carries a :class:`ParamSnapshot`, a full snapshot published whenever a
  parameter changes;
* :data:`SRVS_TOPIC` carries a :class:`ServiceCall` for each service call the node relays.

:func:`encode` writes canonical JSON (sorted keys and lists, no spaces), so one snapshot is one
string, through the recorders' own encoder (:mod:`imrosc.onboard.records`); the ``decode_*``
functions accept exactly that format and raise :class:`RecordError` with a one-line message
for anything else. ``docs/record-format.md`` documents the format.

>>> snapshot = ArchSnapshot({"/t": TopicEnds(frozenset({"/b", "/a"}), frozenset())}, {})
>>> encode(snapshot)
'{"services":{},"topics":{"/t":{"pubs":["/a","/b"],"subs":[]}},"version":1}'
>>> decode_arch(encode(snapshot)) == snapshot
True
"""

from __future__ import annotations

import json
import math
from collections.abc import Mapping
from dataclasses import dataclass

from imrosc.onboard.records import (
    ARCH_TOPIC,
    PARAMS_TOPIC,
    RECORD_PREFIX,
    RECORD_TOPICS,
    RECORD_TYPE,
    SRVS_TOPIC,
    VERSION,
    arch_text,
    call_text,
    params_text,
)
from imrosc.schema.names import BAD_NAME, check_graph_name

__all__ = [
    "ARCH_TOPIC",
    "PARAMS_TOPIC",
    "RECORD_PREFIX",
    "RECORD_TOPICS",
    "RECORD_TYPE",
    "SRVS_TOPIC",
    "VERSION",
    "ArchSnapshot",
    "ParamSnapshot",
    "Record",
    "RecordError",
    "ServiceCall",
    "TopicEnds",
    "decode_arch",
    "decode_call",
    "decode_params",
    "encode",
]


class RecordError(ValueError):
    """A record that is not valid JSON or does not follow the record format."""

    def __init__(self, message: str) -> None:
        super().__init__(message)
        self.message = message


@dataclass(frozen=True)
class TopicEnds:
    """The nodes that publish and subscribe to one topic."""

    pubs: frozenset[str]
    subs: frozenset[str]


@dataclass(frozen=True)
class ArchSnapshot:
    """The node graph at one time: topics to their ends, services to their servers."""

    topics: Mapping[str, TopicEnds]
    services: Mapping[str, frozenset[str]]


@dataclass(frozen=True)
class ParamSnapshot:
    """Every parameter at one time, by global name, as JSON values."""

    params: Mapping[str, object]


@dataclass(frozen=True)
class ServiceCall:
    """One relayed service call: who called whom, with what, and how long it took.

    ``stamp`` is the time of the request in seconds; ``delay`` the seconds until the response;
    ``response`` is None when the call failed (``ok`` is then False).
    """

    service: str
    client: str
    server: str
    request: Mapping[str, object]
    response: Mapping[str, object] | None
    ok: bool
    stamp: float
    delay: float


Record = ArchSnapshot | ParamSnapshot | ServiceCall


def encode(record: Record) -> str:
    """The canonical JSON text of a record: sorted keys, sorted name lists, no spaces, as
    the recorders write it (:mod:`imrosc.onboard.records`, the one encoder).

    Parameter values and service messages are written as given; NaN and infinities are
    written as ``NaN``/``Infinity`` (as Python's json module does), which the decoders accept.
    A call's ``ok`` is whether it has a response, its ``delay`` never negative.
    """
    if isinstance(record, ArchSnapshot):
        topics = {name: (ends.pubs, ends.subs) for name, ends in record.topics.items()}
        return arch_text(topics, record.services)
    if isinstance(record, ParamSnapshot):
        return params_text(record.params)
    return call_text(
        record.service,
        record.client,
        record.server,
        record.request,
        record.response,
        record.stamp,
        record.delay,
    )


def _no_duplicates(pairs: list[tuple[str, object]]) -> dict[str, object]:
    document: dict[str, object] = {}
    for key, value in pairs:
        if key in document:
            raise RecordError(f"key {key!r} appears twice")
        document[key] = value
    return document


def _load(text: str, what: str, keys: frozenset[str]) -> dict[str, object]:
    """Parse a record's text into its top-level object and check version and keys."""
    if not isinstance(text, str):  # a record topic whose messages are not strings
        raise RecordError(f"{what} record is not text but {type(text).__name__}")
    try:
        document = json.loads(text, object_pairs_hook=_no_duplicates)
    except RecordError as error:
        raise RecordError(f"{what} record is malformed: {error.message}") from None
    except json.JSONDecodeError as error:
        message = f"{what} record is not JSON: {error.msg} at character {error.pos + 1}"
        raise RecordError(message) from None
    except (RecursionError, ValueError) as error:
        raise RecordError(f"{what} record is not JSON: {error}") from None
    if not isinstance(document, dict):
        raise RecordError(f"{what} record must be a JSON object, not {_kind(document)}")
    version = document.get("version")
    if version is None:
        raise RecordError(f"{what} record has no 'version'")
    if type(version) is not int or version != VERSION:
        raise RecordError(f"{what} record has version {version!r}; imrosc reads version 1")
    unknown = sorted(set(document) - keys - {"version"})
    if unknown:
        raise RecordError(f"{what} record has unknown key {unknown[0]!r}")
    missing = sorted(keys - set(document))
    if missing:
        raise RecordError(f"{what} record has no {missing[0]!r}")
    return document


def _kind(value: object) -> str:
    """A JSON-ish name of a value's type, for messages."""
    if value is None:
        return "null"
    if isinstance(value, bool):
        return "a boolean"
    if isinstance(value, (int, float)):
        return "a number"
    if isinstance(value, str):
        return "a string"
    if isinstance(value, list):
        return "a list"
    return "an object"


def _object(value: object, where: str) -> dict[str, object]:
    if not isinstance(value, dict):
        raise RecordError(f"{where} must be an object, not {_kind(value)}")
    return value


def _name(value: object, where: str, kind: str) -> str:
    """A global ROS name (topic, service, node or parameter)."""
    if not isinstance(value, str):
        raise RecordError(f"{where} must be a {kind} name, not {_kind(value)}")
    for problem in check_graph_name(value, kind):
        if problem.code == BAD_NAME:
            raise RecordError(f"{where}: {problem.message}")
    if not value.startswith("/"):
        raise RecordError(f"{where}: {kind} name {value!r} is not global")
    return value


def _names(value: object, where: str, kind: str) -> frozenset[str]:
    if not isinstance(value, list):
        raise RecordError(f"{where} must be a list of {kind} names, not {_kind(value)}")
    return frozenset(_name(item, f"{where}[{index}]", kind) for index, item in enumerate(value))


def _seconds(value: object, where: str) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise RecordError(f"{where} must be a number of seconds, not {_kind(value)}")
    if not math.isfinite(value):
        raise RecordError(f"{where} must be finite, not {value!r}")
    return float(value)


def decode_arch(text: str) -> ArchSnapshot:
    """Read an architecture record (the ``data`` of a message on :data:`ARCH_TOPIC`)."""
    document = _load(text, "architecture", frozenset({"topics", "services"}))
    topics: dict[str, TopicEnds] = {}
    for topic, value in sorted(_object(document["topics"], "'topics'").items()):
        where = f"topics[{topic!r}]"
        _name(topic, f"'topics' key {topic!r}", "topic")
        ends = _object(value, where)
        if set(ends) != {"pubs", "subs"}:
            raise RecordError(f"{where} must have exactly the keys 'pubs' and 'subs'")
        pubs = _names(ends["pubs"], f"{where}.pubs", "node")
        subs = _names(ends["subs"], f"{where}.subs", "node")
        topics[topic] = TopicEnds(pubs, subs)
    services: dict[str, frozenset[str]] = {}
    for service, value in sorted(_object(document["services"], "'services'").items()):
        _name(service, f"'services' key {service!r}", "service")
        services[service] = _names(value, f"services[{service!r}]", "node")
    return ArchSnapshot(topics, services)


def decode_params(text: str) -> ParamSnapshot:
    """Read a parameter record (the ``data`` of a message on :data:`PARAMS_TOPIC`)."""
    document = _load(text, "parameter", frozenset({"params"}))
    params = _object(document["params"], "'params'")
    for name in params:
        _name(name, f"'params' key {name!r}", "parameter")
    return ParamSnapshot(dict(sorted(params.items())))


def decode_call(text: str) -> ServiceCall:
    """Read a service-call record (the ``data`` of a message on :data:`SRVS_TOPIC`)."""
    keys = {"service", "client", "server", "request", "response", "ok", "stamp", "delay"}
    document = _load(text, "service-call", frozenset(keys))
    ok = document["ok"]
    if not isinstance(ok, bool):
        raise RecordError(f"'ok' must be true or false, not {_kind(ok)}")
    response = document["response"]
    if ok != (response is not None):
        expected = "an object when 'ok' is true" if ok else "null when 'ok' is false"
        raise RecordError(f"'response' must be {expected}")
    delay = _seconds(document["delay"], "'delay'")
    if delay < 0:
        raise RecordError(f"'delay' must not be negative, not {delay!r}")
    return ServiceCall(
        service=_name(document["service"], "'service'", "service"),
        client=_name(document["client"], "'client'", "node"),
        server=_name(document["server"], "'server'", "node"),
        request=_object(document["request"], "'request'"),
        response=None if response is None else _object(response, "'response'"),
        ok=ok,
        stamp=_seconds(document["stamp"], "'stamp'"),
        delay=delay,
    )
