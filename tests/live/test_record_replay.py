"""End to end on real ROS 1, without the monitor: ``rosbag record`` of the running test system,
inference from the nominal recording, and replay of a recording with injected faults."""

from __future__ import annotations

import json
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import pytest
from click.testing import CliRunner

from imrosc.bags import open_bag
from imrosc.cli import main
from imrosc.detect import run_detect
from imrosc.invariants import dumps
from imrosc.replay import replay
from imrosc.runtime import Violation
from tests.live.harness import SYSTEM_TOPICS, Ros, live_config, record_nominal

pytestmark = pytest.mark.live

Z = "car_pose.pose.position.z"
COMMAND = "cmd_subject_ctrl_state.data"


@dataclass
class Recorded:
    config: Path
    nominal: list[Path]
    fault: Path


@pytest.fixture(scope="module")
def recorded(ros: Ros, tmp_path_factory: pytest.TempPathFactory) -> Recorded:
    """The test system recorded nominal, then with three poses at z = 50 m, one command 9
    and a second publisher of the poses (all injected about 1 s into the recording)."""
    folder = tmp_path_factory.mktemp("live")
    config = live_config(folder)
    ros.start_system()
    nominal = record_nominal(ros, folder / "bags" / "nominal")

    def inject() -> None:
        time.sleep(1.0)
        ros.inject("/a/car", "out_of_range:3")
        ros.inject("/a/car_ctrl", "out_of_range:1")
        intruder = ros.node("car.py", name="intruder", namespace="/a")
        ros.wait_publisher("/a/car_pose", "/a/intruder", watch=[intruder])

    fault = ros.record(folder / "fault.bag", SYSTEM_TOPICS, 3.0, during=inject)
    return Recorded(config, nominal, fault)


@pytest.fixture(scope="module")
def document(recorded: Recorded) -> dict[str, Any]:
    result = run_detect(recorded.config, workers=1)
    assert result.ok, [str(d) for d in result.diagnostics]
    assert result.document is not None
    return result.document


def of(found: list[Violation], family: str, variable: str) -> list[Violation]:
    return [v for v in found if v.family == family and variable in v.text]


def test_rosbag_record_writes_bags_imrosc_reads(recorded: Recorded) -> None:
    whole = recorded.nominal[0]
    assert whole.name == "nominal.bag"
    assert len(recorded.nominal) >= 8  # the split bags
    with open_bag(whole) as reader:
        types = {c.topic: c.msgtype for c in reader.connections}
        assert types == {
            "/a/car_pose": "geometry_msgs/msg/PoseStamped",
            "/a/cmd_subject_ctrl_state": "std_msgs/msg/UInt8",
            "/a/subject_ctrl_state": "std_msgs/msg/UInt8",
        }
        callerids = {c.topic: c.ext.callerid for c in reader.connections}  # type: ignore[union-attr]
        assert callerids["/a/car_pose"] == "/a/car"
        assert callerids["/a/cmd_subject_ctrl_state"] == "/a/car_ctrl"
        duration = (reader.end_time - reader.start_time) / 1e9
        assert 3.0 < duration < 5.0
        poses = [
            reader.deserialize(raw, c.msgtype)
            for c, _, raw in reader.messages()
            if c.topic == "/a/car_pose"
        ]
    assert 15 < len(poses) / duration < 25  # 20 Hz
    assert {p.pose.position.z for p in poses} <= {0.1, 0.12, 0.14, 0.16, 0.18}  # type: ignore[attr-defined]
    stamps = [p.header.stamp.sec + p.header.stamp.nanosec / 1e9 for p in poses]  # type: ignore[attr-defined]
    assert stamps == sorted(stamps)


def test_invariants_learnt_from_the_nominal_recording(document: dict[str, Any]) -> None:
    by_text = {i["text"]: i for i in document["invariants"]}
    z_bounds = [
        i for i in document["invariants"] if i["family"] == "bounds" and Z in i["variables"]
    ]
    assert [(i["params"]["min"], i["params"]["max"]) for i in z_bounds] == [(0.1, 0.18)]
    assert f"{COMMAND} == 3" in by_text
    frequency = next(
        i for i in document["invariants"] if i["family"] == "frequency" and i["point"] == "v"
    )
    assert 18 <= frequency["params"]["min"] <= frequency["params"]["max"] <= 22
    assert "max_pubs(/a/car_pose) = {/a/car}" in by_text


def test_the_nominal_recording_replays_clean(recorded: Recorded, document: dict[str, Any]) -> None:
    runs = replay(document, recorded.nominal)
    assert [r.error for r in runs] == [None] * len(runs)
    assert sum(r.messages for r in runs) > 100
    assert [v.text for r in runs for v in r.violations] == []


def test_the_faulty_recording_breaks_the_invariants(
    recorded: Recorded, document: dict[str, Any]
) -> None:
    (run,) = replay(document, [recorded.fault])
    assert run.error is None
    found = run.violations
    z = of(found, "bounds", Z)
    assert [v.observed for v in z] == [50.0] * 3
    assert {v.text for v in z} == {f"0.1 <= {Z} <= 0.18"}
    assert [v.observed for v in of(found, "one-of", COMMAND)] == [9.0]
    # the intruder's connection, then each of its messages (Engine.intruder): one invariant
    arch = [v for v in found if v.family == "architecture" and "/a/car_pose" in v.text]
    assert len(arch) > 1
    assert len({v.invariant for v in arch}) == 1
    assert all("/a/intruder" in json.dumps(v.observed, default=sorted) for v in arch)
    assert z[0].time >= run.start + 0.5  # injected about 1 s in


def test_the_cli_replays_the_recordings(recorded: Recorded, document: dict[str, Any]) -> None:
    inv = recorded.config.parent / "landing_live.inv"
    inv.write_text(dumps(document), encoding="utf-8")
    runner = CliRunner()
    clean = runner.invoke(main, ["replay", str(inv), str(recorded.nominal[0])])
    assert clean.exit_code == 0, clean.output
    faulty = runner.invoke(main, ["replay", str(inv), str(recorded.fault), "--format", "json"])
    assert faulty.exit_code == 1, faulty.output
    (run,) = json.loads(faulty.output)["runs"]
    broken = {e["text"] for e in run["episodes"]}
    assert "0.1 <= car_pose.pose.position.z <= 0.18" in broken
