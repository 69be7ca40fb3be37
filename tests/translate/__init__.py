"""Helpers for translator tests: write ROS 1 bags of arbitrary std/geometry messages."""

from __future__ import annotations

import functools
import sqlite3
from collections.abc import Iterable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from rosbags.rosbag1 import Writer
from rosbags.rosbag2 import StoragePlugin
from rosbags.rosbag2 import Writer as Ros2Writer
from rosbags.typesys import Stores, get_types_from_msg, get_typestore
from rosbags.typesys.store import Typestore

from imrosc.backends.plan import render_job, render_plan
from imrosc.backends.registry import BuildInputs, TopicType
from imrosc.lower import lower
from imrosc.passes.context import PassContext
from imrosc.passes.pipeline import run_passes
from imrosc.schema.loader import parse_config_bytes
from imrosc.translate.catalog import build_catalog
from imrosc.translate.points import PointSpec, point_specs

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


def good_run(path: Path, offset: float, odd: bool = False) -> Path:
    """A ROS 1 bag of 40 pairs: ``/in`` (Int32 0, 1, 2, ...) then ``/out`` (Float64 0..4) 10 ms
    later, every 0.1 s from ``offset``; ``odd``: ``/out`` is NaN and inf at the 4th and 5th."""
    messages = []
    for i in range(40):
        t = offset + i * 0.1
        value = float(i % 5)
        if odd and i in (3, 4):
            value = [float("nan"), float("inf")][i - 3]
        messages.append(msg("/in", t, "std_msgs/msg/Int32", "/src", data=i % 3))
        messages.append(msg("/out", t + 0.01, "std_msgs/msg/Float64", "/ctl", data=value))
    return write_bag(path, messages)


def specs_for(config: str, bags: list[Path]) -> tuple[list[PointSpec], Any, Any]:
    """The point specs of ``config`` over ``bags`` (as ``imrosc infer`` compiles them), the
    topics' layouts and the bags' catalog."""
    loaded, problems = parse_config_bytes(config.encode(), "t.xml")
    assert loaded is not None and not problems
    catalog = build_catalog(bags)
    assert not catalog.diagnostics, [d.as_text() for d in catalog.diagnostics]
    project = run_passes(lower(loaded), PassContext())
    types = {t: TopicType(m, f) for t, (m, f) in catalog.types.items()}
    inputs = BuildInputs(project, (), types)
    specs, skipped, layouts = point_specs(render_plan(inputs), render_job(inputs), catalog)
    assert not skipped
    return specs, layouts, catalog


def unknown_type_bag(path: Path) -> Path:
    """A ROS 2 bag whose message definitions were lost (as old rosbag2 versions wrote)."""
    store = get_typestore(Stores.LATEST)
    store.register(get_types_from_msg("float64 level\n", "my_pkg/msg/Thing"))
    with Ros2Writer(path, version=9, storage_plugin=StoragePlugin.SQLITE3) as writer:
        connection = writer.add_connection("/out", "my_pkg/msg/Thing", typestore=store)
        thing = store.types["my_pkg/msg/Thing"](level=1.5)
        writer.write(connection, 1, bytes(store.serialize_cdr(thing, "my_pkg/msg/Thing")))
    with sqlite3.connect(next(path.glob("*.db3"))) as database:
        database.execute("delete from message_definitions")
    return path
