"""The engine call of an ``imrosc record`` record (parameters, a service call, the graph),
for both ways of replaying a bag (:mod:`imrosc.replay`, message by message, and
:mod:`imrosc.checking.run`, by chunks)."""

from __future__ import annotations

import json
from collections.abc import Callable
from typing import Any

from imrosc import records
from imrosc.runtime import Engine, Violation
from imrosc.translate.catalog import flatten_json

RECORDS = (records.PARAMS_TOPIC, records.SRVS_TOPIC, records.ARCH_TOPIC)
"""The topics of the records."""
EngineCall = Callable[[float], list[Violation]]
"""An engine call waiting for its time."""


def snapshot(record: records.ArchSnapshot) -> dict[str, dict[str, frozenset[str]]]:
    """An architecture record as the engine's graph takes it."""
    return {
        "pub": {topic: ends.pubs for topic, ends in record.topics.items()},
        "sub": {topic: ends.subs for topic, ends in record.topics.items()},
        "srv": dict(record.services),
    }


def record_call(engine: Engine, topic: str, message: Any) -> EngineCall | None:
    """The engine call of the record ``message`` on ``topic`` (one of the record topics);
    ``None`` when its text does not decode."""
    text = getattr(message, "data", "")
    try:
        if topic == records.PARAMS_TOPIC:
            params: dict[str, Any] = {}
            for name, value in records.decode_params(text).params.items():
                params.update(flatten_json(value, name))
            return lambda now: engine.params(now, params)
        if topic == records.SRVS_TOPIC:
            call = records.decode_call(text)
            values = flatten_json({"request": call.request, "response": call.response})
            values["delay"] = call.delay
            return lambda now: engine.call(call.service, now, values)
        graph = snapshot(records.decode_arch(text))
        return lambda now: engine.graph(now, graph)
    except (records.RecordError, json.JSONDecodeError):
        return None
