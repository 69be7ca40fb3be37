"""Pattern invariants with multi-pointer DFAs (thesis 3.4.4.2, Algorithms 9 and 12)."""

from __future__ import annotations

import pickle

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from imrosc.infer.core import Invariant
from imrosc.infer.temporal import (
    PatternState,
    compile_pattern,
    dfa_from_json,
    make_temporal_states,
)
from imrosc.infer.temporal import pattern as pattern_module
from imrosc.schema.pattern import PatternError
from tests.infer.temporal.helpers import Event, concrete, context, samples, trace

Patterns = list[tuple[str, list[tuple[dict[str, str], str]]]]


def infer(
    runs: list[list[Event]], events: tuple[str, ...], patterns: Patterns, limit: float = 0.99
) -> dict[str, Invariant]:
    state = PatternState(events, patterns)
    for run, stream in enumerate(runs):
        state.update(samples(stream, run))
        state.end_run()
    return {inv.text: inv for inv in state.finalize(context(limit))}


def test_figure_3_14_partial_trace_finds_aab_star() -> None:
    # The system ran "AABAAB..." but recording started one event late: "ABAAB...".
    events = ("a", "b")
    patterns = [concrete("(AAB)*", events), concrete("(AB)*", events)]
    assert [text for _, bound in patterns for _, text in bound] == [
        "(aab)*",
        "(bba)*",
        "(ab)*",
        "(ba)*",
    ]
    found = infer([trace("ab" + "aab" * 4)], events, patterns)
    assert list(found) == ["(aab)*"]
    inv = found["(aab)*"]
    assert inv.family == "pattern"
    assert inv.kind == "pattern"
    assert inv.variables == ("event",)
    assert inv.samples == 14
    assert inv.params == {
        "pattern": "(aab)*",
        "general": "(AAB)*",
        "binding": {"A": "a", "B": "b"},
        "alphabet": ["a", "b"],
        "states": 3,
        "start": 0,
        "transitions": {"0": {"a": 1}, "1": {"a": 2}, "2": {"b": 0}},
        "accepting": [0],
    }


def test_a_plain_dfa_from_its_start_would_miss_it() -> None:
    dfa = compile_pattern("(aab)*", ("a", "b"))
    table = dfa.table()
    state: int | None = 0
    for event in "abaab":
        state = table[state].get(event) if state is not None else None
    assert state is None


def test_scan_sync_pattern_of_section_5_3() -> None:
    events = ("scan", "obs_imu", "scan_sync")
    patterns = [concrete("((A|B)+C)*", events)]
    assert patterns[0][1][0][1] == "((<scan>|<obs_imu>)+<scan_sync>)*"
    s, o, y = events
    # Each scan_sync follows at least one scan or obs_imu; scan and obs_imu repeat, so the
    # patterns ending in scan or in obs_imu die.
    order = [s, o, y, o, o, y, s, s, y, s, o, y, o, s, y]
    stream = [(e, 0.1 * i) for i, e in enumerate(order * 2)]
    found = infer([stream], events, patterns)
    assert sorted(found) == [
        "((<obs_imu>|<scan>)+<scan_sync>)*",
        "((<scan>|<obs_imu>)+<scan_sync>)*",
    ]
    # Table 5.5: the recorder saw consecutive scan_sync messages, which break the pattern.
    late = [(e, 10 + 0.1 * i) for i, e in enumerate([s, o, y, y, s, y])]
    assert infer([stream, late], events, patterns) == {}


def test_events_outside_the_alphabet_pass_the_machine_by() -> None:
    # Figure 3.9: (AB)* over a, b, c finds (ac)* and (ca)* although b happens too.
    events = ("a", "b", "c")
    found = infer([trace("abcbacbbacac")], events, [concrete("(AB)*", events)])
    assert sorted(found) == ["(ac)*", "(ca)*"]


def test_a_machine_that_cannot_die_is_vacuous() -> None:
    events = ("a", "b")
    found = infer([trace("abab" * 4)], events, [concrete("(A|B)*", events), concrete("A*", events)])
    assert found == {}


def test_evidence_needs_one_pointer_around_all_states() -> None:
    events = ("a", "b", "c")
    # States: 0 (start), 1 (after a), 2 (after ab). Runs of a lone "a" visit two of them.
    patterns: Patterns = [("(abc)*", [({}, "(abc)*")])]
    assert infer([trace("a")] * 8, events, patterns, limit=0.0) == {}
    assert list(infer([trace("a")] * 8 + [trace("ab")], events, patterns, limit=0.0)) == ["(abc)*"]
    # A dead machine is not reported, whatever its pointers visited before dying.
    assert infer([trace("abcb")], events, patterns, limit=0.0) == {}
    assert list(infer([trace("cab")], events, patterns, limit=0.0)) == ["(abc)*"]


def test_survival_is_needed_in_every_run() -> None:
    events = ("a", "b")
    patterns = [concrete("(AB)*", events)]
    assert list(infer([trace("abab" * 3)], events, patterns)) == ["(ab)*", "(ba)*"]
    assert infer([trace("abab" * 3), trace("aa")], events, patterns) == {}


def test_justification_counts_driving_events() -> None:
    events = ("a", "b")
    patterns = [concrete("(AB)*", events)]
    assert infer([trace("abab")], events, patterns) == {}
    assert infer([trace("abab")], events, patterns, limit=0.9)["(ab)*"].samples == 4


def test_multi_letter_ids_and_errors() -> None:
    dfa = compile_pattern("(<land>b)*", ("land", "b"))
    assert dfa.alphabet == ("land", "b")
    assert dfa_from_json(dfa.to_json()) == dfa
    with pytest.raises(ValueError, match="outside the scope"):
        compile_pattern("(<fly>b)*", ("land", "b"))
    with pytest.raises(ValueError, match="placeholder 'A'"):
        compile_pattern("(Ab)*", ("a", "b"))
    with pytest.raises(PatternError):
        compile_pattern("(ab", ("a", "b"))
    state = PatternState(("a", "b"), [concrete("(AB)*", ("a", "b"))])
    with pytest.raises(ValueError, match="not among"):
        state.update(samples([("z", 0.0)]))


def test_minimal_dfa_is_canonical() -> None:
    events = ("a", "b", "c")
    assert compile_pattern("((a|b)+c)*", events) == compile_pattern("(-|(a|b)(a|b)*c)+", events)
    assert compile_pattern("((a|b)+c)*", events).states == 2
    assert compile_pattern("(ab)*", events) != compile_pattern("(ba)*", events)


def test_make_temporal_states_builds_pattern_state() -> None:
    events = ("a", "b")
    states = make_temporal_states(
        events, [concrete("(AB)*", events)], 2.0, 10, frozenset({"interval", "pattern"})
    )
    assert [s.family for s in states] == ["interval", "pattern"]
    only = make_temporal_states(events, [("-", [({}, "-")])], 2.0, 10, frozenset({"pattern"}))
    assert only == []


# -- properties --------------------------------------------------------------------------------

EVENTS = ("a", "b", "c")
PATTERNS: Patterns = [
    concrete("(AB)*", EVENTS),
    concrete("(AAB)*", EVENTS),
    concrete("((A|B)+C)*", EVENTS),
    ("ab*|c", [({}, "ab*|c")]),
]


def reference(runs: list[str], text: str) -> tuple[bool, bool, int]:
    """Algorithm 9 literally: one pointer per starting state with its visited states."""
    dfa = compile_pattern(text, EVENTS)
    table = dfa.table()
    alive, evidence, driven = True, False, 0
    for run in runs:
        pointers: dict[int, tuple[int, frozenset[int]]] = {
            s: (s, frozenset((s,))) for s in dfa.all_states()
        }
        for event in run:
            if event not in dfa.alphabet:
                continue
            driven += 1
            pointers = {
                start: (table[state][event], visited | {table[state][event]})
                for start, (state, visited) in pointers.items()
                if event in table[state]
            }
            if not pointers:
                return False, evidence, driven
        if any(len(visited) == dfa.states for _, visited in pointers.values()):
            evidence = True
    return alive, evidence, driven


def split(stream: str, cuts: list[int]) -> list[str]:
    points = sorted({min(c, len(stream)) for c in cuts})
    pieces, last = [], 0
    for point in [*points, len(stream)]:
        pieces.append(stream[last:point])
        last = point
    return pieces


def biased_runs() -> st.SearchStrategy[str]:
    """Mostly pattern-like streams, so that machines survive often enough."""
    words = st.sampled_from(["ab", "aab", "ac", "bc", "abc", "c", "ba"])
    return st.lists(words, max_size=8).map("".join) | st.text("abc", max_size=12)


@settings(max_examples=80, deadline=None)
@given(st.lists(st.tuples(biased_runs(), st.lists(st.integers(0, 20), max_size=3)), max_size=4))
def test_fold_equals_merge_equals_reference(runs: list[tuple[str, list[int]]]) -> None:
    folded = PatternState(EVENTS, PATTERNS)
    merged = PatternState(EVENTS, PATTERNS)
    for run, (stream, cuts) in enumerate(runs):
        start = 0.0
        for piece in split(stream, cuts):
            folded.update(samples(trace(piece, start=start), run))
            start += len(piece)
            folded = pickle.loads(pickle.dumps(folded))
        folded.end_run()
        alone = PatternState(EVENTS, PATTERNS)
        alone.update(samples(trace(stream), run))
        merged.merge(pickle.loads(pickle.dumps(alone)))
    for limit in (0.0, 0.99):
        assert folded.finalize(context(limit)) == merged.finalize(context(limit))
    reported = {inv.text for inv in folded.finalize(context(0.0))}
    for machine in folded.machines:
        alive, evidence, driven = reference([stream for stream, _ in runs], machine.text)
        expected = alive and evidence and driven > 0 and machine.dfa.can_die()
        assert (machine.text in reported) == expected, machine.text


def test_memo_reset_changes_nothing(monkeypatch: pytest.MonkeyPatch) -> None:
    events = ("a", "b", "c")
    patterns = [concrete("(AAB)*", events), concrete("((A|B)+C)*", events)]
    runs = [trace("baab" + "aab" * 5 + "c"), trace("abcabc" * 3)]
    expected = infer(runs, events, patterns, limit=0.0)
    monkeypatch.setattr(pattern_module, "_MEMO_LIMIT", 2)
    assert infer(runs, events, patterns, limit=0.0) == expected
    assert expected
