"""``imrosc record --ros2`` on the command line, where things go wrong before anything is
recorded: one line on stderr, exit status 1 (2 for a bad option), no traceback. Recording
itself is tested live (tests/backends/test_ros2_record_live.py)."""

from __future__ import annotations

import importlib.util
import sys
from pathlib import Path

import pytest
from click.testing import CliRunner, Result

from imrosc.cli import main
from imrosc.record.command_ros2 import existing_ros2_bags, is_ros2_bag
from tests.record.support import CONFIG, one_line_error

NO_RCLPY = importlib.util.find_spec("rclpy") is None


def record(*args: str, **env: str | None) -> Result:
    environment: dict[str, str | None] = {"IMROSC_ROS2_PYTHON": None, "ROS_VERSION": None}
    environment.update(env)
    return CliRunner().invoke(main, ["record", *args], env=environment)


@pytest.fixture
def config(tmp_path: Path) -> Path:
    path = tmp_path / "robot.xml"
    path.write_text(CONFIG, encoding="utf-8")
    return path


@pytest.mark.skipif(not NO_RCLPY, reason="this Python has rclpy")
def test_without_a_ros2_python_it_says_what_to_set(config: Path, tmp_path: Path) -> None:
    line = one_line_error(record(str(config), "-o", str(tmp_path / "out"), "--ros2"))
    assert line.startswith("imrosc record: no Python with rclpy: set IMROSC_ROS2_PYTHON")
    assert not (tmp_path / "out").exists()


@pytest.mark.skipif(not NO_RCLPY, reason="this Python has rclpy")
def test_ros_version_2_chooses_ros2_and_ros1_overrides_it(config: Path, tmp_path: Path) -> None:
    out = str(tmp_path / "out")
    line = one_line_error(record(str(config), "-o", out, ROS_VERSION="2"))
    assert "no Python with rclpy" in line
    ros1 = one_line_error(
        record(
            str(config), "-o", out, "--ros1", ROS_VERSION="2", ROS_MASTER_URI="http://127.0.0.1:9"
        )
    )
    assert "no ROS master" in ros1


def test_a_python_without_rclpy_is_named(config: Path, tmp_path: Path) -> None:
    out = str(tmp_path / "out")
    missing = one_line_error(record(str(config), "-o", out, "--ros2", "--python", "/no/python"))
    assert missing.startswith("imrosc record: cannot run the ROS 2 Python /no/python")
    if NO_RCLPY:
        line = one_line_error(
            record(str(config), "-o", out, "--ros2", IMROSC_ROS2_PYTHON=sys.executable)
        )
        assert line.startswith(f"imrosc record: the ROS 2 Python {sys.executable} cannot import")


@pytest.mark.parametrize(
    "args",
    [("--launch", "x.launch"), ("--launch-out", "y"), ("--server", "/s=/n"), ("--all-params",)],
)
def test_ros1_only_options_are_usage_errors(config: Path, tmp_path: Path, args: tuple[str]) -> None:
    result = record(str(config), "-o", str(tmp_path / "out"), "--ros2", *args)
    assert result.exit_code == 2, result.output
    assert f"{args[0]} is for ROS 1 only" in result.stderr
    assert "Traceback" not in result.output


def test_a_bag_in_the_folder_is_refused_unless_forced(config: Path, tmp_path: Path) -> None:
    out = tmp_path / "out"
    old = out / "small_robot"
    old.mkdir(parents=True)
    (old / "metadata.yaml").write_text("rosbag2_bagfile_information: {}\n")
    (old / "small_robot.mcap").write_bytes(b"")
    args = (str(config), "-o", str(out), "--ros2", "--python", "/no/python")
    line = one_line_error(record(*args), 2)  # an output refused
    assert line == (
        f"imrosc record: {out} holds a bag already (small_robot): record into a new folder, "
        f"or use --force"
    )
    assert old.exists()
    forced = one_line_error(record(*args, "--force"))
    assert "cannot run the ROS 2 Python" in forced  # got past the check
    assert not old.exists()  # the old bag of that name is replaced


def test_a_folder_of_that_name_that_is_not_a_bag_is_never_removed(
    config: Path, tmp_path: Path
) -> None:
    notes = tmp_path / "out" / "small_robot"
    notes.mkdir(parents=True)
    (notes / "notes.txt").write_text("mine")
    args = (str(config), "-o", str(tmp_path / "out"), "--ros2", "--python", "/no/python")
    line = one_line_error(record(*args, "--force"), 2)
    assert line == f"imrosc record: {notes}: exists and is not a ROS 2 bag; choose another --name"
    assert (notes / "notes.txt").read_text() == "mine"


def test_configuration_errors_come_first(tmp_path: Path) -> None:
    bad = tmp_path / "bad.xml"
    bad.write_text('<imROS project="p"><scope><call id="Q">/x</call></scope></imROS>')
    result = record(str(bad), "-o", str(tmp_path / "out"), "--ros2")
    assert result.exit_code == 1
    assert f"{bad}:1:" in result.stderr
    assert "Traceback" not in result.output


def test_what_counts_as_a_ros2_bag(tmp_path: Path) -> None:
    killed = tmp_path / "killed"
    killed.mkdir()
    (killed / "killed.mcap").write_bytes(b"")  # a recording that was killed: no metadata
    empty = tmp_path / "empty"
    empty.mkdir()
    (tmp_path / "old.bag").write_bytes(b"")
    (tmp_path / ".hidden").mkdir()
    assert is_ros2_bag(killed) and not is_ros2_bag(empty)
    assert [p.name for p in existing_ros2_bags(tmp_path)] == ["old.bag", "killed"]
