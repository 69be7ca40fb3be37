"""The landing simulation: deterministic bags in three formats, a controller that lands, faults
that change what they should and nothing else, and records that give the graph of Figure 3.6."""

from __future__ import annotations

import json
import math
import time
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner
from rosbags.typesys import Stores, get_typestore

from imrosc.cli import main
from imrosc.graph.file import load_graph_file
from imrosc.records import (
    ARCH_TOPIC,
    PARAMS_TOPIC,
    RECORD_TYPE,
    SRVS_TOPIC,
    decode_arch,
    decode_call,
    decode_params,
)
from imrosc.sim import (
    FAMILIES,
    FORMATS,
    GRAPH,
    SCENARIO_KINDS,
    TOPICS,
    BagFormat,
    Run,
    Scenario,
    ScenarioKind,
    simulate,
    write_run,
    write_runs,
)
from imrosc.sim.recording import RECORDER, START_NS
from imrosc.sim.scenarios import EXTRA_PUBLISHER, MISSING_SUBSCRIBER, SLOW_RATE, SPOOF_JUMP
from imrosc.sim.world import DT, LANDING_RADIUS, LANDING_TIME, PLATFORM_HALF, UAV_REST
from tests.sim import TopicData, callerids, rate, read_bag, same_stream, tilt

ROOT = Path(__file__).resolve().parents[2]
EXAMPLE_GRAPH = ROOT / "examples" / "uav_landing.graph.yaml"
SEED = 3
SHORT = 6.0
"""Long enough for every topic's rate; the controller is still hovering."""
FULL = 30.0
FAULT = Scenario("tilt", start=6.0)
"""Scenario tests run 16 s with the fault from 6 s."""
FAULT_RUN = 16.0


def _suffix(fmt: BagFormat) -> str:
    return ".bag" if fmt == "ros1" else ""


@pytest.fixture(scope="module")
def bags(tmp_path_factory: pytest.TempPathFactory) -> dict[BagFormat, Path]:
    folder = tmp_path_factory.mktemp("sim")
    return {
        fmt: write_run(folder / f"run_{fmt}{_suffix(fmt)}", seed=SEED, fmt=fmt, duration=SHORT)
        for fmt in FORMATS
    }


@pytest.fixture(scope="module")
def contents(bags: dict[BagFormat, Path]) -> dict[BagFormat, dict[str, TopicData]]:
    return {fmt: read_bag(path) for fmt, path in bags.items()}


@pytest.fixture(scope="module")
def full_run() -> Run:
    return simulate(SEED, duration=FULL)


@pytest.fixture(scope="module")
def nominal() -> Run:
    return simulate(SEED, duration=FAULT_RUN)


# --- determinism ---------------------------------------------------------------------------


def test_same_seed_same_bytes(tmp_path: Path) -> None:
    first = write_run(tmp_path / "a.bag", seed=11, fmt="ros1", duration=3.0)
    second = write_run(tmp_path / "b.bag", seed=11, fmt="ros1", duration=3.0)
    other = write_run(tmp_path / "c.bag", seed=12, fmt="ros1", duration=3.0)
    assert first.read_bytes() == second.read_bytes()
    assert first.read_bytes() != other.read_bytes()


@pytest.mark.parametrize("fmt", ["sqlite3", "mcap"])
def test_same_seed_same_ros2_bag(tmp_path: Path, fmt: BagFormat) -> None:
    first = write_run(tmp_path / "one" / "run", seed=11, fmt=fmt, duration=2.0)
    second = write_run(tmp_path / "two" / "run", seed=11, fmt=fmt, duration=2.0)
    files = sorted(p.name for p in first.iterdir())
    assert files == sorted(p.name for p in second.iterdir())
    for name in files:
        assert (first / name).read_bytes() == (second / name).read_bytes(), name


def test_simulate_is_pure() -> None:
    one, two = simulate(5, duration=4.0), simulate(5, duration=4.0)
    assert all(same_stream(a, b) for a, b in zip(one.streams, two.streams, strict=True))


# --- what the bags hold --------------------------------------------------------------------


@pytest.mark.parametrize("fmt", FORMATS)
def test_topics_types_and_rates(
    contents: dict[BagFormat, dict[str, TopicData]], fmt: BagFormat
) -> None:
    topics = contents[fmt]
    expected = {spec.topic for spec in TOPICS} | {ARCH_TOPIC, PARAMS_TOPIC, SRVS_TOPIC}
    assert set(topics) == expected
    for spec in TOPICS:
        data = topics[spec.topic]
        assert data.msgtype == spec.msgtype
        measured = rate(data.times)
        if spec.topic == "/a/cmd_subject_ctrl_state":  # 5 Hz and on every change
            assert spec.rate <= measured <= spec.rate * 1.3, measured
        else:
            assert measured == pytest.approx(spec.rate, rel=0.1), spec.topic
    for record in (ARCH_TOPIC, PARAMS_TOPIC, SRVS_TOPIC):
        assert topics[record].msgtype == RECORD_TYPE
    assert (np.diff(topics["/vicon/car"].times) > 0).all()


def test_ros1_callerids(bags: dict[BagFormat, Path]) -> None:
    found = callerids(bags["ros1"])
    for spec in TOPICS:
        assert found[spec.topic] == {spec.publisher}
        assert spec.topic in GRAPH[spec.publisher]["publishes"]
    for record in (ARCH_TOPIC, PARAMS_TOPIC, SRVS_TOPIC):
        assert found[record] == {RECORDER}
    assert callerids(bags["mcap"])["/a/car_pose"] == {None}


@pytest.mark.parametrize("fmt", FORMATS)
def test_serialization_matches_rosbags(
    contents: dict[BagFormat, dict[str, TopicData]], fmt: BagFormat
) -> None:
    """The vectorised serializer writes exactly what rosbags' own serializer writes."""
    store = get_typestore(Stores.ROS1_NOETIC if fmt == "ros1" else Stores.ROS2_HUMBLE)
    for topic, data in contents[fmt].items():
        for message, raw in list(zip(data.messages, data.raws, strict=True))[::7]:
            if fmt == "ros1":
                again = store.serialize_ros1(message, data.msgtype)
            else:
                again = store.serialize_cdr(message, data.msgtype)
            assert bytes(again) == raw, topic


def test_messages_are_realistic(contents: dict[BagFormat, dict[str, TopicData]]) -> None:
    topics = contents["ros1"]
    vicon = topics["/vicon/car"].messages
    first = vicon[0]
    assert first.header.frame_id == "world" and first.child_frame_id == "car"  # type: ignore[attr-defined]
    stamps = [m.header.stamp.sec * 10**9 + m.header.stamp.nanosec for m in vicon]  # type: ignore[attr-defined]
    assert all(s <= t for s, t in zip(stamps, topics["/vicon/car"].times, strict=True))
    assert [m.header.seq for m in vicon[:3]] == [0, 1, 2]  # type: ignore[attr-defined]
    z = np.array([m.transform.translation.z for m in vicon])  # type: ignore[attr-defined]
    assert 0 < z.std() < 0.005  # the platform's markers, with Vicon noise
    status = topics["/a/subject_status"].messages[0]
    assert 11.0 < status.voltage < 12.8 and len(status.cell_voltage) == 3  # type: ignore[attr-defined]


# --- the controller lands ------------------------------------------------------------------


def test_nominal_run_lands(full_run: Run) -> None:
    world = full_run.world
    assert world.landed and world.touchdown is not None
    changes = np.flatnonzero(np.diff(world.mode.astype(int))) + 1
    assert [int(world.mode[0])] + [int(world.mode[c]) for c in changes] == [0, 1, 2, 3, 4, 5]
    # the UAV stays on the platform with its motors off for at least 5 s
    after = world.time >= world.touchdown
    assert world.time[after][-1] - world.touchdown >= 5.0
    assert not world.motors[after].any()
    offset = np.hypot(*(world.uav[after, 0:2] - world.platform[after, 0:2]).T)
    assert offset.max() < PLATFORM_HALF
    assert np.allclose(world.uav[after, 2], world.platform[after, 2] + UAV_REST)
    # the state machine reports landing, then shutdown
    states = full_run.stream("/a/subject_ctrl_state").values[:, 0]
    assert 4 in states and states[-1] == 5


def test_landing_waits_within_radius(full_run: Run) -> None:
    """Land is commanded once the UAV has been within 15 cm of the platform for 1.5 s."""
    world = full_run.world
    land = int(np.argmax(world.mode == 4))
    land_time = world.cycle_step[land] * DT
    window = (world.time > land_time - LANDING_TIME) & (world.time < land_time)
    offset = np.hypot(*(world.uav[window, 0:2] - world.platform[window, 0:2]).T)
    assert offset.max() < LANDING_RADIUS + 0.01
    before = world.time < land_time - LANDING_TIME - 0.1
    assert world.mode[world.cycle_step * DT < land_time - LANDING_TIME - 0.1].max() <= 3
    assert before.any()


def test_records(full_run: Run) -> None:
    arch = full_run.stream(ARCH_TOPIC)
    assert len(arch) == 1
    snapshot = decode_arch(arch.texts[0])
    assert snapshot.topics["/a/subject_ctrl_state"].subs == {
        "/a/car_ctrl",
        "/a/launch_ctrl",
        "/a/ctrl_input_arb",
    }
    assert snapshot.services == {
        "/a/execute_task": frozenset({"/a/car"}),
        "/a/poll_status": frozenset({"/a/car_ctrl"}),
    }
    params = decode_params(full_run.stream(PARAMS_TOPIC).texts[0]).params
    assert params["/a/car_ctrl/landing_radius"] == 0.15
    assert params["/a/car_ctrl/landing_time"] == 1.5
    assert "/a/car_ctrl/poll_rate" in params
    srvs = full_run.stream(SRVS_TOPIC)
    calls = [decode_call(text) for text in srvs.texts]
    tasks = [c for c in calls if c.service == "/a/execute_task"]
    assert [c.request["task_id"] for c in tasks] == [0, 1, 2, 3]
    assert all(c.client == "/a/car_ctrl" and c.server == "/a/car" and c.ok for c in tasks)
    assert all(c.response == {"status": "ok"} and 0.2 < c.delay < 2.0 for c in tasks)
    for call, received in zip(calls, srvs.time_ns, strict=True):
        assert received / 1e9 >= call.stamp + call.delay - 1e-6
    polls = [c for c in calls if c.service == "/a/poll_status"]
    assert polls and all(c.server == "/a/car_ctrl" for c in polls)
    assert (np.diff(srvs.time_ns) >= 0).all()  # published as the responses come back


def test_state_command_precedes_waypoint(full_run: Run) -> None:
    cmd, way = full_run.stream("/a/cmd_subject_ctrl_state"), full_run.stream("/a/task_waypose")
    assert cmd.cycle is not None
    gap = way.time_ns[cmd.cycle] - cmd.time_ns
    assert (gap > 0).all() and (gap < 2_000_000).all()


def test_platform_stays_level(full_run: Run) -> None:
    assert tilt(full_run.stream("/vicon/car").values).max() < 0.05
    platform = full_run.world.platform
    assert np.abs(platform[:, 0:2]).max() <= 4.0 - PLATFORM_HALF


# --- fault scenarios -----------------------------------------------------------------------

EXPECTED_CHANGES: dict[ScenarioKind, set[tuple[str, str]]] = {
    "slowed": {("/a/car_pose", "/a/car")},
    "spoofed": {("/a/car_pose", "/a/car")},
    "stuck": {("/a/subject_status", "/a/robot_monitor")},
    "tilt": {("/a/car_pose", "/a/car"), ("/vicon/car", "/vicon")},
    "extra_publisher": {("/a/car_pose", EXTRA_PUBLISHER), (ARCH_TOPIC, RECORDER)},
    "missing_subscriber": {(ARCH_TOPIC, RECORDER)},
    "out_of_order": {
        ("/a/cmd_subject_ctrl_state", "/a/car_ctrl"),
        ("/a/task_waypose", "/a/car_ctrl"),
    },
}


def _faulty(kind: ScenarioKind) -> Run:
    return simulate(SEED, duration=FAULT_RUN, scenario=Scenario(kind, start=FAULT.start))


def _seconds(time_ns: np.ndarray) -> np.ndarray:
    return (time_ns - START_NS) / 1e9


@pytest.mark.parametrize("kind", SCENARIO_KINDS)
def test_scenario_changes_only_its_streams(nominal: Run, kind: ScenarioKind) -> None:
    faulty = _faulty(kind)
    before = {(s.topic, s.callerid): s for s in nominal.streams}
    after = {(s.topic, s.callerid): s for s in faulty.streams}
    changed = {
        key
        for key in before.keys() | after.keys()
        if key not in before or key not in after or not same_stream(before[key], after[key])
    }
    assert changed == EXPECTED_CHANGES[kind]
    for key in changed & before.keys():  # nothing changes before the fault starts
        early_before = before[key].select(_seconds(before[key].time_ns) < FAULT.start)
        early_after = after[key].select(_seconds(after[key].time_ns) < FAULT.start)
        assert same_stream(early_before, early_after), key
    assert faulty.world is not nominal.world
    assert faulty.world.touchdown == nominal.world.touchdown


def test_slowed_drops_the_platform_rate(nominal: Run) -> None:
    pose = _faulty("slowed").stream("/a/car_pose")
    seconds = _seconds(pose.time_ns)
    slow = (seconds >= FAULT.start) & (seconds < FAULT.start + 5.0)
    assert np.diff(seconds[slow]) == pytest.approx(1 / SLOW_RATE, abs=0.01)
    # in every 1 s window of the slow period at most one message: the frequency invariant breaks
    counts = np.histogram(seconds, bins=np.arange(FAULT.start, FAULT.start + 5.0, 1.0))[0]
    assert counts.max() <= 1
    normal = (seconds >= FAULT.start + 5.0) & (seconds < FAULT.start + 10.0)
    assert rate(pose.time_ns[normal]) == pytest.approx(20.0, rel=0.1)
    # the messages left are the nominal ones
    kept = np.isin(nominal.stream("/a/car_pose").time_ns, pose.time_ns)
    assert np.array_equal(nominal.stream("/a/car_pose").values[kept], pose.values)


def test_spoofed_jumps_the_platform(nominal: Run) -> None:
    true, fake = nominal.stream("/a/car_pose"), _faulty("spoofed").stream("/a/car_pose")
    shift = fake.values - true.values
    on = _seconds(fake.time_ns) >= FAULT.start
    assert np.allclose(np.hypot(shift[on, 0], shift[on, 1]), SPOOF_JUMP)
    assert np.allclose(shift[:, 2:], 0.0) and np.allclose(shift[~on], 0.0)

    def speed(values: np.ndarray) -> float:
        step = np.hypot(*np.diff(values[:, 0:2], axis=0).T) / np.diff(_seconds(fake.time_ns))
        return float(step.max())

    assert speed(true.values) < 0.6  # the platform drives at 0.3 m/s
    assert speed(fake.values) > 20.0  # the change-rate invariant breaks


def test_stuck_status_has_no_variance(nominal: Run) -> None:
    status = _faulty("stuck").stream("/a/subject_status")
    on = _seconds(status.time_ns) >= FAULT.start
    assert np.ptp(status.values[on], axis=0).max() == 0.0
    assert (nominal.stream("/a/subject_status").values[on].std(axis=0)[[0, 1, 2]] > 0).all()


def test_tilt_tips_the_platform(nominal: Run) -> None:
    faulty = _faulty("tilt")
    for topic in ("/vicon/car", "/a/car_pose"):
        pose = faulty.stream(topic)
        tipped = _seconds(pose.time_ns) >= FAULT.start + 0.5
        assert tilt(pose.values[tipped]).min() > 0.3
        assert tilt(pose.values[~tipped & (_seconds(pose.time_ns) < FAULT.start)]).max() < 0.05
        assert np.array_equal(pose.values[:, 0:3], nominal.stream(topic).values[:, 0:3])
        assert np.allclose(np.linalg.norm(pose.values[:, 3:7], axis=1), 1.0)


def test_extra_publisher(tmp_path: Path) -> None:
    scenario = Scenario("extra_publisher", start=2.0)
    bag = write_run(tmp_path / "x.bag", seed=SEED, fmt="ros1", duration=5.0, scenario=scenario)
    assert callerids(bag)["/a/car_pose"] == {"/a/car", EXTRA_PUBLISHER}
    arch = read_bag(bag)[ARCH_TOPIC]
    snapshots = [decode_arch(m.data) for m in arch.messages]  # type: ignore[attr-defined]
    assert [(t - START_NS) / 1e9 for t in arch.times] == pytest.approx([0.0005, 2.0005])
    assert snapshots[0].topics["/a/car_pose"].pubs == {"/a/car"}
    assert snapshots[1].topics["/a/car_pose"].pubs == {"/a/car", EXTRA_PUBLISHER}
    extra = _faulty("extra_publisher").stream("/a/car_pose", EXTRA_PUBLISHER)
    assert rate(extra.time_ns) == pytest.approx(20.0, rel=0.1)
    assert _seconds(extra.time_ns).min() >= FAULT.start


def test_missing_subscriber(tmp_path: Path) -> None:
    scenario = Scenario("missing_subscriber", start=1.2, length=2.0)
    bag = write_run(tmp_path / "m", seed=SEED, fmt="mcap", duration=5.0, scenario=scenario)
    arch = read_bag(bag)[ARCH_TOPIC]
    snapshots = [decode_arch(m.data) for m in arch.messages]  # type: ignore[attr-defined]
    subs = [s.topics["/a/subject_ctrl_state"].subs for s in snapshots]
    assert [MISSING_SUBSCRIBER in s for s in subs] == [True, False, True]
    assert [(t - START_NS) / 1e9 for t in arch.times] == pytest.approx([0.0005, 1.5005, 3.5005])
    assert all(MISSING_SUBSCRIBER not in ends.subs for ends in snapshots[1].topics.values())


def test_out_of_order_swaps_command_and_waypoint(nominal: Run) -> None:
    faulty = _faulty("out_of_order")
    cmd, way = faulty.stream("/a/cmd_subject_ctrl_state"), faulty.stream("/a/task_waypose")
    assert cmd.cycle is not None
    gap = way.time_ns[cmd.cycle] - cmd.time_ns
    on = _seconds(cmd.time_ns) >= FAULT.start + 0.01
    off = _seconds(cmd.time_ns) < FAULT.start
    assert (gap[on] < 0).all() and (gap[off] > 0).all()
    # the same messages, only the times of each pair swapped
    nominal_cmd = nominal.stream("/a/cmd_subject_ctrl_state")
    nominal_way = nominal.stream("/a/task_waypose")
    assert np.array_equal(cmd.values, nominal_cmd.values)
    assert np.array_equal(way.values, nominal_way.values)
    everything = np.sort(np.concatenate([cmd.time_ns, way.time_ns]))
    assert np.array_equal(
        everything, np.sort(np.concatenate([nominal_cmd.time_ns, nominal_way.time_ns]))
    )


def test_scenario_is_validated() -> None:
    with pytest.raises(ValueError, match="unknown scenario"):
        Scenario("wind")  # type: ignore[arg-type]
    with pytest.raises(ValueError, match="start"):
        Scenario("tilt", start=-1.0)
    with pytest.raises(ValueError, match="length"):
        Scenario("tilt", length=0.0)
    assert Scenario("tilt", start=2.0, length=3.0).end == 5.0
    assert math.isinf(Scenario("tilt").end)
    assert set(FAMILIES) == set(SCENARIO_KINDS)


def test_fault_after_the_end_changes_nothing() -> None:
    late = simulate(SEED, duration=2.0, scenario=Scenario("missing_subscriber", start=10.0))
    plain = simulate(SEED, duration=2.0)
    assert all(same_stream(a, b) for a, b in zip(late.streams, plain.streams, strict=True))


# --- writers -------------------------------------------------------------------------------


def test_write_runs(tmp_path: Path) -> None:
    paths = write_runs(tmp_path / "nominal", runs=2, seed=20, fmt="ros1", duration=2.0)
    assert [p.name for p in paths] == ["nominal_000.bag", "nominal_001.bag"]
    again = write_run(tmp_path / "again.bag", seed=21, fmt="ros1", duration=2.0)
    assert paths[1].read_bytes() == again.read_bytes()
    faulty = write_runs(
        tmp_path / "fail", runs=1, seed=20, fmt="sqlite3", duration=2.0, scenario=FAULT
    )
    assert [p.name for p in faulty] == ["tilt_000"]
    assert (faulty[0] / "metadata.yaml").is_file()


def test_refuses_to_overwrite_and_bad_names(tmp_path: Path) -> None:
    bag = write_run(tmp_path / "a.bag", seed=1, fmt="ros1", duration=1.0)
    with pytest.raises(FileExistsError, match="already exists"):
        write_run(bag, seed=1, fmt="ros1", duration=1.0)
    with pytest.raises(ValueError, match=r"\.bag"):
        write_run(tmp_path / "b.db", seed=1, fmt="ros1", duration=1.0)
    with pytest.raises(ValueError, match="format"):
        write_run(tmp_path / "c", seed=1, fmt="ros3", duration=1.0)  # type: ignore[arg-type]
    with pytest.raises(ValueError, match="duration"):
        write_run(tmp_path / "d.bag", seed=1, fmt="ros1", duration=0.0)


def test_thirty_seconds_write_fast(tmp_path: Path) -> None:
    write_run(tmp_path / "warm.bag", seed=1, fmt="ros1", duration=1.0)
    started = time.perf_counter()
    write_run(tmp_path / "run.bag", seed=1, fmt="ros1", duration=FULL)
    assert time.perf_counter() - started < 2.0


# --- the graph and the example configuration -----------------------------------------------


@pytest.mark.parametrize("fmt", ["ros1", "mcap"])
def test_graph_command_shows_figure_3_6(bags: dict[BagFormat, Path], fmt: BagFormat) -> None:
    result = CliRunner().invoke(main, ["graph", str(bags[fmt])])
    assert result.exit_code == 0, result.output
    expected, problems = load_graph_file(EXAMPLE_GRAPH)
    assert expected is not None and not problems
    body = expected.render_text().split("\n", 1)[1]
    header, rest = result.output.split("\n", 1)
    assert header.startswith("# sources: records")
    assert rest == body


def test_graph_yaml_matches_the_example(bags: dict[BagFormat, Path]) -> None:
    result = CliRunner().invoke(main, ["graph", "--format", "yaml", str(bags["sqlite3"])])
    assert result.exit_code == 0, result.output
    expected, _ = load_graph_file(EXAMPLE_GRAPH)
    assert expected is not None
    assert result.output.split("\n", 1)[1] == expected.render_yaml().split("\n", 1)[1]


def test_example_configuration_checks_and_builds() -> None:
    config = str(ROOT / "examples" / "landing_sim.xml")
    runner = CliRunner()
    checked = runner.invoke(main, ["check", "--format", "json", config])
    assert checked.exit_code == 0, checked.output
    assert json.loads(checked.output)["diagnostics"] == []
    built = runner.invoke(main, ["build", config, "--graph", str(EXAMPLE_GRAPH), "--emit-ir"])
    assert built.exit_code == 0, built.output
    project = json.loads(built.output)
    ids = {point["id"] for point in project["points"]}
    assert {"a", "b", "c", "d", "e", "p", "s", "v"} <= ids
