"""Helpers for translator tests: write ROS 1 bags of arbitrary std/geometry messages."""

from __future__ import annotations

import functools
from collections.abc import Iterable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from rosbags.rosbag1 import Writer
from rosbags.typesys import Stores, get_typestore
from rosbags.typesys.store import Typestore

SECOND = 1_000_000_000


@functools.cache
def store() -> Typestore:
    return get_typestore(Stores.ROS1_NOETIC)


@dataclass(frozen=True)
class Msg:
    """A message to write: topic, time in seconds, type, field values, callerid."""

    topic: str
    time: float
    msgtype: str
    fields: tuple[tuple[str, Any], ...]
    callerid: str = "/node"


def msg(topic: str, time: float, msgtype: str, callerid: str = "/node", **fields: Any) -> Msg:
    return Msg(topic, time, msgtype, tuple(fields.items()), callerid)


def build(msgtype: str, fields: dict[str, Any]) -> Any:
    """A message object of ``msgtype`` with defaults for fields not given (one level)."""
    types = store().types
    cls = types[msgtype]
    _, defs = store().fielddefs[msgtype]
    values: dict[str, Any] = {}
    for name, (kind, detail) in defs:
        if name in fields:
            values[name] = fields[name]
        elif kind == 2:  # a nested message
            values[name] = build(str(detail), {})
        elif kind == 1:
            values[name] = "" if detail[0] == "string" else 0
        else:
            import numpy as np

            values[name] = np.array([], dtype=np.float64)
    return cls(**values)


def write_bag(path: Path, messages: Iterable[Msg]) -> Path:
    with Writer(path) as writer:
        connections: dict[tuple[str, str, str], Any] = {}
        for m in sorted(messages, key=lambda m: m.time):
            key = (m.topic, m.msgtype, m.callerid)
            if key not in connections:
                connections[key] = writer.add_connection(
                    m.topic, m.msgtype, typestore=store(), callerid=m.callerid
                )
            data = store().serialize_ros1(build(m.msgtype, dict(m.fields)), m.msgtype)
            writer.write(connections[key], int(m.time * SECOND), bytes(data))
    return path
