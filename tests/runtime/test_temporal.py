"""Interval and pattern machines against the invariants inference builds from the same runs."""

from __future__ import annotations

import json
from collections.abc import Mapping, Sequence
from typing import Any

from hypothesis import given, settings
from hypothesis import strategies as st

from imrosc.infer.core import Invariant
from imrosc.infer.temporal import IntervalState, PatternState, compile_pattern
from imrosc.invariants import document, dumps
from imrosc.runtime.temporal import IntervalMachine, PatternMachine
from imrosc.runtime.violation import Violation
from tests.infer.temporal.helpers import Event, concrete, context, samples

POINT = "e"
GENERAL = ("(AB)*", "(AAB)*", "((A|B)+C)*", "(A(B|C))*")


def as_json(invariants: Sequence[Invariant]) -> list[dict[str, Any]]:
    """The invariants as the invariants file holds them (ids, JSON-safe params)."""
    doc = document(
        project="t",
        source="t.xml",
        bags=[],
        tunables={},
        topics={},
        points=[],
        invariants=invariants,
    )
    loaded: list[dict[str, Any]] = json.loads(dumps(doc))["invariants"]
    return loaded


def infer(
    runs: Sequence[Sequence[Event]], events: tuple[str, ...], max_interval: float, max_events: int
) -> list[dict[str, Any]]:
    """Interval and pattern invariants of ``runs`` (every justified one: limit 0)."""
    patterns = [concrete(text, events) for text in GENERAL]
    states: list[IntervalState | PatternState] = [
        IntervalState(events, max_interval, max_events),
        PatternState(events, patterns),
    ]
    for run, stream in enumerate(runs):
        for state in states:
            state.update(samples(stream, run, POINT))
            state.end_run()
    return as_json([i for state in states for i in state.finalize(context(0.0, POINT))])


@st.composite
def event_runs(draw: st.DrawFn) -> tuple[tuple[str, ...], list[list[Event]]]:
    """3 or 4 events and 1 to 3 runs of them: random, or a motif with occasional noise."""
    events = ("a", "b", "c", "d")[: draw(st.integers(3, 4))]
    gaps = st.sampled_from([0.0, 0.1, 0.25, 0.5, 0.75, 1.0, 1.5, 2.5])
    runs: list[list[Event]] = []
    for _ in range(draw(st.integers(1, 3))):
        size = draw(st.integers(0, 30))
        if draw(st.booleans()):
            names = draw(st.lists(st.sampled_from(events), min_size=size, max_size=size))
        else:
            motif = draw(st.sampled_from(["ab", "aab", "abc", "acb", "abac", "cab"]))
            offset = draw(st.integers(0, len(motif) - 1))
            names = [motif[(offset + i) % len(motif)] for i in range(size)]
            for k in draw(st.lists(st.integers(0, max(size - 1, 0)), max_size=2)):
                if k < size:
                    names[k] = draw(st.sampled_from(events))
        time = draw(st.sampled_from([0.0, 1.7e9]))
        stream: list[Event] = []
        for name in names:
            time += draw(gaps)
            stream.append((name, time))
        runs.append(stream)
    return events, runs


def drive_intervals(
    machine: IntervalMachine, runs: Sequence[Sequence[Event]]
) -> tuple[list[Violation], list[Violation]]:
    """``(violations of intervals that close in their run, those of run tails)``, the timer
    ticking at every event as the engine does."""
    closed: list[Violation] = []
    tails: list[Violation] = []
    for stream in runs:
        machine.reset()
        pending: dict[float, list[Violation]] = {}
        for name, time in stream:
            opened = machine.opened
            found = machine.tick(time) + machine.event(time, name)
            if opened is None:
                opened = machine.opened
            if found:
                assert opened is not None
                pending.setdefault(opened, []).extend(found)
            if machine.opened is None and opened is not None:  # an interval closed
                closed += pending.pop(opened, [])
        for found in pending.values():
            tails += found
        # the engine withdraws exactly these when a recorded run ends (Engine.end_run),
        # unless the open interval outlived its maximum time: then they stand
        standing = machine.timed_out
        open_ = [v for found in pending.values() for v in found]
        assert machine.unfinished() == ([] if standing else open_)
    return closed, tails


def drive_pattern(machine: PatternMachine, runs: Sequence[Sequence[Event]]) -> list[Violation]:
    found: list[Violation] = []
    for stream in runs:
        machine.reset()
        for name, time in stream:
            found += machine.event(time, name)
    return found


@settings(max_examples=80, deadline=None)
@given(event_runs(), st.sampled_from([(2.0, 10), (5.0, 10), (100.0, 4), (100.0, 100)]))
def test_training_runs_never_violate_their_invariants(
    drawn: tuple[tuple[str, ...], list[list[Event]]], thresholds: tuple[float, int]
) -> None:
    events, runs = drawn
    invariants = infer(runs, events, *thresholds)
    for inv in invariants:
        if inv["family"] == "interval":
            closed, tails = drive_intervals(IntervalMachine(inv, POINT), runs)
            # Every interval inference recorded passes; only an interval still open when its
            # run ended (inference never records those) may break the invariant; replay
            # withdraws those violations unless the interval outlived its maximum time
            # (IntervalMachine.unfinished).
            assert closed == []
            for violation in tails:
                assert violation.expected.startswith(("at most", inv["params"]["second"]))
        else:
            assert inv["family"] == "pattern"
            assert drive_pattern(PatternMachine(inv, POINT), runs) == []


# -- known violations ------------------------------------------------------------------------


def interval(
    first: str = "a",
    second: str = "b",
    times: tuple[float, float] = (1.0, 2.0),
    least: Mapping[str, int] | None = None,
    most: Mapping[str, int] | None = None,
) -> dict[str, Any]:
    return {
        "id": "i1",
        "family": "interval",
        "kind": "interval",
        "point": POINT,
        "variables": ["event"],
        "text": f"{first} -> {second}",
        "params": {
            "first": first,
            "second": second,
            "min_time": times[0],
            "max_time": times[1],
            "min_events": dict(least or {}),
            "max_events": dict(most or {}),
        },
    }


def feed(machine: IntervalMachine | PatternMachine, stream: Sequence[Event]) -> list[Violation]:
    found: list[Violation] = []
    for name, time in stream:
        if isinstance(machine, IntervalMachine):
            found += machine.tick(time)
        found += machine.event(time, name)
    return found


def summary(found: Sequence[Violation]) -> list[tuple[float, Any, str]]:
    return [(v.time, v.observed, v.expected) for v in found]


def test_thesis_aab_breaks_an_empty_maximum() -> None:
    # inferred from "a b" only: a -> b with nothing in between
    inferred = infer([[("a", 0.0), ("b", 1.0)]] * 3, ("a", "b"), 2.0, 10)
    (inv,) = [i for i in inferred if i["text"].startswith("a -> b")]
    assert inv["params"]["max_events"] == {}
    machine = IntervalMachine(inv, POINT)
    found = feed(machine, [("a", 0.0), ("a", 0.5), ("b", 1.0)])
    assert summary(found) == [(0.5, "a", "at most 0 x a within a -> b")]
    assert found[0].invariant == inv["id"]
    assert (found[0].family, found[0].kind, found[0].point) == ("interval", "interval", POINT)
    # the interval closed at b: a new one opens cleanly
    assert feed(machine, [("a", 2.0), ("b", 3.0)]) == []


def test_too_many_events_are_reported_once_per_interval() -> None:
    machine = IntervalMachine(interval(times=(0.0, 10.0), most={"c": 1}), POINT)
    found = feed(machine, [("a", 0.0), ("c", 1.0), ("c", 2.0), ("c", 3.0), ("b", 4.0)])
    assert summary(found) == [(2.0, "c", "at most 1 x c within a -> b")]


def test_interval_too_short_and_too_long() -> None:
    machine = IntervalMachine(interval(), POINT)
    assert summary(feed(machine, [("a", 0.0), ("b", 0.5)])) == [(0.5, 0.5, "[1, 2] s")]
    assert feed(machine, [("a", 1.0), ("b", 2.0)]) == []  # exactly min_time
    assert feed(machine, [("a", 3.0), ("b", 5.0)]) == []  # exactly max_time
    # no timer ran: the closing event finds it too long
    machine.event(10.0, "a")
    assert summary(machine.event(12.5, "b")) == [(12.5, 2.5, "[1, 2] s")]


def test_the_timer_reports_an_overdue_interval_exactly_once() -> None:
    machine = IntervalMachine(interval(most={"c": 1}), POINT)
    assert machine.tick(1.0) == []  # closed: nothing to time
    assert machine.event(10.0, "a") == []
    assert machine.tick(12.0) == []  # exactly max_time is fine
    found = machine.tick(12.25)
    assert summary(found) == [(12.25, 2.25, "b within 2 s of a")]
    assert machine.tick(13.0) == []
    assert machine.event(13.5, "c") == []  # the count check still runs, the timer not
    assert machine.event(14.0, "b") == []  # already reported: no second time violation
    # the next interval is timed afresh
    machine.event(20.0, "a")
    assert len(machine.tick(30.0)) == 1


def test_a_new_run_forgets_the_open_interval() -> None:
    machine = IntervalMachine(interval(), POINT)
    machine.event(0.0, "a")
    machine.reset()
    assert machine.tick(100.0) == []
    assert machine.event(101.0, "b") == []  # b alone does nothing


def test_least_multiset_not_met() -> None:
    machine = IntervalMachine(interval(times=(0.0, 10.0), least={"c": 2}, most={"c": 3}), POINT)
    found = feed(machine, [("a", 0.0), ("c", 1.0), ("b", 2.0)])
    assert summary(found) == [(2.0, "{1 x c}", "at least {2 x c} between a and b")]
    assert feed(machine, [("a", 3.0), ("c", 4.0), ("c", 4.5), ("b", 5.0)]) == []


def test_an_interval_left_open_at_the_end_of_a_training_run_is_no_training_sample() -> None:
    # Inference never records an interval that its run ends before closing, so such a tail
    # may break the invariant when the same run is replayed (Algorithm 11 times it out).
    runs = [[("a", 0.0), ("b", 1.0), ("a", 2.0), ("c", 2.5)]] * 2
    (inv,) = [i for i in infer(runs, ("a", "b", "c"), 5.0, 10) if i["text"].startswith("a -> b")]
    assert (inv["params"]["max_time"], inv["params"]["max_events"]) == (1.0, {})
    closed, tails = drive_intervals(IntervalMachine(inv, POINT), runs)
    assert closed == []
    assert summary(tails) == [(2.5, "c", "at most 0 x c within a -> b")] * 2
    machine = IntervalMachine(inv, POINT)
    feed(machine, runs[0])
    assert summary(machine.tick(3.5)) == [(3.5, 1.5, "b within 1 s of a")]


def test_the_end_of_a_run_withdraws_only_an_undecided_interval() -> None:
    machine = IntervalMachine(interval(most={"c": 0}), POINT)
    found = feed(machine, [("a", 0.0), ("c", 0.5)])  # too many events, still within 2 s
    assert summary(found) == [(0.5, "c", "at most 0 x c within a -> b")]
    assert machine.unfinished() == found  # undecided when the run ends: withdrawn
    feed(machine, [("a", 10.0), ("c", 10.5)])
    assert summary(machine.tick(13.0)) == [(13.0, 3.0, "b within 2 s of a")]
    assert machine.unfinished() == []  # b overdue: the interval's violations stand
    assert machine.opened is None


def test_events_before_the_opening_do_nothing() -> None:
    machine = IntervalMachine(interval(most={}), POINT)
    assert feed(machine, [("b", 0.0), ("c", 0.5), ("c", 0.6)]) == []


def pattern(text: str, events: tuple[str, ...]) -> dict[str, Any]:
    return {
        "id": "p1",
        "family": "pattern",
        "kind": "pattern",
        "point": POINT,
        "variables": ["event"],
        "text": text,
        "params": {"pattern": text, **compile_pattern(text, events).to_json()},
    }


def test_pattern_broken_by_a_repeated_event_then_watching_again() -> None:
    machine = PatternMachine(pattern("(ab)*", ("a", "b")), POINT)
    found = feed(machine, [("b", 0.0), ("a", 1.0), ("b", 2.0), ("a", 3.0), ("a", 4.0)])
    assert summary(found) == [(4.0, "b a b a a", "events in the order (ab)*")]
    assert found[0].invariant == "p1"
    # reset to every state: the trace goes on from wherever it is
    assert feed(machine, [("b", 5.0), ("a", 6.0), ("b", 7.0)]) == []
    assert summary(feed(machine, [("b", 8.0)])) == [(8.0, "b a b b", "events in the order (ab)*")]


def test_pattern_ignores_events_outside_its_alphabet_and_keeps_8_events() -> None:
    machine = PatternMachine(pattern("(ab)*", ("a", "b", "c")), POINT)
    stream = [(e, float(i)) for i, e in enumerate("acbcab" + "ab" * 4 + "b")]
    (found,) = feed(machine, stream)
    assert found.observed == "a b a b a b a b b"[2:]  # the last 8 events of the alphabet


def test_pattern_starts_anywhere_in_each_run() -> None:
    machine = PatternMachine(pattern("(aab)*", ("a", "b")), POINT)
    assert feed(machine, [(e, float(i)) for i, e in enumerate("abaab")]) == []
    machine.reset()
    assert feed(machine, [(e, float(i)) for i, e in enumerate("baab")]) == []
    assert len(feed(machine, [("b", 9.0)])) == 1
