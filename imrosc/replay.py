"""Replay: bags fed to the runtime engine as if live, message by message, in bag order.

The very engine the monitor runs (``imrosc.runtime``) gets each message flattened with the
flattener the monitor uses, each service call, parameter set and architecture snapshot
from the ``/imrosc/*`` records, and the clock of the bag. A bag without architecture
records gives its connections' publishers (ROS 1 ``callerid``) at its start, which tells
publishers only, as in inference. Each bag is one run: the engine is reset between bags.
"""

from __future__ import annotations

import json
from collections.abc import Callable, Iterable, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from imrosc import records
from imrosc.bags import BagError, MessageError, open_bag
from imrosc.runtime import Engine, Violation
from imrosc.runtime.flatten import make_flattener
from imrosc.translate.catalog import flatten_json

RECORDS = (records.PARAMS_TOPIC, records.SRVS_TOPIC, records.ARCH_TOPIC)


@dataclass
class RunResult:
    """What replaying one bag gave."""

    bag: Path
    violations: list[Violation] = field(default_factory=list)
    messages: int = 0
    start: float = 0.0
    end: float = 0.0
    skipped: int = 0
    error: str | None = None

    @property
    def violated(self) -> set[str]:
        """Ids of the invariants this run broke."""
        return {v.invariant for v in self.violations}


def _snapshot(record: records.ArchSnapshot) -> dict[str, dict[str, frozenset[str]]]:
    return {
        "pub": {topic: ends.pubs for topic, ends in record.topics.items()},
        "sub": {topic: ends.subs for topic, ends in record.topics.items()},
        "srv": dict(record.services),
    }


def _callerids(connections: Iterable[Any]) -> dict[str, dict[str, frozenset[str]]]:
    publishers: dict[str, set[str]] = {}
    for connection in connections:
        callerid = getattr(connection.ext, "callerid", None)
        if callerid and not connection.topic.startswith(records.RECORD_PREFIX):
            publishers.setdefault(connection.topic, set()).add(callerid)
    return {"pub": {t: frozenset(p) for t, p in publishers.items()}}


class Replayer:
    """Feeds bags to one engine built from an invariants document."""

    def __init__(self, document: Mapping[str, Any], engine: Engine | None = None) -> None:
        self.document = document
        self.engine = engine if engine is not None else Engine(document)
        self.flatteners: dict[str, Callable[[Any], list[Any]]] = {
            topic: make_flattener(info["variables"]) for topic, info in document["topics"].items()
        }

    def run(self, bag: Path) -> RunResult:
        """Replay one bag as one run; a broken bag gives its error instead of raising."""
        result = RunResult(bag)
        engine = self.engine
        engine.reset()
        found = result.violations
        try:
            with open_bag(bag) as reader:
                result.start, result.end = reader.start_time / 1e9, reader.end_time / 1e9
                wanted = [
                    c
                    for c in reader.connections
                    if c.topic in self.flatteners or c.topic in RECORDS
                ]
                if not any(c.topic == records.ARCH_TOPIC for c in reader.connections):
                    found += engine.graph(result.start, _callerids(reader.connections), ("pub",))
                for connection, stamp, raw in reader.messages(connections=wanted):
                    result.messages += 1
                    time = stamp / 1e9
                    try:
                        message = reader.deserialize(raw, connection.msgtype)
                    except MessageError:
                        result.skipped += 1
                        continue
                    topic = connection.topic
                    flatten = self.flatteners.get(topic)
                    if flatten is not None:
                        found += engine.message(topic, time, flatten(message))
                    else:
                        found += self._record(topic, time, message)
                found += engine.advance(result.end)
        except BagError as error:
            result.error = str(error)
        return result

    def _record(self, topic: str, time: float, message: Any) -> list[Violation]:
        text = getattr(message, "data", "")
        engine = self.engine
        try:
            if topic == records.PARAMS_TOPIC:
                params: dict[str, Any] = {}
                for name, value in records.decode_params(text).params.items():
                    params.update(flatten_json(value, name))
                return engine.params(time, params)
            if topic == records.SRVS_TOPIC:
                call = records.decode_call(text)
                values = flatten_json({"request": call.request, "response": call.response})
                values["delay"] = call.delay
                return engine.call(call.service, time, values)
            return engine.graph(time, _snapshot(records.decode_arch(text)))
        except (records.RecordError, json.JSONDecodeError):
            return []


def replay(document: Mapping[str, Any], bags: Iterable[Path]) -> list[RunResult]:
    """Replay each bag as one run."""
    replayer = Replayer(document)
    return [replayer.run(bag) for bag in bags]
