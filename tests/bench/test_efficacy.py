"""bench/efficacy.py's pieces: the fault injectors on a small generated ROS 1 bag, the bag
copies, the session folds of ALFA's flights, the classifying configurations and the scoring (one
monitor or two side by side). The bench itself is not run."""

from __future__ import annotations

import argparse
import dataclasses
import json
import math
import shutil
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from lxml import etree
from rosbags.rosbag1 import Reader, Writer
from rosbags.typesys import Stores, get_types_from_msg, get_typestore
from rosbags.typesys.store import Typestore

from bench import efficacy as e
from imrosc.classify import load_project
from imrosc.diagnostics import Diagnostic, make
from imrosc.ir import Project
from imrosc.runtime.alarms import Alarm
from imrosc.runtime.violation import Violation

SECOND = 1_000_000_000
START = 1_553_088_600 * SECOND
ONSET = START + 2 * SECOND
LOG_TYPE = "crazyflie_driver/msg/GenericLogData"
IMU_TYPE = "sensor_msgs/msg/Imu"


def _store() -> Typestore:
    store = get_typestore(Stores.ROS1_NOETIC)
    store.register(get_types_from_msg("std_msgs/Header header\nfloat64[] values\n", LOG_TYPE))
    return store


def _header(store: Typestore, seq: int, stamp: int) -> Any:
    time = store.types["builtin_interfaces/msg/Time"](sec=stamp // SECOND, nanosec=stamp % SECOND)
    return store.types["std_msgs/msg/Header"](seq=seq, stamp=time, frame_id="cf1")


def _imu(store: Typestore, seq: int, stamp: int) -> Any:
    t = store.types
    vector, quaternion = t["geometry_msgs/msg/Vector3"], t["geometry_msgs/msg/Quaternion"]
    return t[IMU_TYPE](
        header=_header(store, seq, stamp),
        orientation=quaternion(x=0.0, y=0.0, z=0.0, w=1.0),
        orientation_covariance=np.zeros(9),
        angular_velocity=vector(x=0.01 * seq, y=0.0, z=0.0),
        angular_velocity_covariance=np.zeros(9),
        linear_acceleration=vector(x=0.1 * seq, y=-0.2, z=9.81),
        linear_acceleration_covariance=np.zeros(9),
    )


def _log(store: Typestore, seq: int, stamp: int, offset: float) -> Any:
    values = np.array([offset + 0.01 * seq, offset - 0.02 * seq, 0.5], dtype=np.float64)
    return store.types[LOG_TYPE](header=_header(store, seq, stamp), values=values)


@pytest.fixture(scope="module")
def flight(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """3 s of a small Crazyflie: IMU at 30 Hz, three logs at 10 Hz, one publisher."""
    path = tmp_path_factory.mktemp("efficacy") / "flight.bag"
    store = _store()
    with Writer(path) as writer:
        imu = writer.add_connection(e.IMU, IMU_TYPE, typestore=store, callerid="/crazyflie_server")
        logs = {
            topic: writer.add_connection(
                topic, LOG_TYPE, typestore=store, callerid="/crazyflie_server"
            )
            for topic in (e.POS, e.RPY, e.RANGES)
        }
        writer.add_connection("/cf1/silent", "std_msgs/msg/Float64", typestore=store)
        for seq in range(90):
            stamp = START + seq * SECOND // 30
            writer.write(imu, stamp, store.serialize_ros1(_imu(store, seq, stamp), IMU_TYPE))
            if seq % 3 == 0:
                for offset, connection in enumerate(logs.values()):
                    value = _log(store, seq // 3, stamp + 1000, float(offset))
                    writer.write(connection, stamp + 1000, store.serialize_ros1(value, LOG_TYPE))
    return path


def _on(messages: list[e.Message], topic: str, after: bool) -> list[e.Message]:
    return [m for m in messages if m.topic.topic == topic and (m.time >= ONSET) == after]


def test_a_bag_is_copied_with_every_connection_and_message(flight: Path, tmp_path: Path) -> None:
    bag = e.read_bag(flight)
    copy = e.read_bag(e.write_bag(tmp_path / "copy.bag", bag.messages, bag.topics))
    assert copy.topics == bag.topics  # definitions, md5sums and callerids too
    assert copy.messages == bag.messages
    assert (copy.start, copy.end) == (bag.start, bag.end)
    assert len(bag.topics) == 5 and bag.topics[-1].topic == "/cf1/silent"


def test_a_crop_keeps_the_messages_before_the_onset_and_every_connection(
    flight: Path, tmp_path: Path
) -> None:
    bag = e.read_bag(flight)
    cropped = e.read_bag(e.crop(flight, ONSET, tmp_path / "pre.bag"))
    assert cropped.topics == bag.topics
    assert cropped.messages == [m for m in bag.messages if m.time < ONSET]
    assert cropped.messages and all(m.time < ONSET for m in cropped.messages)


@pytest.mark.parametrize("name", list(e.FAULTS))
def test_a_fault_leaves_the_messages_before_the_onset_alone(flight: Path, name: str) -> None:
    messages = e.read_bag(flight).messages
    faulty = e.FAULTS[name](messages, ONSET)
    assert [m for m in faulty if m.time < ONSET] == [m for m in messages if m.time < ONSET]
    assert faulty != messages
    assert [m.time for m in faulty] == sorted(m.time for m in faulty)


def test_the_six_faults() -> None:
    assert list(e.FAULTS) == [
        "slowed topic",
        "dead topic",
        "frozen sensor",
        "position jump",
        "scaled IMU",
        "second publisher",
    ]


def test_a_slowed_topic_keeps_a_third_of_its_messages(flight: Path) -> None:
    messages = e.read_bag(flight).messages
    faulty = e.slowed_topic(messages, ONSET)
    before, after = _on(messages, e.IMU, True), _on(faulty, e.IMU, True)
    assert len(after) == math.ceil(len(before) / 3)
    assert after == before[::3]
    assert _on(faulty, e.POS, True) == _on(messages, e.POS, True)


def test_a_dead_topic_stops(flight: Path) -> None:
    messages = e.read_bag(flight).messages
    faulty = e.dead_topic(messages, ONSET)
    assert not _on(faulty, e.RANGES, True) and _on(messages, e.RANGES, True)
    assert _on(faulty, e.RANGES, False) == _on(messages, e.RANGES, False)
    assert len(faulty) == len(messages) - len(_on(messages, e.RANGES, True))


def test_a_frozen_sensor_repeats_its_last_values_under_new_headers(flight: Path) -> None:
    messages = e.read_bag(flight).messages
    faulty = e.frozen_sensor(messages, ONSET)
    last = e.decode(_on(messages, e.RPY, False)[-1])
    frozen = [e.decode(m) for m in _on(faulty, e.RPY, True)]
    original = [e.decode(m) for m in _on(messages, e.RPY, True)]
    assert len(frozen) == len(original) > 1
    for value, was in zip(frozen, original, strict=True):
        assert value.values.tolist() == last.values.tolist()
        assert value.header.seq == was.header.seq
    times = [m.time for m in _on(messages, e.RPY, True)]
    assert [m.time for m in _on(faulty, e.RPY, True)] == times


def test_a_position_jump_moves_x_only(flight: Path) -> None:
    messages = e.read_bag(flight).messages
    faulty = e.position_jump(messages, ONSET)
    for value, was in zip(
        (e.decode(m) for m in _on(faulty, e.POS, True)),
        (e.decode(m) for m in _on(messages, e.POS, True)),
        strict=True,
    ):
        assert value.values[0] == pytest.approx(was.values[0] + e.JUMP)
        assert value.values[1:].tolist() == was.values[1:].tolist()
    assert _on(faulty, e.RPY, True) == _on(messages, e.RPY, True)


def test_a_scaled_imu_scales_the_linear_acceleration(flight: Path) -> None:
    messages = e.read_bag(flight).messages
    faulty = e.scaled_imu(messages, ONSET)
    pairs = zip(
        (e.decode(m) for m in _on(faulty, e.IMU, True)),
        (e.decode(m) for m in _on(messages, e.IMU, True)),
        strict=True,
    )
    for value, was in pairs:
        for axis in "xyz":
            scaled = getattr(value.linear_acceleration, axis)
            assert scaled == pytest.approx(getattr(was.linear_acceleration, axis) * 1.5)
        assert value.angular_velocity == was.angular_velocity


def test_a_second_publisher_writes_a_second_connection(flight: Path, tmp_path: Path) -> None:
    bag = e.read_bag(flight)
    faulty = e.second_publisher(bag.messages, ONSET)
    path = e.write_bag(tmp_path / "intruder.bag", faulty, bag.topics)
    with Reader(path) as reader:
        on_pos = [c for c in reader.connections if c.topic == e.POS]
        callerids = [getattr(c.ext, "callerid", None) for c in on_pos]
        assert sorted(c or "" for c in callerids) == ["/crazyflie_server", e.INTRUDER]
        intruder = on_pos[callerids.index(e.INTRUDER)]
        assert intruder.msgdef == on_pos[0].msgdef and intruder.digest == on_pos[0].digest
        times = [t for _, t, _ in reader.messages(connections=[intruder])]
    assert len(times) == len(_on(bag.messages, e.POS, True)) and min(times) >= ONSET


ALFA_FLIGHTS = [
    "ailerons/carbonZ_2018-10-05-14-34-20_2_right_aileron_failure_with_emr_traj.bag",
    "elevator/carbonZ_2018-09-11-14-41-51_elevator_failure.bag",
    "engine/carbonZ_2018-07-18-15-53-31_1_engine_failure.bag",
    "engine/carbonZ_2018-07-18-15-53-31_2_engine_failure.bag",
    "engine/carbonZ_2018-07-18-16-22-01_engine_failure_with_emr_traj.bag",
    "engine/carbonZ_2018-07-18-16-37-39_2_engine_failure_with_emr_traj.bag",
    "engine/carbonZ_2018-07-30-16-39-00_1_engine_failure.bag",
    "engine/carbonZ_2018-07-30-16-39-00_2_engine_failure.bag",
    "engine/carbonZ_2018-07-30-17-10-45_engine_failure_with_emr_traj.bag",
    "engine/carbonZ_2018-07-30-17-36-35_engine_failure_with_emr_traj.bag",
    "engine/carbonZ_2018-07-30-17-46-31_engine_failure_with_emr_traj.bag",
    "engine/carbonZ_2018-09-11-11-56-30_engine_failure.bag",
    "engine/carbonZ_2018-10-18-11-04-35_engine_failure_with_emr_traj.bag",
    "engine/carbonZ_2018-10-18-11-06-06_engine_failure_with_emr_traj.bag",
    "no_failure/carbonZ_2018-07-18-16-37-39_1_no_failure.bag",
    "no_failure/carbonZ_2018-07-30-16-39-00_3_no_failure.bag",
    "no_failure/carbonZ_2018-09-11-14-16-55_no_failure.bag",
    "no_failure/carbonZ_2018-10-05-14-34-20_1_no_failure.bag",
    "rudder/carbonZ_2018-09-11-15-06-34_1_rudder_right_failure.bag",
    "rudder/carbonZ_2018-09-11-15-06-34_2_rudder_right_failure.bag",
    "rudder/carbonZ_2018-09-11-15-06-34_3_rudder_left_failure.bag",
]


def test_a_session_is_the_date_time_stamp() -> None:
    assert e.session_of(ALFA_FLIGHTS[6]) == "2018-07-30-16-39-00"
    assert e.session_of(ALFA_FLIGHTS[15]) == "2018-07-30-16-39-00"
    assert len({e.session_of(n) for n in ALFA_FLIGHTS}) == 14


@pytest.mark.parametrize("folds", [2, 3, 5, 10, 14, 40])
def test_no_session_is_split_across_folds(folds: int) -> None:
    split = e.session_folds(reversed(ALFA_FLIGHTS), folds)
    assert len(split) == min(folds, 14)
    assert sorted(n for fold in split for n in fold) == sorted(ALFA_FLIGHTS)
    home: dict[str, int] = {}
    for index, fold in enumerate(split):
        for name in fold:
            assert home.setdefault(e.session_of(name), index) == index
    sizes = [len(fold) for fold in split]
    assert max(sizes) - min(sizes) <= 3  # the largest session holds three flights
    assert e.session_folds(ALFA_FLIGHTS, folds) == split  # deterministic, order-free


def test_five_folds_of_alfa() -> None:
    split = e.session_folds(ALFA_FLIGHTS, 5)
    assert sorted(len(fold) for fold in split) == [4, 4, 4, 4, 5]


def test_one_fold_per_session() -> None:
    """``--folds session``: leave one recording session out, whatever their number."""
    split = e.session_folds(ALFA_FLIGHTS, e.SESSIONS)
    assert len(split) == 14
    assert all(len({e.session_of(n) for n in fold}) == 1 for fold in split)
    assert sorted(len(fold) for fold in split) == [1] * 9 + [2] * 3 + [3] * 2
    assert len(e.session_folds(ALFA_FLIGHTS[2:4], e.SESSIONS)) == 1  # one session


def test_the_folds_option() -> None:
    assert e.folds_of("session") == e.SESSIONS and e.folds_of("3") == 3
    for wrong in ("1", "0", "-2", "sessions", "2.5"):
        with pytest.raises(argparse.ArgumentTypeError, match="at least 2"):
            e.folds_of(wrong)


def test_test_flights_are_read_from_their_onsets(tmp_path: Path) -> None:
    (tmp_path / "engine").mkdir()
    (tmp_path / "engine" / "a.bag").write_bytes(b"")
    info = {"class": "engine", "onset_ns": 5, "onset_s": 1.0, "start_ns": 0, "end_ns": 9}
    (tmp_path / "onsets.json").write_text(json.dumps({"engine/a.bag": info}))
    flights = e.read_flights(tmp_path)
    assert (flights.root, flights.onsets) == (tmp_path, {"engine/a.bag": info})


@pytest.mark.parametrize(
    ("listing", "problem"),
    [
        (None, "cannot read the flights' onsets"),
        ("{", "cannot read the flights' onsets"),
        ('["engine/a.bag"]', "not a mapping of bag to its class and onset_ns"),
        ('{"engine/a.bag": {"class": "engine"}}', "not a mapping of bag to its class"),
        ('{"engine/b.bag": {"class": "engine", "onset_ns": 5}}', "1 listed bags are missing"),
    ],
)
def test_unreadable_test_flights_exit_naming_the_listing(
    tmp_path: Path, listing: str | None, problem: str
) -> None:
    (tmp_path / "engine").mkdir()
    (tmp_path / "engine" / "a.bag").write_bytes(b"")
    if listing is not None:
        (tmp_path / "onsets.json").write_text(listing)
    with pytest.raises(SystemExit) as raised:
        e.read_flights(tmp_path)
    assert str(raised.value).startswith(f"{tmp_path / 'onsets.json'}: ")
    assert problem in str(raised.value)


def _run(onset: float | None, *alarms: float) -> e.Outcome:
    return e.Outcome("run", "fault" if onset is not None else "nominal", onset, tuple(alarms))


def test_an_outcome() -> None:
    caught = _run(10.0, 10.5, 12.0)
    assert (caught.detected, caught.delay, caught.before, caught.false_alarm) == (
        True,
        0.5,
        0,
        False,
    )
    at_onset = _run(10.0, 10.0)
    assert at_onset.detected and at_onset.delay == 0.0
    early = _run(10.0, 3.0, 11.0)  # alarmed before the onset: a false alarm, not a detection
    assert (early.detected, early.delay, early.before, early.false_alarm) == (False, 1.0, 1, True)
    missed = _run(10.0)
    assert (missed.detected, missed.delay, missed.first) == (False, None, None)
    nominal = _run(None, 4.0, 5.0)
    assert (nominal.detected, nominal.before, nominal.false_alarm, nominal.delay) == (
        False,
        2,
        True,
        None,
    )
    assert not _run(None).false_alarm


def test_the_scores() -> None:
    runs = [
        _run(10.0, 11.0),  # detected, 1 s
        _run(10.0, 13.0, 14.0),  # detected, 3 s
        _run(10.0, 2.0, 10.5),  # false alarm before the onset
        _run(10.0),  # missed
        _run(None),  # quiet nominal run
        _run(None, 7.0),  # false alarm on a nominal run
    ]
    s = e.score(runs)
    assert (s.runs, s.faulty, s.detected, s.false_alarms, s.alarmed) == (6, 4, 2, 2, 4)
    assert s.recall == 0.5 and s.precision == 0.5
    assert s.false_rate == pytest.approx(2 / 6)
    assert (s.mean_delay, s.max_delay) == (2.0, 3.0)
    empty = e.score([_run(10.0), _run(None)])
    assert empty.recall == 0.0
    assert math.isnan(empty.precision) and math.isnan(empty.mean_delay)


def test_figures_are_printed_without_a_negative_zero() -> None:
    assert e.fmt(-0.001) == "0.00" and e.fmt(None) == "-" and e.fmt(math.nan) == "-"
    assert e.fmt(2.345, 1) == "2.3"


# --- classification: the configuration and two monitors side by side ------------------------


def _classifying(config: Path, flight: Path, **onset: Any) -> Project:
    """``config`` given a <check> of ``flight`` (success) and two copies of it (fail),
    loaded, checked and lowered without a diagnostic."""
    fails = [flight.with_name("fail_1.bag"), flight.with_name("fail_2.bag")]
    for path in fails:
        if not path.exists():
            shutil.copyfile(flight, path)
    e.set_check(config, "alfa.inv", e.Classification([flight], fails, **onset))
    project, problems = load_project(config)
    assert project is not None and not problems, [p.as_text() for p in problems]
    check = project.check
    assert check is not None and check.mode == "classify" and check.inv == "alfa.inv"
    assert check.success == (str(flight.resolve()),)
    assert check.fail == tuple(str(p.resolve()) for p in fails)
    return project


def test_a_classifying_config_with_an_onset_topic(flight: Path, tmp_path: Path) -> None:
    config = e.write_config(tmp_path / "alfa.xml", "alfa", e.ALFA_SCOPE, [flight])
    project = _classifying(config, flight, onset_topic=e.ALFA_LABEL)
    assert project.detect is not None and project.detect.bags == (str(flight.resolve()),)
    assert project.check is not None
    assert [(o.topic, o.seconds) for o in project.check.onsets] == [(e.ALFA_LABEL, None)] * 2
    assert config.read_text().endswith("</check>\n</imROS>\n")


def test_a_classifying_config_replaces_the_check_with_onset_seconds(
    flight: Path, tmp_path: Path
) -> None:
    from imrosc.demo import CONFIG, example_configs

    source = next(p for p in example_configs() if p.name == CONFIG)
    config = shutil.copyfile(source, tmp_path / CONFIG)
    before = etree.parse(str(config)).getroot()
    index = [c.tag for c in before].index("check")
    project = _classifying(config, flight, onset=e.SIM_START)
    assert project.check is not None
    assert [(o.topic, o.seconds) for o in project.check.onsets] == [(None, e.SIM_START)] * 2
    tree = etree.parse(str(config))
    after = tree.getroot()
    assert [c.tag for c in after] == [c.tag for c in before]  # in the old <check>'s place
    assert after[index].get("inv") == "alfa.inv" and after.find("monitor") is not None
    assert tree.getroot().getprevious() is not None  # the leading comment is kept


def test_both_onsets_conflict(flight: Path, tmp_path: Path) -> None:
    config = e.write_config(tmp_path / "alfa.xml", "alfa", e.ALFA_SCOPE, [flight])
    both = e.Classification([flight], [flight], onset_topic=e.ALFA_LABEL, onset=1.0)
    project, problems = load_project(e.set_check(config, "alfa.inv", both))
    assert project is None and "onset-conflict" in {p.code for p in problems}


def test_the_verdicts() -> None:
    runs = [_run(10.0, 11.0), _run(10.0, 2.0, 11.0), _run(10.0), _run(None), _run(None, 1.0)]
    assert [e.verdict(o) for o in runs] == [
        "detected",
        "false alarm",
        "missed",
        "quiet",
        "false alarm",
    ]
    broken = dataclasses.replace(_run(10.0), error="unreadable")
    assert e.verdict(broken) == "error: unreadable"


def _named(name: str, group: str, onset: float | None, *alarms: float) -> e.Outcome:
    return e.Outcome(name, group, onset, tuple(alarms))


def test_two_monitors_side_by_side(capsys: pytest.CaptureFixture[str]) -> None:
    inferred = [
        _named("a", "rudder", 10.0),
        _named("b", "engine", 10.0, 12.0),
        _named("c", "nominal", None),
    ]
    classified = [
        _named("a", "rudder", 10.0, 10.5),
        _named("b", "engine", 10.0, 3.0),
        _named("c", "nominal", None, 4.0),
    ]
    table = e.side_by_side({"inferred": inferred, "classified": classified})
    assert list(table) == ["engine", "nominal", "rudder", "overall"]
    assert all(list(scores) == ["inferred", "classified"] for scores in table.values())
    one, two = table["overall"]["inferred"], table["overall"]["classified"]
    assert (one.runs, one.faulty, one.detected, one.false_alarms, one.alarmed) == (3, 2, 1, 0, 1)
    assert (two.runs, two.faulty, two.detected, two.false_alarms, two.alarmed) == (3, 2, 1, 2, 3)
    assert (one.mean_delay, two.mean_delay) == (2.0, 0.5)
    assert table["rudder"]["classified"].recall == 1.0 and table["rudder"]["inferred"].recall == 0
    e.print_side_by_side({"inferred": inferred, "classified": classified})
    e.print_scores(table)
    lines = capsys.readouterr().out.splitlines()
    assert "inferred" in lines[0] and "classified" in lines[0]
    row = ["a", "rudder", "10.00", "|", "0", "-", "-", "missed", "|", "1", "10.50", "0.50"]
    assert lines[2].split() == [*row, "detected"]
    assert lines[4].split()[-4:] == ["4.00", "-", "false", "alarm"]
    assert all(line == line.rstrip() for line in lines)
    assert lines[-2].split()[:2] == ["overall", "inferred"]
    assert lines[-1].split()[:5] == ["classified", "3", "2", "1", "0.50"]
    with pytest.raises(ValueError, match="same runs"):
        e.side_by_side({"inferred": inferred, "classified": classified[:2]})


def test_where_the_delays_come_from(capsys: pytest.CaptureFixture[str]) -> None:
    """Per fault run and monitor: the first violation at or after the onset, the first
    alarm, and what the alarm rule added between them; their means over detected runs."""
    slow = [
        dataclasses.replace(_named("a", "engine", 10.0, 13.0), violated=10.5),
        dataclasses.replace(_named("b", "engine", 10.0), violated=11.0),  # never alarmed
        _named("c", "nominal", None),
    ]
    at_once = [
        dataclasses.replace(_named("a", "engine", 10.0, 12.0), violated=12.0),
        dataclasses.replace(_named("b", "engine", 10.0, 14.0), violated=14.0),
        _named("c", "nominal", None),
    ]
    assert slow[0].violation_delay == 0.5 and slow[2].violation_delay is None
    e.print_sources({"persisted": slow, "detector": at_once})
    lines = capsys.readouterr().out.splitlines()
    assert "persisted" in lines[0] and "detector" in lines[0]
    assert lines[2].split() == ["a", "|", "0.50", "3.00", "2.50", "|", "2.00", "2.00", "0.00"]
    assert lines[3].split() == ["b", "|", "1.00", "-", "-", "|", "4.00", "4.00", "0.00"]
    assert len(lines) == 5  # the nominal run has no delay to explain
    assert lines[4].split()[2:] == ["|", "0.50", "3.00", "2.50", "|", "3.00", "3.00", "0.00"]


def test_an_outcome_keeps_its_first_violation_at_or_after_the_onset() -> None:
    def violation(time: float) -> Any:
        return type("V", (), {"time": time})()

    result = type("R", (), {})()
    result.alarms, result.error, result.start = [], None, 0.0
    result.violations = [violation(t) for t in (3.0, 12.0, 11.0)]
    assert e.outcome("r", "engine", 10.0, result).violated == 11.0
    assert e.outcome("r", "nominal", None, result).violated == 3.0
    result.violations = [violation(3.0)]
    assert e.outcome("r", "engine", 10.0, result).violated is None


def test_a_false_alarm_names_what_raised_it(capsys: pytest.CaptureFixture[str]) -> None:
    """The first alarm's point, rule and invariant; printed for runs alarmed before their
    onset (any alarm of a nominal run), not for detections."""
    violation = Violation(12.5, "m", "d1", "detector", "logistic", "detector score <= 2", 3.1, "")
    result = type("R", (), {})()
    result.error, result.start, result.violations = None, 2.0, [violation]
    result.alarms = [Alarm(12.5, "m", "violation", ("d1",), violation)]
    early = e.outcome("early", "engine", 20.0, result)
    assert early.cause == "m, violation: d1 detector score <= 2" and early.false_alarm
    caught = e.outcome("caught", "engine", 10.0, result)
    quiet = _named("quiet", "nominal", None)
    e.print_false_alarms({"classified": [early, caught, quiet]})
    lines = capsys.readouterr().out.splitlines()
    assert lines[1:] == ["  classified early: 10.50 s, m, violation: d1 detector score <= 2"]
    e.print_false_alarms({"classified": [caught, quiet]})
    assert capsys.readouterr().out.splitlines()[1:] == ["  none"]


def test_the_warnings_of_a_classification() -> None:
    def diagnostic(code: str) -> Diagnostic:
        return make("c.xml", 1, 1, code, "...")

    assert e.describe_warnings([]) == "none"
    found = [diagnostic(code) for code in ("success-in-detect", *["onset-unusable"] * 2)]
    assert e.describe_warnings(found) == "onset-unusable x2, success-in-detect (expected)"


def test_the_detectors_of_a_classification() -> None:
    report = {
        "detectors": [{"point": "v", "held_out_nominal": 13}],
        "detectors_refused": [{"point": "b"}, {"point": "a"}],
    }
    assert e.describe_detectors(report) == (
        "detectors 1 learnt (v: 13 held-out nominal runs), 2 refused (a, b)"
    )
    assert e.describe_detectors({}) == "detectors 0 learnt (-), 0 refused (-)"
    report["cover"] = {
        "monitor": "detector",
        "held_out": [
            {"monitor": "cover", "value": 1.364},
            {"monitor": "detector", "value": 11.0256},
        ],
    }
    assert e.describe_detectors(report).endswith(
        "; monitor kept: detector (held-out worth: cover 1.36, detector 11.03)"
    )
