"""The engine end to end on a hand-made invariants document."""

from __future__ import annotations

import copy
import math
from collections.abc import Sequence
from typing import Any

import numpy as np

from imrosc.runtime import Engine, Violation
from imrosc.runtime.arch import Snapshot
from tests.runtime.support import point_inv as inv
from tests.runtime.support import var

POSE = [var("pose.x", "x"), var("pose.mode", "mode", "int"), var("pose.frame", "frame", "string")]
CMD = [var("cmd.v", "v")]
STATE = [var("state.data", "data", "uint")]
STATE_IS_2 = {
    "id": "c1",
    "topic": "/a/state",
    "expression": {"op": "==", "args": [{"field": ["state"]}, {"value": 2}]},
    "fields": [[["state"], "state.data"]],
}

DOCUMENT: dict[str, Any] = {
    "format": "imrosc-invariants",
    "version": 1,
    "topics": {
        "/a/pose": {"type": "T", "variables": POSE},
        "/a/cmd": {"type": "T", "variables": CMD},
        "/a/state": {"type": "T", "variables": STATE},
    },
    "points": {
        "pose": {
            "kind": "publish",
            "trigger": "/a/pose",
            "inputs": ["/a/cmd"],
            "params": ["/gain"],
            "filter": [],
            "events": [],
            "variables": [
                *POSE,
                var("cmd.v", "v", trigger=False),
                var("/gain", "", trigger=False),
            ],
        },
        "pose?state": {
            "kind": "publish",
            "trigger": "/a/pose",
            "filter": [STATE_IS_2],
            "variables": POSE,
        },
        "pose?mode": {
            "kind": "publish",
            "trigger": "/a/pose",
            "filter": [{"variable": "pose.mode", "value": 1.0}],
            "variables": POSE,
        },
        "pose?frame": {
            "kind": "publish",
            "trigger": "/a/pose",
            "filter": [{"variable": "pose.frame", "value": "odom"}],
            "variables": POSE,
        },
        "add": {
            "kind": "call",
            "trigger": "/add",
            "variables": [
                var("add.request.a", "request.a"),
                var("add.response.sum", "response.sum"),
                var("add.delay", "delay"),
            ],
        },
        "gain": {"kind": "param", "trigger": "/gain", "variables": [var("/gain", "")]},
        "arch": {"kind": "arch", "trigger": "", "variables": []},
        "events": {
            "kind": "temporal",
            "trigger": "",
            "events": [["a", "publish", "/a/go"], ["b", "call", "/add"]],
            "variables": [{"name": "event", "type": "string", "path": "", "derived": None}],
        },
    },
    "invariants": [
        inv("x_max", "pose", "bounds", "upper", ["pose.x"], max=10.0),
        inv("x_lt_v", "pose", "order", "<", ["pose.x", "cmd.v"]),
        inv("gain_in_pose", "pose", "bounds", "range", ["/gain"], min=1.0, max=2.0),
        inv("frame", "pose", "string-one-of", "string-one-of", ["pose.frame"], values=["map"]),
        inv("freq", "pose", "frequency", "range", [], min=8.0, max=8.0, window=1.0, topic="/p"),
        inv("rate", "pose", "rate", "range", ["pose.x"], min=-1.0, max=1.0, window=1.0),
        inv("x_min_state", "pose?state", "bounds", "lower", ["pose.x"], min=5.0),
        inv("freq_state", "pose?state", "frequency", "range", [], min=8.0, max=8.0, window=1.0),
        inv("x_max_mode", "pose?mode", "bounds", "upper", ["pose.x"], max=3.0),
        inv("x_max_odom", "pose?frame", "bounds", "upper", ["pose.x"], max=20.0),
        inv(
            "sum",
            "add",
            "linear",
            "linear",
            ["add.response.sum", "add.request.a"],
            a=1.0,
            b=1.0,
            tolerance=0.0,
        ),
        inv("delay", "add", "bounds", "upper", ["add.delay"], max=0.5),
        inv("gain", "gain", "bounds", "range", ["/gain"], min=1.0, max=2.0),
        inv(
            "max_pubs",
            "arch",
            "architecture",
            "max_pubs",
            ["pubs(/a/pose)"],
            resource="/a/pose",
            nodes=["/n1"],
        ),
        inv(
            "min_subs",
            "arch",
            "architecture",
            "min_subs",
            ["subs(/a/pose)"],
            resource="/a/pose",
            nodes=["/m"],
        ),
        inv(
            "a_to_b",
            "events",
            "interval",
            "interval",
            ["event"],
            first="a",
            second="b",
            min_time=0.0,
            max_time=1.0,
            min_events={},
            max_events={},
        ),
        inv("elsewhere", "no-such-point", "bounds", "upper", ["x"], max=0.0),
    ],
}

Seen = list[tuple[float, str, Any]]


def seen(found: Sequence[Violation]) -> Seen:
    return [(v.time, v.invariant, v.observed) for v in found]


def engine(trace: Any = None) -> Engine:
    return Engine(copy.deepcopy(DOCUMENT), trace)


def pose(e: Engine, time: float, x: float, mode: int = 0, frame: str = "map") -> Seen:
    return seen(e.message("/a/pose", time, [x, mode, frame]))


def ready(e: Engine, time: float = 0.0, v: float = 100.0, gain: float = 1.5) -> None:
    """Every input of ``pose`` seen."""
    assert e.message("/a/cmd", time, [v]) == []
    assert e.params(time, {"/gain": gain}) == []


def test_samples_wait_for_every_input_topic_and_the_parameters() -> None:
    e = engine()
    assert pose(e, 0.0, 50.0) == []  # no /a/cmd yet
    assert e.message("/a/cmd", 0.1, [100.0]) == []
    assert pose(e, 0.2, 50.0) == []  # no parameters yet
    assert e.params(0.3, {"/gain": 1.5}) == []
    assert pose(e, 0.4, 50.0) == [(0.4, "x_max", 50.0)]
    assert pose(e, 0.5, 200.0) == [(0.5, "x_max", 200.0), (0.5, "x_lt_v", (200.0, 100.0))]
    assert pose(e, 0.6, 1.0, frame="odom") == [(0.6, "frame", "odom")]
    # the latest input and parameter values pair with each sample
    assert e.message("/a/cmd", 0.7, [0.5]) == []
    assert seen(e.params(0.8, {"/gain": 3.0})) == [(0.8, "gain", 3.0)]
    assert pose(e, 0.9, 1.0) == [(0.9, "gain_in_pose", 3.0), (0.9, "x_lt_v", (1.0, 0.5))]
    e.reset()  # a new run: nothing seen
    assert pose(e, 0.0, 50.0) == []


def test_a_float64_array_is_taken_as_it_is() -> None:
    """A monitor's reader may give a read-only float64 array over the message's bytes: the
    engine checks it as the list of the same values, and keeps it without a copy."""
    by_list, by_array = engine(), engine()
    for e in (by_list, by_array):
        ready(e)
    values = np.frombuffer(np.array([0.5]).tobytes(), np.float64)
    assert not values.flags.writeable
    assert by_array.message("/a/cmd", 0.7, values) == by_list.message("/a/cmd", 0.7, [0.5])
    assert by_array.latest_numeric["/a/cmd"] is values
    assert pose(by_array, 0.9, 1.0) == pose(by_list, 0.9, 1.0) == [(0.9, "x_lt_v", (1.0, 0.5))]
    # any other array is read value by value, as a list is
    ints = np.array([0], dtype=np.int64)
    assert seen(by_array.message("/a/state", 1.0, ints)) == seen(
        by_list.message("/a/state", 1.0, [0])
    )
    assert by_array.latest_numeric["/a/state"] is not ints


def test_a_value_no_source_has_is_missing() -> None:
    document = copy.deepcopy(DOCUMENT)
    point = document["points"]["pose"]
    point["params"], point["inputs"] = [], []
    e = Engine(document)
    # /gain and cmd.v have no source now: NaN, which breaks nothing
    assert pose(e, 0.0, 1.0) == []
    assert pose(e, 0.1, 11.0) == [(0.1, "x_max", 11.0)]


def test_declared_condition_on_the_latest_message_of_its_topic() -> None:
    e = engine()
    ready(e)
    assert pose(e, 0.1, 4.0) == []  # no /a/state message yet: the condition does not hold
    assert e.message("/a/state", 0.2, [2]) == []
    assert pose(e, 0.3, 4.0) == [(0.3, "x_min_state", 4.0)]
    assert pose(e, 0.4, 6.0) == []
    assert e.message("/a/state", 0.5, [3]) == []
    assert pose(e, 0.6, 4.0) == []


def test_discovered_condition_on_the_sample_itself() -> None:
    e = engine()
    ready(e)
    assert pose(e, 0.1, 5.0, mode=0) == []
    assert pose(e, 0.2, 5.0, mode=1) == [(0.2, "x_max_mode", 5.0)]
    assert pose(e, 0.3, 2.0, mode=1) == []


def test_discovered_condition_on_a_string_variable() -> None:
    # discrete strings define conditions too (imrosc.infer.engine): pose.frame == 'odom'
    e = engine()
    ready(e)
    assert pose(e, 0.1, 30.0, frame="odom") == [
        (0.1, "x_max", 30.0),
        (0.1, "frame", "odom"),
        (0.1, "x_max_odom", 30.0),
    ]
    assert pose(e, 0.2, 30.0, frame="map") == [(0.2, "x_max", 30.0)]


def test_calls() -> None:
    e = engine()
    call = {"request.a": 2.0, "response.sum": 3.0, "delay": 0.1}
    assert e.call("/add", 1.0, call) == []
    found = e.call("/add", 2.0, {**call, "response.sum": 4.0, "delay": 0.75})
    assert seen(found) == [(2.0, "delay", 0.75), (2.0, "sum", (4.0, 2.0))]
    assert found[0].point == "add"
    assert e.call("/add", 3.0, {"request.a": "two", "delay": 0.25}) == []  # missing: NaN
    assert e.call("/other", 4.0, call) == []


def test_parameter_points() -> None:
    e = engine()
    assert seen(e.params(1.0, {"/gain": 2.5, "/other": 9})) == [(1.0, "gain", 2.5)]
    assert e.params(2.0, {"/other": 9}) == []  # the point's parameter is not set
    assert e.params(3.0, {"/gain": "high"}) == []  # not a number: NaN


def test_the_architecture_is_checked_at_changes_and_every_second() -> None:
    e = engine()
    graph: Snapshot = {
        "pub": {"/a/pose": frozenset({"/n1", "/n2"})},
        "sub": {"/a/pose": frozenset()},
    }
    assert seen(e.graph(10.0, graph)) == [(10.0, "max_pubs", ["/n2"]), (10.0, "min_subs", [])]
    assert e.advance(12.5) == []  # rechecked at 11 and 12: the same breaks
    healed: Snapshot = {
        "pub": {"/a/pose": frozenset({"/n1"})},
        "sub": {"/a/pose": frozenset({"/m"})},
    }
    assert e.graph(13.0, healed) == []
    assert seen(e.graph(14.0, graph)) == [(14.0, "max_pubs", ["/n2"]), (14.0, "min_subs", [])]
    # a source that tells publishers only
    assert seen(e.graph(15.0, {"pub": {"/a/pose": frozenset({"/n3"})}}, ("pub",))) == [
        (15.0, "max_pubs", ["/n3"])
    ]
    e.reset()
    assert e.advance(100.0) == []  # no snapshot in this run yet


def test_intervals_between_a_message_and_a_call() -> None:
    e = engine()
    call = {"request.a": 2.0, "response.sum": 3.0, "delay": 0.1}
    # /a/go has no layout: its messages are events only
    assert e.message("/a/go", 1.0, []) == []  # a opens a -> b
    assert e.call("/add", 1.5, call) == []  # b within a second
    assert e.message("/a/go", 2.0, []) == []
    assert seen(e.message("/a/go", 2.5, [])) == [(2.5, "a_to_b", "a")]  # a again, before b
    found = e.advance(3.25)  # the timer: b overdue
    assert seen(found) == [(3.25, "a_to_b", 1.25)]
    assert found[0].expected == "b within 1 s of a"
    assert e.advance(4.0) == []
    assert e.call("/add", 4.5, call) == []  # reported already
    assert e.message("/a/go", 5.0, []) == []
    e.reset()  # a new run closes the interval
    assert e.advance(10.0) == []


def stream(e: Engine, start: float, stop: float, x: float = 1.0) -> Seen:
    """/a/pose at 8 Hz (exact binary times) from ``start`` to ``stop`` inclusive."""
    found: Seen = []
    for k in range(int((stop - start) * 8) + 1):
        found += pose(e, start + k / 8, x)
    return found


def test_a_silent_topic_is_reported_once() -> None:
    e = engine()
    ready(e)
    assert e.message("/a/state", 0.0, [2]) == []
    assert stream(e, 0.0, 2.0, x=6.0) == []  # 8 per window: 8 Hz
    assert e.advance(2.125) == []  # a message now would still make 8 Hz
    found = e.advance(2.25)
    # six messages in the window ending now; the conditional point "pose?state" (same
    # topic, same bounds) has no timer: its condition may simply have stopped holding
    assert seen(found) == [(2.25, "freq", 6.0)]
    assert found[0].expected == "at least 8.0 Hz (no message for 0.25 s)"
    assert e.advance(2.5) == []
    assert e.advance(5.0) == []  # once, though the topic stays silent
    # messages again: the same silence until the window is back at 8 Hz; the first, after a
    # silence longer than the window, begins a stretch whose windows warm up as at a run's
    # start (the conditional point, without a timer, reported its window of one message)
    assert stream(e, 5.0, 5.0, x=6.0) == []
    assert e.advance(5.5) == []
    assert [f for f in stream(e, 5.5, 6.5, x=6.0) if f[1] == "freq"] == []
    # recovered at 6.375 (8 in the window): a new silence is a new report
    assert seen(e.advance(6.75)) == [(6.75, "freq", 6.0)]


def alone(*invariants: dict[str, Any]) -> Engine:
    """An engine of ``/p`` (one float ``x``) and the events ``a`` (``/p``) and ``b`` (``/q``),
    holding ``invariants`` only."""
    x = [var("p.x", "x")]
    return Engine(
        {
            "format": "imrosc-invariants",
            "version": 1,
            "topics": {"/p": {"type": "T", "variables": x}, "/q": {"type": "T", "variables": []}},
            "points": {
                "p": {"kind": "publish", "trigger": "/p", "variables": x},
                "events": {
                    "kind": "temporal",
                    "trigger": "",
                    "events": [["a", "publish", "/p"], ["b", "publish", "/q"]],
                    "variables": [{"name": "event", "type": "string", "path": "", "derived": None}],
                },
            },
            "invariants": list(invariants),
        }
    )


def test_a_pause_is_one_violation_of_the_frequency_minimum() -> None:
    e = alone(inv("freq", "p", "frequency", "range", [], min=9.0, max=11.0, window=1.0))
    found: list[Violation] = []
    times = [k / 10 for k in range(51)] + [8.0 + k / 10 for k in range(51)]  # 3 s without
    for time in times:
        found += e.message("/p", time, [1.0])
    assert [(v.time, v.expected) for v in found] == [(8.0, "at least 9.0 Hz (no message for 3 s)")]
    # back at 10 Hz since 9 s: a second pause is a second violation, reported once
    found = [*e.message("/p", 14.0, [1.0]), *e.message("/p", 14.01, [1.0])]
    assert [v.time for v in found] == [14.0]
    assert seen(e.message("/p", 14.02, [1.0])) == []  # 3 in the window: still the silence


def test_a_dead_topic_stays_reported_when_the_run_ends() -> None:
    # a -> b within 0.5 s; /q (b) dies at 2 s while /p (a) goes on to 10 s
    e = alone(
        inv(
            "a_to_b",
            "events",
            "interval",
            "interval",
            ["event"],
            first="a",
            second="b",
            min_time=0.0,
            max_time=0.5,
            min_events={},
            max_events={"a": 100},
        )
    )
    found: list[Violation] = []
    for k in range(11):
        found += e.message("/p", float(k), [1.0])
        if k < 2:
            found += e.message("/q", k + 0.25, [])
    assert seen(found) == [(3.0, "a_to_b", 1.0)]  # b overdue since 2.5 s
    assert e.end_run() == []  # decided long before the end: it stands
    # an interval still within its maximum when the run ends is undecided
    e.reset()
    assert e.message("/p", 0.0, [1.0]) == []
    assert e.end_run() == []


def test_frequency_and_rate_of_full_windows() -> None:
    e = engine()
    ready(e)
    assert stream(e, 0.0, 1.0) == []  # no window is defined before 1 s
    # a ninth message in the window (0.0625, 1.0625]
    assert pose(e, 1.0625, 1.0) == [(1.0625, "freq", 9.0)]
    # (0.125, 1.125]: nine again; x rose by 0.5 since 0.25 (the window's first sample)
    assert pose(e, 1.125, 1.5) == [(1.125, "freq", 9.0)]
    # (0.25, 1.25]: x rose by 2 since 0.375
    assert pose(e, 1.25, 3.0) == [(1.25, "freq", 9.0), (1.25, "rate", 2.0 / 0.875)]


def test_clear_stops_reports() -> None:
    e = engine()
    ready(e)
    assert pose(e, 0.1, 50.0) == [(0.1, "x_max", 50.0)]
    assert e.clear("x_max") is True
    assert e.clear("no-such-id") is False
    assert e.clear("elsewhere") is False  # its point does not exist
    assert pose(e, 0.2, 50.0) == []
    for ident in ("freq", "rate", "a_to_b", "max_pubs", "gain"):
        assert e.clear(ident)
    assert stream(e, 1.0, 3.0) == []
    assert e.advance(10.0) == []  # the silent-topic timer names no cleared invariant
    assert e.message("/a/go", 11.0, []) == []
    assert e.message("/a/go", 11.5, []) == []
    assert e.advance(20.0) == []
    assert seen(e.graph(21.0, {"pub": {"/a/pose": frozenset({"/n9"})}})) == [(21.0, "min_subs", [])]
    assert e.params(22.0, {"/gain": 7.0}) == []
    assert pose(e, 23.0, 1.0, frame="odom") == [
        (23.0, "gain_in_pose", 7.0),  # the parameter point's bounds only were cleared
        (23.0, "frame", "odom"),
    ]


def test_trace_sees_every_checked_sample() -> None:
    traced: list[tuple[str, float, list[float], float | None]] = []

    def trace(point: str, time: float, sample: Any, frequency: float | None) -> None:
        traced.append((point, time, np.asarray(sample).tolist(), frequency))

    e = engine(trace)
    ready(e, v=100.0, gain=1.5)
    pose(e, 0.5, 1.0, mode=1)
    assert traced[0] == ("gain", 0.0, [1.5], None)  # the parameter point's sample
    assert traced[1:] == [
        ("pose", 0.5, [1.0, 1.0, 100.0, 1.5], None),  # the window is not defined yet
        ("pose?mode", 0.5, [1.0, 1.0], None),
    ]
    assert not any(math.isnan(v) for _, _, row, _ in traced for v in row)


def test_rehearsing_keeps_nothing() -> None:
    """``rehearse`` (the monitor's warm-keeping between sparse messages) changes no state and
    no answer: the same stream with a rehearsal before every message breaks the same
    invariants at the same times, polygons included (their lookup memory is refreshed by
    the rehearsal, never left stale)."""
    rng = np.random.default_rng(8)
    cloud = rng.normal(0.0, 1.0, (300, 2))
    vertices = cloud[[0, 1, 2]]  # a triangle of the cloud's first points
    normals = np.stack(
        [vertices[[1, 2, 0], 1] - vertices[:, 1], vertices[:, 0] - vertices[[1, 2, 0], 0]], axis=1
    )
    (ux, uy), (vx, vy) = vertices[1] - vertices[0], vertices[2] - vertices[0]
    if ux * vy - uy * vx < 0:  # clockwise: the normals point in
        normals = -normals
    offsets = (normals * vertices).sum(axis=1)
    document: dict[str, Any] = {
        "format": "imrosc-invariants",
        "version": 1,
        "topics": {"/t": {"type": "T", "variables": [var("t.x", "x"), var("t.y", "y")]}},
        "points": {
            "a": {
                "kind": "publish",
                "trigger": "/t",
                "variables": [var("t.x", "x"), var("t.y", "y")],
            }
        },
        "invariants": [
            inv("x_max", "a", "bounds", "upper", ["t.x"], max=1.0),
            inv(
                "triangle",
                "a",
                "polygon",
                "hull",
                ["t.x", "t.y"],
                vertices=vertices.tolist(),
                A=normals.tolist(),
                b=offsets.tolist(),
            ),
        ],
    }
    plain, rehearsed = Engine(copy.deepcopy(document)), Engine(copy.deepcopy(document))
    stream = [(0.01 * k, [float(x), float(y)]) for k, (x, y) in enumerate(cloud)]
    stream += [(9.0 + 0.01 * k, values) for k, (_, values) in enumerate(stream[::-1])]
    found, again = [], []
    for time, values in stream:
        found += seen(plain.message("/t", time, values))
        rehearsed.rehearse(["/t", "/unknown"])
        again += seen(rehearsed.message("/t", time, values))
        rehearsed.rehearse(["/t"])
    assert {f[1] for f in found} == {"x_max", "triangle"}
    assert again == found
