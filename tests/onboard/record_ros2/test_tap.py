"""The bag tap's plain parts (``imrosc/onboard/record_ros2/tap.py`` and ``__main__.py``)
without ROS: where it finds ``.msg`` definitions, what it says without rclpy (Python 3.8
syntax: tests/onboard/test_py38.py). The tap on a ROS 2 graph: tests/backends/
test_ros2_record_live.py."""

from __future__ import annotations

import importlib.util
import subprocess
import sys
from pathlib import Path

import pytest

from imrosc.onboard.record_ros2 import tap, wire

NO_RCLPY = importlib.util.find_spec("rclpy") is None


def test_definitions_are_found_in_the_share_folder_of_each_prefix(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    first, second = tmp_path / "ws" / "install", tmp_path / "opt"
    (first / "share" / "robot" / "msg").mkdir(parents=True)
    (first / "share" / "robot" / "msg" / "Pose.msg").write_text("robot/Point p\n")
    (second / "share" / "robot" / "msg").mkdir(parents=True)
    (second / "share" / "robot" / "msg" / "Point.msg").write_text("float64 x\n")
    (tmp_path / "nothing").mkdir()
    prefixes = [first, tmp_path / "nothing", tmp_path / "missing", second]
    monkeypatch.setenv("AMENT_PREFIX_PATH", ":".join(map(str, prefixes)))
    folders = tap.share_folders()
    assert folders[:2] == [str(first / "share"), str(second / "share")]
    found, missing = wire.definitions(
        "robot/msg/Pose", lambda name: tap.find_definition(name, folders)
    )
    assert found == {"robot/msg/Pose": "robot/Point p\n", "robot/msg/Point": "float64 x\n"}
    assert missing == []
    assert tap.find_definition("robot/srv/Pose", folders) is None
    assert tap.find_definition("robot/msg/Other", folders) is None


@pytest.mark.skipif(not NO_RCLPY, reason="this Python has rclpy")
@pytest.mark.parametrize("module", ["imrosc.onboard.record_ros2.tap", "imrosc.onboard.record_ros2"])
def test_without_rclpy_each_says_so_in_one_line(module: str) -> None:
    done = subprocess.run(
        [sys.executable, "-m", module, "{}"], capture_output=True, text=True, check=False
    )
    assert done.returncode == 1
    assert done.stderr.strip().endswith("rclpy is not importable; run it under the ROS 2 Python")
    assert "Traceback" not in done.stderr
