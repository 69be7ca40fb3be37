"""The tap's frames and the message definitions it sends
(``imrosc/onboard/record_ros2/wire.py``)."""

from __future__ import annotations

import ast
import io
import json
from pathlib import Path

import pytest

from imrosc.onboard.record_ros2 import wire

ROS2_SIDE = Path(wire.__file__).resolve().parent


def test_frames_go_through_whole_and_in_order() -> None:
    frames = [
        wire.event({"event": "topic", "id": 1, "topic": "/t"}),
        wire.message(1, 10, b"\x00\x01\x00\x00" + bytes(range(256))),
        wire.message(2, 2**63, b""),
        wire.event({"event": "ready"}),
    ]
    read = list(wire.read_frames(io.BytesIO(b"".join(frames))))
    assert [kind for kind, _ in read] == [wire.EVENT, wire.MESSAGE, wire.MESSAGE, wire.EVENT]
    assert json.loads(read[0][1]) == {"event": "topic", "id": 1, "topic": "/t"}
    assert wire.parse_message(read[1][1]) == (1, 10, b"\x00\x01\x00\x00" + bytes(range(256)))
    assert wire.parse_message(read[2][1]) == (2, 2**63, b"")


@pytest.mark.parametrize("cut", [1, 3, 5, 8, 20])
def test_a_frame_cut_short_ends_the_stream_after_the_whole_ones(cut: int) -> None:
    whole = wire.event({"event": "ready"})
    last = wire.message(1, 5, b"0123456789abcdef")
    read = list(wire.read_frames(io.BytesIO(whole + last[:cut])))
    assert read == [(wire.EVENT, b'{"event":"ready"}')]


def test_a_length_beyond_reason_ends_the_stream() -> None:
    broken = wire.MESSAGE + (wire.MAX_FRAME + 1).to_bytes(4, "little") + b"x" * 10
    assert list(wire.read_frames(io.BytesIO(broken))) == []


def test_used_types_follow_the_msg_grammar() -> None:
    text = """# a comment naming fake/Type
std_msgs/Header header
int32 LIMIT=5
string<=8 NAME="x"
geometry_msgs/Point[] points
Inner[<=3] inner   # same package
float64[9] covariance
string<=10[] labels
builtin_interfaces/msg/Time stamp
uint8 level 3
"""
    assert wire.used_types(text, "pkg/msg/Outer") == [
        "std_msgs/msg/Header",
        "geometry_msgs/msg/Point",
        "pkg/msg/Inner",
        "builtin_interfaces/msg/Time",
    ]


def test_definitions_close_over_the_types_used_once_each() -> None:
    texts = {
        "p/msg/A": "p/B b\nB[] more\nq/C c",
        "p/msg/B": "q/C c\nint8 x",
        "q/msg/C": "builtin_interfaces/Time t",
    }
    found, missing = wire.definitions("p/msg/A", texts.get)
    assert list(found) == ["p/msg/A", "p/msg/B", "q/msg/C"]
    assert missing == ["builtin_interfaces/msg/Time"]


def test_the_ros2_side_parses_as_python_3_8() -> None:
    for path in sorted(ROS2_SIDE.glob("*.py")):
        ast.parse(path.read_text(encoding="utf-8"), str(path), feature_version=(3, 8))
