"""The live harness and the test system on a real roscore: nodes talk, faults are injected
on demand, and nothing survives the teardown."""

from __future__ import annotations

import socket
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest

from tests.live.harness import Listener, Ros, token_pids, wait_until

pytestmark = pytest.mark.live

XS = {1.0, 1.25, 1.5, 1.75, 2.0, 2.25, 2.5}
YS = {2.0, 1.75, 1.5}
ZS = {0.1, 0.12, 0.14, 0.16, 0.18}
POSE, COMMAND, STATE = "/a/car_pose", "/a/cmd_subject_ctrl_state", "/a/subject_ctrl_state"


@pytest.fixture(scope="module")
def commands_log(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return tmp_path_factory.mktemp("system") / "commands.jsonl"


@pytest.fixture(scope="module")
def listener(ros: Ros, commands_log: Path) -> Iterator[Listener]:
    """The test system, launched, and a listener on its three topics."""
    ros.start_system(log=commands_log)
    yield ros.listen(POSE, COMMAND, STATE)


def z(record: dict[str, Any]) -> float:
    value: float = record["msg"]["pose"]["position"]["z"]
    return value


def data(records: list[dict[str, Any]]) -> list[int]:
    return [r["msg"]["data"] for r in records]


def test_roscore_runs_on_a_free_port_with_its_own_home(ros: Ros) -> None:
    assert ros.port != 11311
    assert ros.call("getUri").rstrip("/") == ros.uri
    assert "/rosout" in ros.system_state().publishers["/rosout_agg"]
    assert ros.env["ROS_HOSTNAME"] == "127.0.0.1"
    for variable in ("ROS_HOME", "ROS_LOG_DIR"):
        assert Path(ros.env[variable]).is_relative_to(ros.home)
    assert any((ros.home / "ros_log").rglob("master.log"))  # roscore logs in the tmp home


def test_the_test_system_talks(ros: Ros, listener: Listener, commands_log: Path) -> None:
    poses = listener.wait_count(20, POSE)
    assert {p["callerid"] for p in poses} == {"/a/car"}
    assert {p["type"] for p in poses} == {"geometry_msgs/PoseStamped"}
    positions = [p["msg"]["pose"]["position"] for p in poses]
    assert {p["x"] for p in positions} <= XS
    assert {p["y"] for p in positions} <= YS
    assert {p["z"] for p in positions} <= ZS
    stamps = [p["msg"]["header"]["stamp"] for p in poses]
    assert stamps == sorted(stamps)
    rate = (len(poses) - 1) / (poses[-1]["t"] - poses[0]["t"])
    assert 12 < rate < 30, rate  # 20 Hz

    commands = listener.wait_count(3, COMMAND)
    assert {(c["callerid"], c["msg"]["data"]) for c in commands} == {("/a/car_ctrl", 3)}
    listener.wait(lambda found: any(s["msg"]["data"] == 3 for s in found), "state 3", topic=STATE)

    received = wait_until(lambda: commands_log.read_text().splitlines(), "the state machine's log")
    assert '"data": 3' in received[0] and '"/a/car_ctrl"' in received[0]

    state = ros.system_state()
    assert "/a/car_ctrl" in state.subscribers[POSE]
    assert "/a/ctrl_state_machine" in state.subscribers[COMMAND]
    assert ros.get_param("/a/car_ctrl") == {
        "landing_radius": 0.5,
        "landing_time": 1.5,
        "poll_rate": 2.0,
    }


def test_out_of_range_values_on_demand(ros: Ros, listener: Listener, commands_log: Path) -> None:
    start = len(listener.wait_count(1, POSE))
    ros.inject("/a/car", "out_of_range:2")
    wait_until(lambda: not ros.has_param("/a/car/fault"), "the car to take the fault")
    found = listener.wait(
        lambda found: (
            len(found) > start
            and sum(z(p) == 50.0 for p in found[start:]) == 2
            and z(found[-1]) != 50.0
        ),
        "two poses at z = 50 m, then a good one",
        topic=POSE,
    )[start:]
    bad = [i for i, p in enumerate(found) if z(p) == 50.0]
    assert bad[1] == bad[0] + 1  # two in a row

    start = len(listener.messages(COMMAND))
    ros.inject("/a/car_ctrl", "out_of_range:1")
    found = listener.wait(
        lambda found: 9 in data(found[start:]) and data(found[start:])[-1] == 3,
        "state 9, then a good command",
        topic=COMMAND,
    )
    assert data(found[start:]).count(9) == 1
    wait_until(lambda: '"data": 9' in commands_log.read_text(), "the state machine to get 9")


def test_silence_on_demand(ros: Ros, listener: Listener) -> None:
    listener.wait_count(1, POSE)
    ros.inject("/a/car", "silent")
    try:
        time.sleep(0.3)  # what was in flight arrives
        before = len(listener.messages(POSE))
        time.sleep(1.0)
        assert len(listener.messages(POSE)) == before
    finally:
        ros.delete_param("/a/car/fault")
    listener.wait_count(before + 5, POSE)


def test_a_second_publisher(ros: Ros, listener: Listener) -> None:
    intruder = ros.node("car.py", name="intruder", namespace="/a")
    try:
        assert ros.wait_publisher(POSE, "/a/intruder", watch=[intruder]) == {
            "/a/car",
            "/a/intruder",
        }
        listener.wait(
            lambda found: any(p["callerid"] == "/a/intruder" for p in found),
            "a pose from /a/intruder",
            topic=POSE,
        )
    finally:
        ros.stop(intruder)
    seen: list[set[str]] = []

    def only_the_car() -> bool:
        seen[:] = [ros.publishers(POSE)]
        return seen[0] == {"/a/car"}

    try:
        wait_until(only_the_car, "the intruder to unregister")
    except AssertionError as error:  # say what the master still had, and how it ended
        code = intruder.popen.returncode
        raise AssertionError(f"{error}: publishers {seen}, the intruder's exit {code}") from None


def test_faults_from_the_command_line(ros: Ros) -> None:
    listener = ros.listen("/test/bad", "/test/silent")
    args = ("--fault-at", "0.5", "--fault-count", "3")
    bad = ros.node("car.py", "--topic", "/test/bad", "--fault", "out_of_range", *args, name="bad")
    silent = ros.node("car.py", "--topic", "/test/silent", "--fault", "silent", *args, name="mute")
    try:
        found = listener.wait(
            lambda found: sum(z(p) == 50.0 for p in found) == 3 and z(found[-1]) != 50.0,
            "three bad poses",
            topic="/test/bad",
        )
        first_bad = next(p["t"] for p in found if z(p) == 50.0)
        assert first_bad - found[0]["t"] >= 0.3

        def stopped() -> list[dict[str, Any]]:
            quiet = listener.messages("/test/silent")
            return quiet if quiet and time.time() - quiet[-1]["t"] > 0.3 else []

        quiet = wait_until(stopped, "the silent car to stop publishing")
        assert quiet[-1]["t"] - quiet[0]["t"] <= 0.7  # 0.5 s after its first message
        time.sleep(0.5)
        assert len(listener.messages("/test/silent")) == len(quiet)
    finally:
        ros.stop(bad, silent, listener.proc)


def test_teardown_leaves_no_process(tmp_path: Path) -> None:
    graph = Ros(tmp_path / "ros")
    try:
        graph.start()
        graph.start_system()
        graph.listen(POSE).wait_count(3)
        # roscore, rosmaster, rosout, roslaunch, its three nodes, the listener
        assert len(token_pids(graph.token)) >= 8
        procs = list(graph.processes)
    finally:
        strays = graph.shutdown()
    assert strays == []
    assert token_pids(graph.token) == []
    assert all(p.popen.returncode is not None for p in procs)
    with pytest.raises(ConnectionRefusedError), socket.create_connection(("127.0.0.1", graph.port)):
        pass
