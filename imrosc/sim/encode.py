"""Vectorised serialization of the simulator's fixed-layout messages.

A stamped pose or transform whose frame names are the same in every message has one byte
layout for all of them, in ROS 1 and in CDR alike: the simulator fills a numpy structured array
(one row per message) and cuts its bytes into messages, instead of building and serializing
one rosbags message object at a time (about 30 us each in ROS 1). The layouts follow the ROS 1
wire format (little-endian, packed, strings as ``uint32`` length and bytes) and CDR (the 4-byte
little-endian encapsulation header, primitives aligned to their size from the end of that
header, strings with their NUL counted and written); ``tests/sim`` checks them byte for byte
against rosbags' own serializers.

Types with variable-length content (``sensor_msgs/BatteryState``, the record strings) go
through rosbags' typestore; there are few of them.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

__all__ = ["CDR_HEADER", "Layout", "pose_layout", "serialize_rows", "uint8_layout"]

CDR_HEADER = b"\x00\x01\x00\x00"
"""Little-endian plain CDR, as ROS 2 writes it."""


@dataclass
class Layout:
    """The byte layout of one message type with fixed strings, built field by field."""

    cdr: bool
    names: list[str] = field(default_factory=list)
    formats: list[str] = field(default_factory=list)
    offsets: list[int] = field(default_factory=list)
    constants: list[tuple[int, bytes]] = field(default_factory=list)
    size: int = 0

    @property
    def base(self) -> int:
        """Where the message body starts: after the CDR encapsulation header."""
        return len(CDR_HEADER) if self.cdr else 0

    def _align(self, size: int) -> None:
        if self.cdr:
            self.size = (self.size + size - 1) // size * size

    def scalar(self, name: str, fmt: str, size: int) -> None:
        """A primitive field filled per message (``fmt`` is a numpy format, ``'<f8'``)."""
        self._align(size)
        self.names.append(name)
        self.formats.append(fmt)
        self.offsets.append(self.base + self.size)
        self.size += size

    def array(self, name: str, count: int) -> None:
        """A run of ``count`` float64 values filled per message (fixed-size, no length)."""
        self._align(8)
        self.names.append(name)
        self.formats.append(f"({count},)<f8")
        self.offsets.append(self.base + self.size)
        self.size += 8 * count

    def string(self, text: str) -> None:
        """A string that is the same in every message."""
        data = text.encode()
        if self.cdr:
            data += b"\x00"
        self._align(4)
        self.constants.append((self.base + self.size, len(data).to_bytes(4, "little") + data))
        self.size += 4 + len(data)

    def dtype(self) -> np.dtype[np.void]:
        """The structured dtype of one serialized message, header included."""
        spec = {
            "names": self.names,
            "formats": self.formats,
            "offsets": self.offsets,
            "itemsize": self.base + self.size,
        }
        return np.dtype(spec)  # type: ignore[call-overload,no-any-return]

    def template(self) -> bytes:
        """One message with every constant written and zeros elsewhere."""
        row = bytearray(self.base + self.size)
        if self.cdr:
            row[: len(CDR_HEADER)] = CDR_HEADER
        for offset, data in self.constants:
            row[offset : offset + len(data)] = data
        return bytes(row)


def _header(layout: Layout, frame_id: str, *, ros1: bool) -> None:
    if ros1:
        layout.scalar("seq", "<u4", 4)
        layout.scalar("sec", "<u4", 4)
    else:
        layout.scalar("sec", "<i4", 4)
    layout.scalar("nsec", "<u4", 4)
    layout.string(frame_id)


def pose_layout(cdr: bool, frame_id: str, child_frame_id: str | None = None) -> Layout:
    """``geometry_msgs/PoseStamped``, or ``TransformStamped`` when a child frame is given.

    Both are a header, (for a transform) the child frame, then seven float64: position or
    translation x, y, z and the quaternion x, y, z, w.
    """
    layout = Layout(cdr)
    _header(layout, frame_id, ros1=not cdr)
    if child_frame_id is not None:
        layout.string(child_frame_id)
    layout.array("values", 7)
    return layout


def uint8_layout(cdr: bool) -> Layout:
    """``std_msgs/UInt8``: one byte."""
    layout = Layout(cdr)
    layout.scalar("data", "<u1", 1)
    return layout


def serialize_rows(
    layout: Layout, columns: dict[str, NDArray[np.generic]], count: int
) -> list[bytes]:
    """``count`` messages of the layout, each field taken from ``columns`` by name."""
    size = layout.base + layout.size
    if count == 0:
        return []
    buffer = np.tile(np.frombuffer(layout.template(), dtype=np.uint8), count)
    rows = buffer.view(layout.dtype())
    for name in layout.names:
        rows[name] = columns[name]
    raw = buffer.tobytes()
    return [raw[start : start + size] for start in range(0, count * size, size)]


def stamp_columns(stamp_ns: NDArray[np.int64]) -> dict[str, NDArray[np.generic]]:
    """The ``sec`` and ``nsec`` columns of header stamps given in nanoseconds."""
    return {
        "sec": (stamp_ns // 1_000_000_000).astype(np.int64),
        "nsec": (stamp_ns % 1_000_000_000).astype(np.int64),
    }
