"""A blocked topic's values read from CDR bytes (``imrosc/onboard/monitor_ros2/cdr.py``), with
stand-ins for rclpy's message classes and bytes packed as ROS 2's DDS layers write them.
``tests/backends/test_ros2_cdr_live.py`` checks the reader against rclpy's own
serialisation."""

from __future__ import annotations

import math
import struct
from typing import Any

import numpy as np
import pytest

from imrosc.onboard.monitor_ros2 import cdr

CDR_LE = b"\x00\x01\x00\x00"


def fake(fields: dict[str, str]) -> Any:
    """A stand-in for an rclpy message class: ``get_fields_and_field_types``."""

    class Fake:
        @staticmethod
        def get_fields_and_field_types() -> dict[str, str]:
            return dict(fields)

    return Fake


TIME = fake({"sec": "int32", "nanosec": "uint32"})
HEADER = fake({"stamp": "builtin_interfaces/Time", "frame_id": "string"})
DIMENSION = fake({"label": "string", "size": "uint32", "stride": "uint32"})
JOINTS = fake(
    {
        "header": "std_msgs/Header",
        "name": "sequence<string>",
        "position": "sequence<double>",
        "velocity": "sequence<double>",
    }
)
CLASSES = {
    "builtin_interfaces/Time": TIME,
    "std_msgs/Header": HEADER,
    "std_msgs/MultiArrayDimension": DIMENSION,
}


def cdr_string(text: bytes, at: int) -> tuple[bytes, int]:
    """A CDR string at offset ``at`` of the data (after the encapsulation): padding to 4,
    the length with the NUL, the bytes and the NUL; and the offset after it."""
    pad = b"\x00" * (-at % 4)
    body = pad + struct.pack("<I", len(text) + 1) + text + b"\x00"
    return body, at + len(body)


def joints(frame: bytes, names: list[bytes], position: list[float], velocity: list[float]) -> bytes:
    data = struct.pack("<iI", 7, 9)
    piece, at = cdr_string(frame, len(data))
    data += piece
    data += b"\x00" * (-at % 4) + struct.pack("<I", len(names))
    at = len(data)
    for name in names:
        piece, at = cdr_string(name, at)
        data += piece
    for values in (position, velocity):
        data += b"\x00" * (-len(data) % 4) + struct.pack("<I", len(values))
        if values:
            data += b"\x00" * (-len(data) % 8) + struct.pack(f"<{len(values)}d", *values)
    return CDR_LE + data


def elements(count: int) -> list[dict[str, Any]]:
    return [{"path": f"position[{i}]", "type": "float", "derived": None} for i in range(count)]


@pytest.mark.parametrize("frame", [b"", b"a", b"map", b"odom_frame"])
def test_leading_elements_of_a_float64_sequence_are_read_in_place_whatever_the_padding(
    frame: bytes,
) -> None:
    read = cdr.reader(JOINTS, elements(3), CLASSES.get)
    assert read is not None
    data = joints(frame, [b"j1", b"joint2"], [0.5, 1.5, 2.5, 3.5], [9.0])
    values = read(data)
    assert isinstance(values, np.ndarray) and values.tolist() == [0.5, 1.5, 2.5]
    short = read(joints(frame, [], [4.0], []))
    assert short[0] == 4.0 and math.isnan(short[1]) and math.isnan(short[2])
    assert all(math.isnan(v) for v in read(joints(frame, [], [], [])))


def test_strings_statistics_elements_and_fields_after_a_sequence() -> None:
    layout: list[dict[str, Any]] = [
        {"path": "header.frame_id", "type": "string", "derived": None},
        {"path": "header.stamp.nanosec", "type": "float", "derived": None},
        {"path": "position", "type": "float", "derived": "avg"},
        {"path": "velocity[0]", "type": "float", "derived": None},
        {"path": "velocity[5]", "type": "float", "derived": None},
        {"path": "position", "type": "float", "derived": "len"},
    ]
    read = cdr.reader(JOINTS, layout, CLASSES.get)
    assert read is not None
    got = read(joints("é".encode(), [b"x"], [1.0, 2.0, 6.0], [-2.0]))
    assert got[:5] == ["é", 9.0, 3.0, -2.0, got[4]] and math.isnan(got[4]) and got[5] == 3.0


def test_an_array_of_messages_is_walked_past() -> None:
    layout_class = fake(
        {"dim": "sequence<std_msgs/MultiArrayDimension>", "offset": "uint32", "data": "float[2]"}
    )
    read = cdr.reader(
        layout_class,
        [{"path": "offset", "type": "float"}, {"path": "data", "derived": "max"}],
        CLASSES.get,
    )
    assert read is not None
    data = struct.pack("<I", 2)
    for label in (b"rows", b"c"):
        piece, _ = cdr_string(label, len(data))
        data += piece + b"\x00" * (-(len(data) + len(piece)) % 4)
        data += struct.pack("<II", 3, 1)  # size, stride
    data += struct.pack("<I2f", 12, 0.5, 1.5)
    assert read(CDR_LE + data) == [12.0, 1.5]


@pytest.mark.parametrize(
    ("fields", "path", "kind"),
    [
        ({"b": "octet"}, "b", "float"),
        ({"c": "char"}, "c", "float"),
        ({"w": "wstring"}, "w", "string"),
        ({"names": "sequence<string>"}, "names[0]", "string"),
        ({"dims": "sequence<std_msgs/MultiArrayDimension>"}, "dims.size", "float"),
        ({"s": "string"}, "s", "float"),
        ({"x": "double"}, "x", "string"),
        ({"x": "double"}, "y", "float"),
        ({"p": "pkg/Missing"}, "p.x", "float"),
    ],
)
def test_a_layout_the_plan_does_not_cover_gets_no_reader(
    fields: dict[str, str], path: str, kind: str
) -> None:
    assert cdr.reader(fake(fields), [{"path": path, "type": kind}], CLASSES.get) is None


def test_bytes_the_plan_cannot_read_raise_for_the_node_to_deserialise() -> None:
    read = cdr.reader(JOINTS, elements(2), CLASSES.get)
    assert read is not None
    data = joints(b"f", [], [1.0, 2.0], [])
    with pytest.raises(ValueError, match="encapsulation"):
        read(b"\x00\x00\x00\x00" + data[4:])  # big-endian CDR
    general = cdr.reader(JOINTS, [{"path": "header.frame_id", "type": "string"}], CLASSES.get)
    assert general is not None
    with pytest.raises((ValueError, struct.error)):
        general(data[:14])
