"""Ordered-pair interval invariants (thesis 3.4.4.1, Algorithm 8, Figure 3.13, Table 5.5)."""

from __future__ import annotations

import pickle
from collections import Counter
from dataclasses import dataclass, field

from hypothesis import given, settings
from hypothesis import strategies as st

from imrosc.infer.core import Invariant, confidence
from imrosc.infer.temporal import IntervalState, make_temporal_states
from tests.infer.temporal.helpers import Event, context, samples, trace

# Figure 3.13 is an image; this trace is reconstructed from its description (section
# 3.4.4.1): four a -> b intervals of 1 to 2 s with nothing in between, exactly two b between
# every a and the next c, and b -> c with at most one other b in between (the trace opens
# with "b c", as if recording started late). a -> c then lasts 2 to 3 s, so the thresholds
# are the plan's 5 s rather than the default 2 s.
FIGURE_3_13: list[Event] = [
    ("b", 0.0),
    ("c", 0.5),
    ("a", 1.0),
    ("b", 2.0),
    ("b", 2.5),
    ("c", 3.0),
    ("a", 4.0),
    ("b", 6.0),
    ("b", 6.5),
    ("c", 7.0),
    ("a", 8.0),
    ("b", 9.5),
    ("b", 10.0),
    ("c", 10.5),
    ("a", 11.0),
    ("b", 12.25),
    ("b", 12.5),
    ("c", 13.0),
]


def infer(
    runs: list[list[Event]],
    events: tuple[str, ...] = ("a", "b", "c"),
    max_interval: float = 5.0,
    max_events: int = 10,
    limit: float = 0.0,
) -> dict[str, Invariant]:
    state = IntervalState(events, max_interval, max_events)
    for run, stream in enumerate(runs):
        state.update(samples(stream, run))
        state.end_run()
    return {
        f"{i.params['first']} -> {i.params['second']}": i for i in state.finalize(context(limit))
    }


def test_figure_3_13() -> None:
    found = infer([FIGURE_3_13])
    assert {name: inv.text for name, inv in found.items()} == {
        "a -> b": "a -> b: [1.0, 2.0] s, min {}, max {}",
        "a -> c": "a -> c: [2.0, 3.0] s, min {2 x b}, max {2 x b}",
        "b -> c": "b -> c: [0.5, 1.0] s, min {}, max {b}",
        # "three other intervals invariant (b -> a, c -> b and c -> a) would be generated"
        "b -> a": "b -> a: [1.0, 2.0] s, min {c}, max {b, c}",
        "c -> a": "c -> a: [0.5, 1.0] s, min {}, max {}",
        "c -> b": "c -> b: [1.5, 3.0] s, min {a}, max {a}",
    }
    inv = found["a -> c"]
    assert inv.family == "interval"
    assert inv.kind == "interval"
    assert inv.variables == ("event",)
    assert inv.params == {
        "first": "a",
        "second": "c",
        "min_time": 2.0,
        "max_time": 3.0,
        "min_events": {"b": 2},
        "max_events": {"b": 2},
        "max_interval": 5.0,
        "max_events_threshold": 10,
    }
    assert inv.samples == 4
    # The maximum time last changed at the second interval: 3 intervals since.
    assert inv.confidence == confidence(3)


def test_default_thresholds_drop_weak_pairs() -> None:
    found = infer([FIGURE_3_13], max_interval=2.0)
    # a -> c and c -> b once took 3 s: not ordered pairs at all.
    assert sorted(found) == ["a -> b", "b -> a", "b -> c", "c -> a"]


def test_a_pair_dropped_in_one_run_stays_dropped() -> None:
    slow = [("a", 0.0), ("b", 3.0)]
    found = infer([trace("ab" * 8), slow, trace("ab" * 8)], events=("a", "b"), max_interval=2.0)
    assert "a -> b" not in found
    assert "b -> a" in found


def test_open_interval_is_dropped_once_too_long_even_without_second_event() -> None:
    # a opens at 0; c at 2.5 is recorded after the 2 s limit: a -> b is weak, though b never
    # closes that interval.
    found = infer([[("a", 0.0), ("c", 2.5)], trace("ab" * 8)], max_interval=2.0)
    assert "a -> b" not in found


def test_repeated_first_event_is_recorded_not_reopened() -> None:
    found = infer([[("a", 0.0), ("a", 0.5), ("b", 1.0)]], events=("a", "b"))
    assert found["a -> b"].params["min_time"] == 1.0
    assert found["a -> b"].params["max_events"] == {"a": 1}


def test_too_many_events_in_between() -> None:
    found = infer([trace("accb")], max_events=1)
    assert "a -> b" not in found
    assert "a -> c" in found
    found = infer([trace("accb")], max_events=2)
    assert found["a -> b"].params["max_events"] == {"c": 2}


def test_runs_never_share_an_interval() -> None:
    found = infer([trace("a"), trace("b")], events=("a", "b"))
    assert found == {}


def test_table_5_5_interleaved_sensors() -> None:
    # scan (s), obs_imu (o), scan_sync (y) at about 10 Hz, highly interleaved: repeated
    # first events and consecutive scan_sync land in the event multisets.
    stream = [(e, 0.1 * i) for i, e in enumerate("syysoosyo" * 3)]
    found = infer([stream], events=("s", "o", "y"), max_interval=2.0, limit=0.0)
    assert found["s -> o"].params["min_events"] == {"y": 1}
    assert found["s -> o"].params["max_events"] == {"s": 1, "y": 2}
    assert found["s -> o"].text.endswith("min {y}, max {s, 2 x y}")
    assert found["o -> s"].params["min_events"] == {}
    assert found["o -> s"].params["max_events"] == {"o": 1}


def test_justification_needs_unchanged_intervals() -> None:
    stream = trace("ab" * 10, step=0.5)
    found = infer([stream], events=("a", "b"), limit=0.99)
    # Every a -> b interval is 0.5 s with nothing in between: 10 unchanged intervals.
    assert found["a -> b"].confidence == confidence(10)
    assert found["b -> a"].samples == 9
    stream[-1] = ("b", stream[-1][1] + 0.25)
    assert "a -> b" not in infer([stream], events=("a", "b"), limit=0.99)


def test_make_temporal_states() -> None:
    events = ("a", "b")
    assert make_temporal_states(events, [], 2.0, 10, frozenset({"bounds"})) == []
    (state,) = make_temporal_states(events, [], 2.0, 10, frozenset({"interval", "pattern"}))
    assert state.family == "interval"


# -- a literal, event-by-event Algorithm 8 as the reference ----------------------------------


@dataclass
class _Pair:
    open: bool = False
    since: float = 0.0
    between: Counter[str] = field(default_factory=Counter)
    dropped: bool = False
    intervals: list[tuple[float, Counter[str]]] = field(default_factory=list)


def reference(
    runs: list[list[Event]], events: tuple[str, ...], max_interval: float, max_events: int
) -> dict[str, dict[str, object]]:
    pairs = {(a, b): _Pair() for a in events for b in events if a != b}
    for stream in runs:
        for pair in pairs.values():
            pair.open = False
        for event, time in stream:
            for (first, second), pair in pairs.items():
                if pair.dropped:
                    continue
                if not pair.open:
                    if event == first:
                        pair.open, pair.since, pair.between = True, time, Counter()
                elif event == second:
                    if time - pair.since > max_interval:
                        pair.dropped = True
                        continue
                    pair.intervals.append((time - pair.since, pair.between))
                    pair.open = False
                else:
                    pair.between[event] += 1
                    if time - pair.since > max_interval or pair.between.total() > max_events:
                        pair.dropped = True
    result: dict[str, dict[str, object]] = {}
    for (first, second), pair in pairs.items():
        if pair.dropped or not pair.intervals:
            continue
        since = 0
        low = high = 0.0
        least: dict[str, int] = {}
        most: dict[str, int] = {}
        for i, (elapsed, between) in enumerate(pair.intervals):
            counts = {e: between[e] for e in events}
            new = (
                (elapsed, elapsed, counts, counts)
                if i == 0
                else (
                    min(low, elapsed),
                    max(high, elapsed),
                    {e: min(least[e], counts[e]) for e in events},
                    {e: max(most[e], counts[e]) for e in events},
                )
            )
            since = 1 if i == 0 or new != (low, high, least, most) else since + 1
            low, high, least, most = new
        result[f"{first} -> {second}"] = {
            "min_time": low,
            "max_time": high,
            "min_events": {e: n for e, n in least.items() if n},
            "max_events": {e: n for e, n in most.items() if n},
            "samples": len(pair.intervals),
            "confidence": confidence(since),
        }
    return result


EVENTS = ("a", "b", "c")
streams = st.lists(
    st.tuples(st.sampled_from(EVENTS), st.sampled_from([0.0, 0.25, 0.5, 1.0, 2.5])), max_size=40
).map(
    lambda steps: [(e, float(sum(d for _, d in steps[: i + 1]))) for i, (e, _) in enumerate(steps)]
)
cut_lists = st.lists(st.integers(0, 40), max_size=4)


def split(stream: list[Event], cuts: list[int]) -> list[list[Event]]:
    points = sorted({min(c, len(stream)) for c in cuts})
    pieces, last = [], 0
    for point in [*points, len(stream)]:
        pieces.append(stream[last:point])
        last = point
    return pieces


@settings(max_examples=80, deadline=None)
@given(
    st.lists(st.tuples(streams, cut_lists), max_size=4),
    st.sampled_from([1.0, 2.0, 5.0]),
    st.sampled_from([1, 3, 10]),
)
def test_fold_equals_merge_equals_reference(
    runs: list[tuple[list[Event], list[int]]], max_interval: float, max_events: int
) -> None:
    folded = IntervalState(EVENTS, max_interval, max_events)
    merged = IntervalState(EVENTS, max_interval, max_events)
    for run, (stream, cuts) in enumerate(runs):
        for piece in split(stream, cuts):
            folded.update(samples(piece, run))
            folded = pickle.loads(pickle.dumps(folded))
        folded.end_run()
        alone = IntervalState(EVENTS, max_interval, max_events)
        alone.update(samples(stream, run))
        merged.merge(pickle.loads(pickle.dumps(alone)))
    for limit in (0.0, 0.99):
        assert folded.finalize(context(limit)) == merged.finalize(context(limit))
    expected = reference([stream for stream, _ in runs], EVENTS, max_interval, max_events)
    found = {
        f"{i.params['first']} -> {i.params['second']}": {
            "min_time": i.params["min_time"],
            "max_time": i.params["max_time"],
            "min_events": i.params["min_events"],
            "max_events": i.params["max_events"],
            "samples": i.samples,
            "confidence": i.confidence,
        }
        for i in folded.finalize(context(0.0))
    }
    assert found == expected
