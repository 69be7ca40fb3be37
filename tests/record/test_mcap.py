"""The MCAP bag of ``imrosc record --ros2`` (``imrosc/record/mcap.py``): connections from the
definitions the tap sends, messages as they come, a bag ``imrosc`` reads back."""

from __future__ import annotations

import struct
from pathlib import Path
from typing import Any, cast

import pytest
from rosbags.typesys import Stores, get_typestore

from imrosc import records
from imrosc.bags import open_bag
from imrosc.record.mcap import BagSink, SinkError, offered_qos

JAZZY = get_typestore(Stores.ROS2_JAZZY)
POINT = "float64 x\nfloat64 y\nfloat64 z\n"
STAMPED = "std_msgs/Header header\ngeometry_msgs/Point point\n"
HEADER = "builtin_interfaces/Time stamp\nstring frame_id\n"


def cdr_string(text: str) -> bytes:
    data = text.encode() + b"\x00"
    return b"\x00\x01\x00\x00" + struct.pack("<I", len(data)) + data


def test_a_bag_of_system_types_reads_back_with_their_values(tmp_path: Path) -> None:
    sink = BagSink(tmp_path / "run")
    sink.add_topic(
        {
            "id": 7,
            "topic": "/a/pose",
            "type": "geometry_msgs/msg/PointStamped",
            "definitions": {
                "geometry_msgs/msg/PointStamped": STAMPED,
                "geometry_msgs/msg/Point": POINT,
                "std_msgs/msg/Header": HEADER,
            },
            "qos": [["best_effort", "volatile"]],
        }
    )
    sink.add_topic(
        {
            "id": 1,
            "topic": records.ARCH_TOPIC,
            "type": "std_msgs/msg/String",
            "definitions": {"std_msgs/msg/String": "string data"},
            "qos": [["reliable", "transient_local"]],
        }
    )
    message = JAZZY.types["geometry_msgs/msg/PointStamped"](
        JAZZY.types["std_msgs/msg/Header"](JAZZY.types["builtin_interfaces/msg/Time"](3, 4), "map"),
        JAZZY.types["geometry_msgs/msg/Point"](1.0, 2.0, 3.0),
    )
    raw = bytes(JAZZY.serialize_cdr(message, "geometry_msgs/msg/PointStamped"))
    arch = records.encode(records.ArchSnapshot({}, {}))
    sink.write(7, 1_000, raw)
    sink.write(1, 2_000, cdr_string(arch))
    sink.write(99, 3_000, b"unknown connection: dropped")
    assert sink.close() == {"/a/pose": 1, records.ARCH_TOPIC: 1}
    with open_bag(tmp_path / "run") as reader:
        found = {c.topic: c for c in reader.connections}
        assert found["/a/pose"].digest == JAZZY.hash_rihs01("geometry_msgs/msg/PointStamped")
        assert found[records.ARCH_TOPIC].digest == JAZZY.hash_rihs01("std_msgs/msg/String")
        qos = found["/a/pose"].ext.offered_qos_profiles  # type: ignore[union-attr]
        assert [q.reliability.name for q in qos] == ["BEST_EFFORT"]
        read = [
            (c.topic, stamp, reader.deserialize(data, c.msgtype))
            for c, stamp, data in reader.messages()
        ]
    assert [(topic, stamp) for topic, stamp, _ in read] == [
        ("/a/pose", 1_000),
        (records.ARCH_TOPIC, 2_000),
    ]
    pose = cast(Any, read[0][2])
    assert (pose.header.frame_id, pose.point.z) == ("map", 3.0)
    assert cast(Any, read[1][2]).data == arch


def test_types_without_a_definition_come_from_rosbags_jazzy_types(tmp_path: Path) -> None:
    sink = BagSink(tmp_path / "run")
    connection = sink.add_topic(
        {"id": 1, "topic": "/imu", "type": "sensor_msgs/msg/Imu", "definitions": {}, "qos": []}
    )
    assert connection.digest == JAZZY.hash_rihs01("sensor_msgs/msg/Imu")
    sink.close()


def test_the_publishers_type_hash_is_kept(tmp_path: Path) -> None:
    sink = BagSink(tmp_path / "run")
    announced = {"id": 1, "topic": "/n", "type": "std_msgs/msg/Int8"}
    connection = sink.add_topic({**announced, "hashes": ["RIHS01_" + "ab" * 32]})
    assert connection.digest == "RIHS01_" + "ab" * 32
    sink.close()


def test_an_unknown_type_is_refused_in_one_line(tmp_path: Path) -> None:
    sink = BagSink(tmp_path / "run")
    announced = {
        "id": 1,
        "topic": "/odd",
        "type": "robot/msg/Odd",
        "definitions": {"robot/msg/Odd": "robot/Inner inner"},
    }
    with pytest.raises(SinkError, match="no definition of the message type robot/msg/Inner"):
        sink.add_topic(announced)
    with pytest.raises(SinkError, match="cannot be read: Could not parse") as refused:
        sink.add_topic({**announced, "definitions": {"robot/msg/Odd": "int32[ x"}})
    assert "\n" not in str(refused.value)
    assert sink.close() == {}


def test_the_bag_of_no_message_still_opens(tmp_path: Path) -> None:
    BagSink(tmp_path / "empty").close()
    with open_bag(tmp_path / "empty") as reader:
        assert list(reader.messages()) == []


def test_offered_qos_keeps_the_two_policies_that_matter() -> None:
    profiles = offered_qos([["reliable", "transient_local"], ["best_effort", "volatile"]])
    assert [(q.reliability.name, q.durability.name) for q in profiles] == [
        ("RELIABLE", "TRANSIENT_LOCAL"),
        ("BEST_EFFORT", "VOLATILE"),
    ]
