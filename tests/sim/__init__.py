"""Tests of imrosc.sim, and helpers to read back what it writes.

Bags are read with rosbags' ``AnyReader`` (the reader every imrosc stage uses); the helpers
here turn a bag into plain Python: per topic, the receive times, the ROS 1 callerids and the
decoded messages.
"""

from __future__ import annotations

from collections import defaultdict
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from numpy.typing import NDArray
from rosbags.highlevel import AnyReader
from rosbags.interfaces import ConnectionExtRosbag1
from rosbags.typesys import Stores, get_typestore

from imrosc.sim import Stream


@dataclass
class TopicData:
    """What a bag holds on one topic."""

    msgtype: str
    times: list[int] = field(default_factory=list)
    callerids: list[str | None] = field(default_factory=list)
    messages: list[object] = field(default_factory=list)
    raws: list[bytes] = field(default_factory=list)


def read_bag(path: Path) -> dict[str, TopicData]:
    """Every message of a bag by topic, in the order the bag gives them."""
    topics: dict[str, TopicData] = {}
    store = get_typestore(Stores.ROS2_HUMBLE)
    with AnyReader([path], default_typestore=store) as reader:
        for connection, time, raw in reader.messages():
            data = topics.setdefault(connection.topic, TopicData(connection.msgtype))
            ext = connection.ext
            data.times.append(time)
            data.callerids.append(ext.callerid if isinstance(ext, ConnectionExtRosbag1) else None)
            data.messages.append(reader.deserialize(raw, connection.msgtype))
            data.raws.append(bytes(raw))
    return topics


def callerids(path: Path) -> dict[str, set[str | None]]:
    """The callerids of each topic's connections (None in ROS 2 bags)."""
    found: defaultdict[str, set[str | None]] = defaultdict(set)
    with AnyReader([path]) as reader:
        for connection in reader.connections:
            ext = connection.ext
            callerid = ext.callerid if isinstance(ext, ConnectionExtRosbag1) else None
            found[connection.topic].add(callerid)
    return dict(found)


def rate(times: list[int] | NDArray[np.int64]) -> float:
    """Messages per second over the span of the given times (ns)."""
    span = (int(times[-1]) - int(times[0])) / 1e9
    return (len(times) - 1) / span


def same_stream(a: Stream, b: Stream) -> bool:
    """Whether two streams hold the same messages at the same times."""

    def equal(x: NDArray[np.generic] | None, y: NDArray[np.generic] | None) -> bool:
        if x is None or y is None:
            return x is y
        return bool(np.array_equal(x, y))

    return (
        a.msgtype == b.msgtype
        and equal(a.time_ns, b.time_ns)
        and equal(a.values, b.values)
        and equal(a.stamp_ns, b.stamp_ns)
        and equal(a.seq, b.seq)
        and a.texts == b.texts
    )


def tilt(values: NDArray[np.float64]) -> NDArray[np.float64]:
    """The angle (rad) between the body's z axis and the vertical, from pose columns 3-6."""
    x, y = values[:, 3], values[:, 4]
    cosine = np.clip(1.0 - 2.0 * (x * x + y * y), -1.0, 1.0)
    angle: NDArray[np.float64] = np.arccos(cosine)
    return angle
