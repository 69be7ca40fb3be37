"""The ROS 2 session of ``imrosc record`` without ROS (``imrosc/record/session_ros2.py``):
the ROS 2 Python, the children's environment, and the tap's frames written into the bag."""

from __future__ import annotations

import importlib.util
import io
import os
import struct
import sys
import threading
from pathlib import Path

import pytest

from imrosc import records
from imrosc.bags import open_bag
from imrosc.onboard.record_ros2 import wire
from imrosc.record.scope import Scope
from imrosc.record.session import PACKAGE, RecordError, link_package
from imrosc.record.session_ros2 import (
    PYTHON_VARIABLE,
    Settings2,
    TapRecording,
    check_python,
    choose_python,
    ros2_environment,
)


def test_the_ros2_python_is_the_option_then_the_variable() -> None:
    assert choose_python("/given", {PYTHON_VARIABLE: "/named"}) == "/given"
    assert choose_python(None, {PYTHON_VARIABLE: "/named"}) == "/named"


@pytest.mark.skipif(importlib.util.find_spec("rclpy") is not None, reason="this Python has rclpy")
def test_without_rclpy_anywhere_it_says_what_to_set() -> None:
    with pytest.raises(RecordError, match=f"no Python with rclpy: set {PYTHON_VARIABLE}"):
        choose_python(None, {})


def test_a_python_without_rclpy_is_refused_in_one_line(tmp_path: Path) -> None:
    with pytest.raises(RecordError, match="cannot run the ROS 2 Python"):
        check_python(str(tmp_path / "missing"), os.environ)
    if importlib.util.find_spec("rclpy") is None:
        with pytest.raises(RecordError, match="cannot import rclpy: ModuleNotFoundError"):
            check_python(sys.executable, os.environ)


def test_the_children_find_imrosc_through_a_link_and_nothing_else(tmp_path: Path) -> None:
    folder = link_package(tmp_path / "path")
    assert [p.name for p in folder.iterdir()] == ["imrosc"]
    assert (folder / "imrosc").resolve() == PACKAGE
    assert link_package(folder) == folder  # again: kept
    env = ros2_environment({"PYTHONPATH": "/opt/ros/lib", "ROS_NAMESPACE": "/x"}, folder)
    assert env["PYTHONPATH"] == f"{folder}{os.pathsep}/opt/ros/lib"
    assert "ROS_NAMESPACE" not in env


def cdr_string(text: str) -> bytes:
    data = text.encode() + b"\x00"
    return b"\x00\x01\x00\x00" + struct.pack("<I", len(data)) + data


def recording(tmp_path: Path) -> TapRecording:
    settings = Settings2(tmp_path / "out", "run")
    return TapRecording(
        Scope(topics=("/n",)),
        settings,
        {},
        lambda arch: ("/n",),
        say=lambda text: None,
        warn=lambda text: None,
    )


def test_the_tap_s_frames_become_the_bag(tmp_path: Path) -> None:
    session = recording(tmp_path)
    from imrosc.record.mcap import BagSink

    session.sink = BagSink(session.settings.bag)
    arch = records.encode(records.ArchSnapshot({}, {}))
    stream = b"".join(
        [
            wire.event(
                {
                    "event": "topic",
                    "id": 1,
                    "topic": records.ARCH_TOPIC,
                    "type": "std_msgs/msg/String",
                    "definitions": {"std_msgs/msg/String": "string data"},
                    "qos": [["reliable", "transient_local"]],
                }
            ),
            wire.event({"event": "topic", "id": 2, "topic": "/odd", "type": "robot/msg/Odd"}),
            wire.event({"event": "graph", "arch": arch}),
            wire.message(1, 5, cdr_string(arch)),
            wire.message(2, 6, b"dropped: its topic was refused"),
            wire.event({"event": "ready"}),
            wire.message(1, 7, cdr_string(arch))[:-3],  # the tap killed while it wrote
        ]
    )
    session._read_frames(io.BytesIO(stream))
    warnings: list[str] = []
    session.warn = warnings.append
    session.pump()
    assert session.state == {"graph": arch, "tap ready": True}
    assert warnings == ["/odd: no definition of the message type robot/msg/Odd was found"]
    assert session.sink.close() == {records.ARCH_TOPIC: 1}
    with open_bag(session.settings.bag) as reader:
        assert [stamp for _, stamp, _ in reader.messages()] == [5]


def test_finishing_a_recording_that_never_started_says_so(tmp_path: Path) -> None:
    with pytest.raises(RecordError, match="no bag was written"):
        recording(tmp_path).finish()


def test_a_bag_that_cannot_be_written_is_one_line_before_anything_starts(tmp_path: Path) -> None:
    session = recording(tmp_path)
    session.settings.bag.mkdir(parents=True)  # there already: rosbags refuses it
    with pytest.raises(RecordError, match=r"out: cannot write the bag: .*exists"):
        session.start(threading.Event())
    assert session.tap is None
    blocked = recording(tmp_path / "other")
    (blocked.settings.logs / "path" / "imrosc").mkdir(parents=True)  # not imrosc's link
    with pytest.raises(RecordError, match="cannot write the bag: File exists"):
        blocked.start(threading.Event())
