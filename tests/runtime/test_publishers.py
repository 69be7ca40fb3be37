"""Messages of a publisher the architecture does not know (``Engine.intruder``): they break
the topic's ``max_pubs`` invariants, are an alarm from their first message, and no other
invariant sees them, so the data invariants check what the known publishers send."""

from __future__ import annotations

from pathlib import Path
from typing import Any

from imrosc.checking import run as checking_run
from imrosc.onboard import monitor
from imrosc.replay import Replayer
from imrosc.runtime import Engine
from imrosc.runtime.alarms import AlarmRule
from tests.runtime.support import point_inv, var
from tests.translate import msg, write_bag

FLOAT = "std_msgs/msg/Float64"

STATE_IS_4 = {
    "id": "c1",
    "topic": "/a/state",
    "expression": {"op": "==", "args": [{"field": ["state"]}, {"value": 4}]},
    "fields": [[["state"], "state.data"]],
}


def document(conditional: bool = False) -> dict[str, Any]:
    """``/a/pose`` published by ``/car`` at 20 Hz (``15 <= freq <= 25``, ``x <= 10``), its
    publishers bounded by ``max_pubs(/a/pose) = {/car}`` at ``arch`` (``conditional``: only
    while ``/a/state`` is 4)."""
    arch: dict[str, Any] = {"kind": "arch", "trigger": "", "variables": []}
    if conditional:
        arch["filter"] = [STATE_IS_4]
    return {
        "format": "imrosc-invariants",
        "version": 1,
        "topics": {
            "/a/pose": {"type": "T", "variables": [var("pose.x", "x")]},
            "/a/state": {"type": "T", "variables": [var("state.data", "data", "uint")]},
        },
        "points": {
            "v": {"kind": "publish", "trigger": "/a/pose", "variables": [var("pose.x", "x")]},
            "d": arch,
        },
        "invariants": [
            point_inv("x_max", "v", "bounds", "upper", ["pose.x"], max=10.0),
            point_inv(
                "freq", "v", "frequency", "range", [], min=15.0, max=25.0, window=1.0, topic=""
            ),
            point_inv(
                "pubs",
                "d",
                "architecture",
                "max_pubs",
                ["pubs(/a/pose)"],
                resource="/a/pose",
                nodes=["/car"],
            ),
        ],
    }


def test_an_unknown_publisher_breaks_the_architecture_and_nothing_else() -> None:
    """The car at 20 Hz and a thief at 50 Hz with values out of bounds: only the thief's
    messages break an invariant (max_pubs, an alarm at its first message and every later
    one in it); the frequency and the bounds see the car's messages alone and hold. Before,
    the frequency (70 Hz) and the bounds broke on the merged stream."""
    engine = Engine(document(), rule=AlarmRule(persist=3))
    thief_found, car_found = [], []
    for step in range(200):  # 2 s at 100 Hz: the car every 5th step, the thief every 2nd
        now = step * 0.01
        if step % 5 == 0:
            car_found += engine.message("/a/pose", now, [1.0], "/car")
        if step % 2 == 0:
            thief_found += engine.message("/a/pose", now, [50.0], "/thief")
    assert car_found == []
    assert len(thief_found) == 100
    assert {(v.invariant, v.family, tuple(v.observed)) for v in thief_found} == {
        ("pubs", "architecture", ("/thief",))
    }
    alarms = engine.take_alarms()
    assert [(a.rule, a.time, a.violation.invariant) for a in alarms] == [("event", 0.0, "pubs")]
    assert len(engine.alarms.alarmed(thief_found[-1:], [])) == 1
    assert engine.latest_numeric["/a/pose"].tolist() == [1.0]  # the car's, not the thief's
    # without the publisher (a source that does not say), every message is the system's
    merged = Engine(document(), rule=AlarmRule(persist=3))
    found = []
    for step in range(200):
        if step % 5 == 0:
            found += merged.message("/a/pose", step * 0.01, [1.0])
        if step % 2 == 0:
            found += merged.message("/a/pose", step * 0.01, [50.0])
    assert {v.invariant for v in found} == {"x_max", "freq"}


def test_known_publishers_players_and_anonymous_names_are_admitted() -> None:
    engine = Engine(document())
    assert engine.intruder("/a/pose", 0.0, "/car") == []
    assert engine.intruder("/a/pose", 0.0, "/play_1553088502272947227") == []
    assert engine.intruder("/a/other", 0.0, "/anyone") == []  # no invariant bounds it
    (found,) = engine.intruder("/a/pose", 0.0, "/thief_12345_1553088502272")
    assert found.observed == ["/thief_12345_1553088502272"]  # as it named itself
    assert engine.clear("pubs")
    assert engine.intruder("/a/pose", 1.0, "/thief") == []  # cleared: nothing bounds it


def test_a_conditional_bound_refuses_only_while_its_condition_holds() -> None:
    engine = Engine(document(conditional=True))
    assert engine.message("/a/state", 0.0, [3]) == []
    assert engine.message("/a/pose", 0.1, [1.0], "/thief") == []  # not landing: data
    assert engine.latest_numeric["/a/pose"].tolist() == [1.0]
    assert engine.message("/a/state", 0.2, [4]) == []
    (found,) = engine.message("/a/pose", 0.3, [2.0], "/thief")
    assert (found.point, found.invariant) == ("d", "pubs")
    assert engine.latest_numeric["/a/pose"].tolist() == [1.0]


def test_a_monitor_withholds_the_unknown_publishers_messages_only() -> None:
    """The blocking decision of both nodes (``Checking.check_values`` and ``withheld``):
    on a blocked topic the thief's messages are withheld from its first on, the car's go
    through, and the first of the thief's raises the alarm that unregisters it."""
    violation_map = {"d": ["s"], "v": ["f"]}
    spec: Any = {
        "topics": [{"name": "/a/pose", "relay": True}],
        "services": [],
        "violations": violation_map,
        "actions": {},
    }
    checking = monitor.Checking(spec, document(), Engine, "/m", print)
    relayed: list[tuple[str, float]] = []
    unregistered: list[tuple[str, str]] = []
    state = [[["/a/pose", ["/car", "/thief"]]], [], []]
    by_id = {inv["id"]: inv for inv in document()["invariants"]}
    for step in range(100):
        now = step * 0.01
        for publisher, period, x in (("/car", 5, 1.0), ("/thief", 2, 50.0)):
            if step % period:
                continue
            _, caused, raised, alarmed = checking.check_values("/a/pose", now, [x], publisher)
            if not monitor.withheld(caused, alarmed):
                relayed.append((publisher, now))
            violations = [a.violation for a in raised]
            unregistered += monitor.to_unregister(violations, by_id, state, {"/mon"}, {})
            assert monitor.select_actions(raised, violation_map) == (
                ["s"] if (publisher, step) == ("/thief", 0) else []
            )
    assert {p for p, _ in relayed} == {"/car"}
    assert len(relayed) == 20
    assert unregistered == [("/thief", "/a/pose")]


def test_replay_tells_publishers_apart_by_callerid_both_ways(tmp_path: Path) -> None:
    """A ROS 1 bag of ``/a/pose`` from ``/car`` (20 Hz, x 1) and ``/thief`` (50 Hz, x 50,
    from 0.5 s), each on its connection: the message-by-message replay and the chunked one
    (a chunk of 7 messages, so that dropped rows cross chunks) report the thief's messages
    as breaking ``max_pubs`` only, from its first, and the car's data holds."""
    messages = [msg("/a/pose", 0.05 * k, FLOAT, "/car", data=1.0) for k in range(40)]
    messages += [
        msg("/a/pose", 0.5 + 0.02 * k + 0.001, FLOAT, "/thief", data=50.0) for k in range(50)
    ]
    bag = write_bag(tmp_path / "run.bag", messages)
    doc = document()
    doc["topics"]["/a/pose"]["type"] = FLOAT
    doc["topics"]["/a/pose"]["variables"] = [var("pose.x", "data")]
    doc["points"]["v"]["variables"] = [var("pose.x", "data")]
    doc["alarms"] = {"persist": 3}
    runs = []
    for chunked in (False, True):
        old = checking_run.CHUNK_MESSAGES
        checking_run.CHUNK_MESSAGES = 7
        try:
            result = Replayer(doc, chunked=chunked).run(bag)
        finally:
            checking_run.CHUNK_MESSAGES = old
        assert result.error is None
        runs.append(result)
    by_message, by_chunk = runs
    assert [v.as_json() for v in by_chunk.violations] == [
        v.as_json() for v in by_message.violations
    ]
    assert [a.as_json() for a in by_chunk.alarms] == [a.as_json() for a in by_message.alarms]
    # each of the thief's 50 messages, and the graph the callerids give at its first
    assert len(by_message.violations) == 51
    assert {(v.invariant, tuple(v.observed)) for v in by_message.violations} == {
        ("pubs", ("/thief",))
    }
    assert {(a.time, a.rule, a.point) for a in by_message.alarms} == {(0.501, "event", "d")}
    assert by_message.checked == {"v": 40}  # the car's messages, and only those


def test_a_bound_that_names_no_publisher_refuses_nobody() -> None:
    """``max_pubs(/a/pose) = {}``: the graph learnt no publisher of a topic whose messages
    were recorded (architecture records that left it out). It tells no publisher apart, so
    the messages stay the system's data."""
    doc = document()
    doc["invariants"][-1]["params"]["nodes"] = []
    engine = Engine(doc)
    assert "/a/pose" not in engine.guarded
    assert engine.message("/a/pose", 0.0, [50.0], "/car")[0].invariant == "x_max"
