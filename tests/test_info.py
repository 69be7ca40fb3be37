"""``imrosc info``: what bags hold, per bag and per topic (imrosc/info.py, the CLI command)."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from click.testing import CliRunner

from imrosc.cli import main
from imrosc.info import bag_info, collect
from tests.translate import msg, write_bag

SHARED = Path(__file__).resolve().parents[2] / "shared" / "data"
MCAP = SHARED / "fixtures" / "rosbags_rs" / "tests" / "test_bags" / "test_bag_mcap"


def _bag(path: Path) -> Path:
    messages = [
        msg("/speed", 10.0 + k / 10, "std_msgs/msg/Float64", "/driver", data=k) for k in range(11)
    ]
    messages += [msg("/speed", 10.05, "std_msgs/msg/Float64", "/intruder", data=1.0)]
    messages += [msg("/note", 11.0, "std_msgs/msg/String", "/talker", data="hi")]
    messages += [msg("/imrosc/arch", 10.0, "std_msgs/msg/String", "/imrosc_record", data="{}")]
    return write_bag(path, messages)


def test_a_ros1_bag_is_told_topic_by_topic(tmp_path: Path) -> None:
    info = bag_info(_bag(tmp_path / "run.bag"))
    assert (info.storage, info.messages) == ("ros1", 14)
    assert info.duration == pytest.approx(1.0)
    note, speed = info.topics  # by name
    assert (speed.topic, speed.msgtype, speed.messages) == ("/speed", "std_msgs/msg/Float64", 12)
    assert speed.rate == pytest.approx(12.0) and speed.publishers == ("/driver", "/intruder")
    assert (speed.numeric, speed.strings, speed.arrays, speed.variables) == (1, 0, 0, ("data",))
    assert speed.usable and note.usable and (note.numeric, note.strings) == (0, 1)
    assert [r.topic for r in info.records] == ["/imrosc/arch"]


def test_a_ros2_mcap_bag_from_another_project() -> None:
    info = bag_info(MCAP)
    assert info.storage == "ros2 (mcap)" and info.messages == 188
    accel = next(t for t in info.topics if t.topic == "/test/geometry_msgs/accel")
    assert accel.numeric == 6 and accel.variables[0] == "linear.x" and accel.usable


def test_the_command_prints_text_and_json(tmp_path: Path) -> None:
    bag = _bag(tmp_path / "run.bag")
    done = CliRunner().invoke(main, ["info", str(bag)])
    assert done.exit_code == 0, done.output
    assert "/speed" in done.output and "12 msgs" in done.output and "12 Hz" in done.output
    assert "published by /driver, /intruder" in done.output
    assert "1 numeric, 0 string, 0 array variables: data" in done.output
    done = CliRunner().invoke(main, ["info", str(tmp_path), "--format", "json"])
    assert done.exit_code == 0, done.output
    (found,) = json.loads(done.stdout)
    assert found["bag"] == str(bag) and found["topics"][0]["usable"] is True


def test_unreadable_bags_are_named_and_the_others_told(tmp_path: Path) -> None:
    good = _bag(tmp_path / "good.bag")
    bad = tmp_path / "bad.bag"
    bad.write_bytes(b"#ROSBAG V2.0\n" + b"\x00" * 40)
    done = CliRunner().invoke(main, ["info", str(good), str(bad)])
    assert done.exit_code == 1 and "Traceback" not in done.output
    assert f"imrosc info: {bad}" in done.stderr and "/speed" in done.stdout
    done = CliRunner().invoke(main, ["info", str(tmp_path / "missing.bag")])
    assert done.exit_code == 2 and "no such file or directory" in done.stderr
    infos, problems = collect([bad])
    assert infos == [] and len(problems) == 1
