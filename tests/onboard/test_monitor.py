"""What a monitor node decides, without ROS (``imrosc/onboard/monitor.py``): actions,
warnings, alarms, the logical graph, unregistering, filling an action's message, service
calls as values, the request check, parameters, the watchdog's decision and the guard."""

from __future__ import annotations

import json
import math
from types import SimpleNamespace
from typing import Any

import numpy as np

from imrosc.onboard import files, monitor
from imrosc.runtime import Engine, Violation
from imrosc.runtime.alarms import EVERY_VIOLATION, AlarmRule, AlarmTracker
from tests.runtime.support import alarm_document as alarm_case


def violation(point: str = "a", **fields: Any) -> Violation:
    values: dict[str, Any] = {
        "time": 12.5,
        "point": point,
        "invariant": "i1",
        "family": "bounds",
        "kind": "range",
        "text": "0 <= x <= 1",
        "observed": 3.0,
        "expected": "[0, 1]",
    }
    values.update(fields)
    return Violation(**values)


def test_actions_are_selected_by_scope_id_once_each() -> None:
    found = [violation("a?cmd.data==3"), violation("v?1"), violation("a"), violation("q")]
    assert monitor.select_actions(found, {"a": ["f"], "v": ["g", "f"]}) == ["f", "g"]
    assert monitor.select_actions([violation("q")], {"a": ["f"]}) == []


def test_the_warning_is_json_with_the_invariant_point_family_and_values() -> None:
    broken = violation(observed=frozenset({"/b", "/a"}), family="architecture")
    document = json.loads(monitor.violation_json(broken, ["f"]))
    assert document == {
        "invariant": "i1",
        "point": "a",
        "family": "architecture",
        "kind": "range",
        "text": "0 <= x <= 1",
        "observed": ["/a", "/b"],
        "expected": "[0, 1]",
        "time": 12.5,
        "actions": ["f"],
        "alarm": True,
        "rule": None,
    }
    odd = json.loads(monitor.violation_json(violation(observed=(math.nan, np.float32(2.5)))))
    assert odd["observed"] == ["nan", 2.5]
    alone = json.loads(monitor.violation_json(broken, (), alarm=False))
    assert (alone["alarm"], alone["rule"], alone["actions"]) == (False, None, [])


def test_the_overrides_replace_fields_of_the_files_alarm_rule() -> None:
    calibrated = {"persist": 4, "seconds": 0.5, "distinct": 3, "window": 2.0}
    document = {**alarm_case(calibrated)}
    assert monitor.alarm_document(document, {}) is document
    assert monitor.alarm_document(document, None) is document
    for overrides in ({"persist": 2}, {"distinct": 0, "window": 0.25}, {"seconds": 1.5}):
        engine = Engine(monitor.alarm_document(document, overrides))
        assert engine.alarm_rule == AlarmRule.from_json(calibrated).overridden(**overrides)
    assert document["alarms"] == calibrated  # the file's document is left as it was
    bare = Engine(monitor.alarm_document(alarm_case(None), {"persist": 3}))
    assert bare.alarm_rule == EVERY_VIOLATION.overridden(persist=3)


def test_reports_flag_alarms_and_act_on_newly_raised_ones_only() -> None:
    """Under persist 3: two violations alone (relayed, no action), the third raises the
    alarm (withheld, the point's actions once), the fourth is in the alarmed episode
    (withheld, no action); a clean message ends it."""
    engine = Engine(monitor.alarm_document(alarm_case(None), {"persist": 3}))
    seen: list[Any] = []
    for k, value in enumerate([2.0, 2.0, 2.0, 2.0, 0.0, 2.0]):
        caused = engine.message("/a/x", 0.1 * k, [value, 0.0])
        raised, alarmed = monitor.take_alarms(engine, caused)
        reports = monitor.reports(caused, raised, alarmed, {"x": ["f"]})
        actions = monitor.select_actions(raised, {"x": ["f"]})
        withheld = monitor.withheld(caused, alarmed)
        seen.append([(r[1:], actions, withheld) for r in reports] or None)
    alone: Any = [((False, None, []), [], False)]
    assert seen == [
        alone,
        alone,
        [((True, "persist", ["f"]), ["f"], True)],
        [((True, None, []), [], True)],
        None,
        alone,
    ]


def test_an_event_raises_an_alarm_at_once_and_agreement_names_its_rule() -> None:
    found = [violation("a", invariant="i1"), violation("a", invariant="i2")]
    alarms = [SimpleNamespace(point="a", rule="agree", violation=found[1])]
    reports = monitor.reports(found, alarms, found, {"a": ["f", "g"]})
    assert [(r.alarm, r.rule, r.actions) for r in reports] == [
        (True, None, []),
        (True, "agree", ["f", "g"]),
    ]
    assert monitor.select_actions(alarms, {"a": ["f", "g"]}) == ["f", "g"]
    assert monitor.withheld_for(found, found[1:]) == "i2"
    assert monitor.withheld([], found) is False
    event = [violation("d", family="architecture")]
    raised = AlarmTracker().event(event)
    assert [r.rule for r in monitor.reports(event, raised, event, {})] == ["event"]


def test_the_log_says_alarm_or_violation() -> None:
    broken = violation()
    alarm = monitor.log_line(monitor.Report(broken, True, "persist", ["f"]))
    assert alarm == "imrosc: alarm (persist): i1 broken at a: 0 <= x <= 1"
    assert monitor.log_line(monitor.Report(broken, True, None, [])).startswith("imrosc: alarm: ")
    assert monitor.log_line(monitor.Report(broken, False, None, [])) == (
        "imrosc: violation of i1 at a: 0 <= x <= 1"
    )


STATE = [
    [["/t", ["/a", "/mon", "/rogue"]], ["/m/t", ["/mon", "/sneaky"]], ["/rosout", ["/a", "/mon"]]],
    [["/t", ["/mon"]], ["/m/t", ["/b"]], ["/m/broken_inv", ["/logger"]]],
    [["/s", ["/server"]], ["/m/s", ["/mon"]]],
]


def test_the_logical_graph_folds_relays_back_and_leaves_the_monitor_out() -> None:
    graph = monitor.logical_graph(STATE, {"/mon", "/mon_watchdog"}, {"/t": "/m/t"}, {"/s": "/m/s"})
    assert graph["pub"] == {
        "/t": frozenset({"/a", "/rogue", "/sneaky"}),
        "/rosout": frozenset({"/a"}),
    }
    assert graph["sub"] == {"/t": frozenset({"/b"}), "/m/broken_inv": frozenset({"/logger"})}
    assert graph["srv"] == {"/s": frozenset({"/server"})}


def test_unknown_publishers_are_unregistered_where_they_are_registered() -> None:
    invariants = {
        "i1": {"kind": "max_pubs", "params": {"resource": "/t", "nodes": ["/a"]}},
        "i2": {"kind": "min_pubs", "params": {"resource": "/t", "nodes": ["/a"]}},
    }
    found = [
        violation(
            invariant="i1", family="architecture", kind="max_pubs", observed=["/rogue", "/sneaky"]
        ),
        violation(invariant="i2", family="architecture", kind="min_pubs", observed=["/a"]),
        violation(invariant="i9", family="architecture", kind="max_pubs", observed=["/x"]),
        violation(invariant="i1", family="architecture", kind="max_pubs", observed=["/mon"]),
    ]
    pairs = monitor.to_unregister(found, invariants, STATE, {"/mon"}, {"/t": "/m/t"})
    assert pairs == [("/rogue", "/t"), ("/sneaky", "/m/t")]


def test_a_call_becomes_request_response_and_delay_values() -> None:
    request = {"task_id": 4, "names": ["a", "b"], "when": None}
    assert monitor.call_values(dict, request, {"ok": True}, 0.25) == {
        "request.task_id": 4,
        "len(request.names)": 2,
        "response.ok": True,
        "delay": 0.25,
    }
    assert monitor.request_values(dict, request) == {"request.task_id": 4, "len(request.names)": 2}


def test_the_request_check_keeps_request_only_value_invariants_of_blocked_services() -> None:
    variables = [
        {"name": "srv.request.a", "path": "request.a"},
        {"name": "srv.response.b", "path": "response.b"},
        {"name": "srv.delay", "path": "delay"},
    ]
    document = {
        "points": {
            "c": {"kind": "call", "trigger": "/srv", "variables": variables},
            "d": {"kind": "call", "trigger": "/other", "variables": variables},
        },
        "invariants": [
            {"id": "i1", "point": "c", "family": "bounds", "variables": ["srv.request.a"]},
            {"id": "i2", "point": "c", "family": "bounds", "variables": ["srv.response.b"]},
            {
                "id": "i3",
                "point": "c",
                "family": "order",
                "variables": ["srv.request.a", "srv.delay"],
            },
            {"id": "i4", "point": "c", "family": "frequency", "variables": ["srv.request.a"]},
            {"id": "i5", "point": "d", "family": "bounds", "variables": ["srv.request.a"]},
        ],
    }
    reduced = monitor.request_document(document, ["/srv"])
    assert [i["id"] for i in reduced["invariants"]] == ["i1"]
    assert reduced["points"] is document["points"]


def test_parameters_are_polled_flattened_and_missing_ones_left_out() -> None:
    server = {"/a/gain": 2.5, "/a/pid": {"p": 1, "i": [1, 2]}, "/a/mode": "fast"}

    def read(name: str) -> Any:
        return server[name]

    assert monitor.param_values(read, ["/a/gain", "/a/pid", "/a/missing", "/a/mode"]) == {
        "/a/gain": 2.5,
        "/a/pid.p": 1,
        "len(/a/pid.i)": 2,
        "/a/mode": "fast",
    }


def test_the_watchdog_relays_only_while_the_heartbeat_is_silent() -> None:
    assert not monitor.should_relay(10.0, 12.9, 3.0, 0.0, 5.0)
    assert monitor.should_relay(10.0, 13.1, 3.0, 0.0, 5.0)


def test_the_watchdog_waits_startup_seconds_for_the_first_beat() -> None:
    # a monitor that has not beaten yet is starting: one timeout is not enough
    assert not monitor.should_relay(None, 4.9, 1.0, 0.0, 5.0)
    assert monitor.should_relay(None, 5.1, 1.0, 0.0, 5.0)
    # once it beat, the timeout alone counts
    assert monitor.should_relay(3.0, 4.1, 1.0, 0.0, 5.0)


def test_the_guard_stops_checking_at_the_first_exception_and_reports_it() -> None:
    stopped: list[tuple[str, str]] = []
    guard = monitor.Guard(lambda where, error: stopped.append((where, repr(error))))
    assert guard.run("message on /a", lambda x: x + 1, 1) == 2
    node: dict[str, str] = {}
    assert guard.run("message on /a", lambda: node["op"]) is None
    assert guard.run("the timer", lambda: 1) is None  # stopped: nothing runs any more
    assert stopped == [("message on /a", "KeyError('op')")]
    assert guard.failure == "message on /a: KeyError: 'op'"
    report = json.loads(monitor.failure_json("message on /a", KeyError("op"), 12.5))
    assert report["kind"] == "failure" and report["alarm"] and report["rule"] == "failure"
    assert report["error"] == {"where": "message on /a", "type": "KeyError", "message": "'op'"}
    assert "stops checking" in monitor.failure_text("tick", ValueError("x"))


def test_an_invariants_file_the_engine_cannot_be_built_from_is_refused() -> None:
    """A hand-edited file of the right shape: an unknown family (the engine would skip the
    invariant, and the node would say it checks it) or a parameter the engine reads that
    does not convert; ``files.InvariantsError`` saying what, which the node's ``main`` prefixes with
    the file's path."""
    spec: Any = {"topics": [], "services": [], "violations": {}, "actions": {}}
    document = alarm_case(None)
    assert monitor.Checking(spec, document, Engine, "/m", print).engine is not None
    unknown = json.loads(json.dumps(document))
    unknown["invariants"][1]["family"] = "bogus"
    try:
        monitor.Checking(spec, unknown, Engine, "/m", print)
        raise AssertionError("an unknown family was accepted")
    except files.InvariantsError as error:
        assert str(error) == "malformed: $.invariants[1].family: unknown family 'bogus'"
    edited = json.loads(json.dumps(document))
    edited["invariants"][0]["params"] = {"max": "one"}
    try:
        monitor.Checking(spec, edited, Engine, "/m", print)
        raise AssertionError("a bound that is no number was accepted")
    except files.InvariantsError as error:
        assert str(error) == "malformed: ValueError: could not convert string to float: 'one'"
