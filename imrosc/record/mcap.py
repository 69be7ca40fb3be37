"""The ROS 2 bag of ``imrosc record``: an MCAP bag written with rosbags as messages arrive.

rosbag2 is not needed: the bag tap (:mod:`imrosc.onboard.record_ros2.tap`) announces each topic
with its type and the ``.msg`` definitions of the running system, and :class:`BagSink`
adds the connection (message definition and RIHS01 type hash from those definitions, types
the tap could not find taken from rosbags' Jazzy types), then writes every message, CDR
bytes as received, with its receive time. :meth:`BagSink.close` writes the MCAP summary and
``metadata.yaml``; until then imrosc reads the folder as a bag cut short (its whole chunks,
with a ``bag-recovered`` warning: :mod:`imrosc.bagrecover_ros2`).

>>> import tempfile, pathlib
>>> folder = pathlib.Path(tempfile.mkdtemp()) / "run"
>>> sink = BagSink(folder)
>>> _ = sink.add_topic({"id": 1, "topic": "/n", "type": "std_msgs/msg/Int8",
...                 "definitions": {"std_msgs/msg/Int8": "int8 data"}, "qos": []})
>>> sink.write(1, 5, bytes([0, 1, 0, 0, 7]))
>>> sink.close()
{'/n': 1}
>>> sorted(p.name for p in folder.iterdir())
['metadata.yaml', 'run.mcap']
"""

from __future__ import annotations

import functools
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any, Literal

from rosbags.interfaces import (
    Connection,
    Qos,
    QosDurability,
    QosHistory,
    QosLiveliness,
    QosReliability,
    QosTime,
)
from rosbags.rosbag2 import StoragePlugin, Writer
from rosbags.typesys import Stores, TypesysError, get_types_from_msg, get_typestore
from rosbags.typesys.store import Typestore

__all__ = ["BagSink", "SinkError", "offered_qos"]

VERSION: Literal[9] = 9
"""The rosbag2 metadata version (Jazzy's)."""
_INFINITE = QosTime(9223372036, 854775807)
_RELIABILITY = {"reliable": QosReliability.RELIABLE, "best_effort": QosReliability.BEST_EFFORT}
_DURABILITY = {
    "transient_local": QosDurability.TRANSIENT_LOCAL,
    "volatile": QosDurability.VOLATILE,
}


class SinkError(Exception):
    """A topic cannot be added (its type is not known); the message is one line."""


@functools.lru_cache(maxsize=1)
def _known_types() -> Typestore:
    """rosbags' ROS 2 Jazzy types: for the types the tap found no ``.msg`` of."""
    return get_typestore(Stores.ROS2_JAZZY)


def offered_qos(policies: Sequence[Sequence[str]]) -> list[Qos]:
    """The publishers' QoS as rosbag2 writes it into ``metadata.yaml`` (reliability and
    durability as the tap saw them; depth 0 and infinite times, as rosbag2 records them).

    >>> qos = offered_qos([("best_effort", "volatile")])
    >>> [(q.reliability.name, q.durability.name) for q in qos]
    [('BEST_EFFORT', 'VOLATILE')]
    """
    found = []
    for policy in policies:
        reliability, durability = (str(p) for p in policy[:2])
        found.append(
            Qos(
                QosHistory.UNKNOWN,
                0,
                _RELIABILITY.get(reliability, QosReliability.RELIABLE),
                _DURABILITY.get(durability, QosDurability.VOLATILE),
                _INFINITE,
                _INFINITE,
                QosLiveliness.AUTOMATIC,
                _INFINITE,
                avoid_ros_namespace_conventions=False,
            )
        )
    return found


class BagSink:
    """One MCAP bag being written: topics announced by the tap, messages as they come.
    Used by one thread (the one reading the tap's frames)."""

    def __init__(self, path: Path) -> None:
        self.path = path
        self.types = get_typestore(Stores.EMPTY)
        self.writer = Writer(path, version=VERSION, storage_plugin=StoragePlugin.MCAP)
        self.writer.open()
        self.connections: dict[int, Connection] = {}
        self.counts: dict[str, int] = {}
        self.closed = False

    def _register(self, type_name: str, definitions: Mapping[str, str]) -> None:
        """Register ``type_name`` and what it uses: the system's definitions, else rosbags'
        (all or nothing: a type that cannot be described leaves the store as it was)."""
        new: dict[str, Any] = {}
        for name, text in definitions.items():
            if name in self.types.fielddefs:
                continue
            try:
                new.update(get_types_from_msg(text, name))
            except TypesysError as error:
                reason = _line(error)
                raise SinkError(f"the definition of {name} cannot be read: {reason}") from None
        todo, seen = [type_name], set()
        while todo:
            name = todo.pop()
            if name in seen:
                continue
            seen.add(name)
            fields = self.types.fielddefs.get(name) or new.get(name)
            if fields is None:
                fields = _known_types().fielddefs.get(name)
                if fields is None:
                    raise SinkError(f"no definition of the message type {name} was found")
                new[name] = fields
            for _, (kind, detail) in fields[1]:
                todo += _names(kind, detail)
        try:
            self.types.register({k: v for k, v in new.items() if k not in self.types.fielddefs})
        except TypesysError as error:
            raise SinkError(f"the type {type_name} cannot be registered: {_line(error)}") from None

    def add_topic(self, announced: Mapping[str, Any]) -> Connection:
        """Add the connection the tap announced (``id``, ``topic``, ``type``,
        ``definitions``, ``qos``, the publishers' type ``hashes``); :class:`SinkError` if its
        type cannot be described. The type hash is the publishers' when they announce one,
        else computed from the definitions."""
        type_name = str(announced["type"])
        self._register(type_name, dict(announced.get("definitions") or {}))
        try:
            msgdef, _ = self.types.generate_msgdef(type_name, ros_version=2)
            digest = self.types.hash_rihs01(type_name)
        except (TypesysError, KeyError) as error:
            raise SinkError(f"the type {type_name} cannot be described: {_line(error)}") from None
        hashes = list(announced.get("hashes") or [])
        if len(hashes) == 1:  # what the publishers announce, as rosbag2 records it
            digest = str(hashes[0])
        connection = self.writer.add_connection(
            str(announced["topic"]),
            type_name,
            msgdef=msgdef,
            rihs01=digest,
            offered_qos_profiles=offered_qos(announced.get("qos") or []),
        )
        self.connections[int(announced["id"])] = connection
        self.counts.setdefault(connection.topic, 0)
        return connection

    def write(self, ident: int, stamp: int, data: bytes) -> None:
        """Write one message of an added connection (unknown ids are dropped)."""
        connection = self.connections.get(ident)
        if connection is None:
            return
        self.writer.write(connection, stamp, data)
        self.counts[connection.topic] += 1

    def close(self) -> dict[str, int]:
        """Finish the bag (MCAP summary, ``metadata.yaml``); the messages per topic."""
        if not self.closed:
            self.closed = True
            self.writer.close()
        return dict(self.counts)


def _line(error: Exception, width: int = 120) -> str:
    """An error as one short line (rosbags' parse errors span several).

    >>> _line(ValueError("Could not parse:\\n'x'\\n 19"))
    "Could not parse: 'x' 19"
    """
    text = " ".join(str(error).split())
    return text if len(text) <= width else text[: width - 3] + "..."


def _names(kind: Any, detail: Any) -> list[str]:
    """The message types a field of rosbags' ``fielddefs`` names."""
    from rosbags.interfaces import Nodetype

    if kind == Nodetype.NAME:
        return [str(detail)]
    if kind in (Nodetype.ARRAY, Nodetype.SEQUENCE):
        (inner_kind, inner_detail), _ = detail
        return _names(inner_kind, inner_detail)
    return []
