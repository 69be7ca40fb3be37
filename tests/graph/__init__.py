"""Tests of imrosc.graph, and the bag writers they share with tests/test_bags.py.

Every bag a test needs is written here with rosbags' own writers, into the test's tmp_path:
ROS 1 ``.bag`` files (with a ``callerid`` per connection) and ROS 2 bags in sqlite3 and MCAP
storage. Every message is a ``std_msgs/String``, which is all the graph and records need.
"""

from __future__ import annotations

import functools
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Literal

from rosbags.interfaces import Connection
from rosbags.rosbag1 import Writer as Ros1Writer
from rosbags.rosbag2 import StoragePlugin
from rosbags.rosbag2 import Writer as Ros2Writer
from rosbags.typesys import Stores, get_typestore
from rosbags.typesys.store import Typestore

from imrosc.records import ARCH_TOPIC, RECORD_TYPE, ArchSnapshot, TopicEnds, encode

SECOND = 1_000_000_000


@dataclass(frozen=True)
class Message:
    """One std_msgs/String message to write: topic, receive time, data and (ROS 1) callerid."""

    topic: str
    time_ns: int
    data: str = ""
    callerid: str | None = None
    msgtype: str = RECORD_TYPE


@functools.cache
def ros1_typestore() -> Typestore:
    return get_typestore(Stores.ROS1_NOETIC)


@functools.cache
def ros2_typestore() -> Typestore:
    return get_typestore(Stores.LATEST)


def _serialize_ros1(message: Message) -> bytes:
    store = ros1_typestore()
    if message.msgtype == RECORD_TYPE:
        value = store.types[RECORD_TYPE](data=message.data)
    else:
        value = store.types[message.msgtype](data=len(message.data))
    return bytes(store.serialize_ros1(value, message.msgtype))


def write_ros1_bag(
    path: Path,
    messages: Iterable[Message],
    *,
    compression: Ros1Writer.CompressionFormat | None = None,
) -> Path:
    """A ROS 1 bag of the messages; one connection per (topic, type, callerid)."""
    writer = Ros1Writer(path)
    if compression is not None:
        writer.set_compression(compression)
    connections: dict[tuple[str, str, str | None], Connection] = {}
    with writer:
        for message in sorted(messages, key=lambda m: m.time_ns):
            key = (message.topic, message.msgtype, message.callerid)
            if key not in connections:
                connections[key] = writer.add_connection(
                    message.topic,
                    message.msgtype,
                    typestore=ros1_typestore(),
                    callerid=message.callerid,
                )
            writer.write(connections[key], message.time_ns, _serialize_ros1(message))
    return path


def write_ros2_bag(
    path: Path, messages: Iterable[Message], *, storage: Literal["sqlite3", "mcap"] = "sqlite3"
) -> Path:
    """A ROS 2 bag directory of the messages in sqlite3 or MCAP storage."""
    plugin = StoragePlugin.SQLITE3 if storage == "sqlite3" else StoragePlugin.MCAP
    store = ros2_typestore()
    connections: dict[tuple[str, str], Connection] = {}
    with Ros2Writer(path, version=9, storage_plugin=plugin) as writer:
        for message in sorted(messages, key=lambda m: m.time_ns):
            key = (message.topic, message.msgtype)
            if key not in connections:
                connections[key] = writer.add_connection(
                    message.topic, message.msgtype, typestore=store
                )
            if message.msgtype == RECORD_TYPE:
                value = store.types[RECORD_TYPE](data=message.data)
            else:
                value = store.types[message.msgtype](data=len(message.data))
            data = bytes(store.serialize_cdr(value, message.msgtype))
            writer.write(connections[key], message.time_ns, data)
    return path


def arch(
    topics: Mapping[str, tuple[Sequence[str], Sequence[str]]],
    services: Mapping[str, Sequence[str]] | None = None,
) -> ArchSnapshot:
    """An architecture snapshot from plain lists: topic -> (publishers, subscribers)."""
    return ArchSnapshot(
        {t: TopicEnds(frozenset(p), frozenset(s)) for t, (p, s) in topics.items()},
        {name: frozenset(servers) for name, servers in (services or {}).items()},
    )


def arch_message(
    time_s: float, snapshot: ArchSnapshot, callerid: str = "/imrosc_record"
) -> Message:
    """The /imrosc/arch message of a snapshot at a time in seconds."""
    return Message(ARCH_TOPIC, int(time_s * SECOND), encode(snapshot), callerid)
