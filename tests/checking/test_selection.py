"""imrosc.selection: the set of invariants a monitor keeps (``<check select="cover">``)."""

from __future__ import annotations

import random
from pathlib import Path

import pytest

from imrosc.classify import RunOutcome, monitor_choice, none_kept_message, whole_monitor
from imrosc.selection import Cover, Nominal, Whole, cover, detected_by


def _value(
    chosen: set[str],
    nominal: dict[str, Nominal],
    detects: dict[int, set[str]],
    early: dict[int, set[str]],
    runs: int,
) -> float:
    clean = 1.0
    for ident in chosen:
        clean *= 1.0 - nominal[ident].false_alarm
    return detected_by(chosen, detects, early) - runs * (1.0 - clean)


def test_specialists_are_kept_together() -> None:
    """Each of three invariants detects one fault kind alone (recall 1/3 each, an F-score the
    thesis' filter drops); the union detects them all."""
    nominal = {name: Nominal(40, 0) for name in "abc"}
    detects = {1: {"a"}, 2: {"b"}, 3: {"c"}}
    found = cover(nominal, detects, {}, runs=20)
    assert set(found.chosen) == {"a", "b", "c"} and found.detected == 3
    assert found.false_alarm == pytest.approx(1 - (41 / 42) ** 3)


def test_an_invariant_that_breaks_on_good_runs_costs_more_than_it_detects() -> None:
    nominal = {"noisy": Nominal(10, 5), "quiet": Nominal(10, 0)}
    found = cover(nominal, {1: {"noisy"}, 2: {"noisy", "quiet"}}, {}, runs=6)
    assert found.chosen == ("quiet",)


def test_few_runs_make_an_unbroken_invariant_uncertain() -> None:
    """Unbroken on 2 nominal runs, an invariant breaks a new one with probability 1/4: over
    10 runs that costs 2.5 false alarms, more than the 2 failed runs it detects."""
    assert cover({"a": Nominal(2, 0)}, {1: {"a"}, 2: {"a"}}, {}, runs=10).chosen == ()
    assert cover({"a": Nominal(30, 0)}, {1: {"a"}, 2: {"a"}}, {}, runs=10).chosen == ("a",)


def test_a_break_before_the_onset_spoils_the_detection() -> None:
    nominal = {"early": Nominal(20, 1), "late": Nominal(20, 0)}
    detects = {1: {"early", "late"}}
    early = {1: {"early"}}
    assert detected_by({"early", "late"}, detects, early) == 0
    assert cover(nominal, detects, early, runs=4).chosen == ("late",)


def test_ties_go_to_the_order_given() -> None:
    nominal = {"x": Nominal(50, 0), "y": Nominal(50, 0)}
    detects = {1: {"x", "y"}}
    assert cover(nominal, detects, {}, runs=5, order=["y", "x"]).chosen == ("y",)
    assert cover(nominal, detects, {}, runs=5).chosen == ("x",)


def test_nothing_to_detect_keeps_nothing() -> None:
    assert cover({"a": Nominal(5, 0)}, {1: set()}, {}, runs=3) == Cover((), 0, 0.0, 0.0)


@pytest.mark.parametrize("seed", range(20))
def test_the_greedy_value_is_the_sets_value_and_each_step_adds_worth(seed: int) -> None:
    """The reported value is the objective of the chosen set; each invariant chosen raised
    it, and adding any other would not (greedy stops at a local optimum)."""
    rng = random.Random(seed)
    names = [f"i{k}" for k in range(8)]
    nominal = {n: Nominal(rng.randint(3, 30), 0) for n in names}
    nominal = {n: Nominal(v.tested, rng.randint(0, v.tested // 3)) for n, v in nominal.items()}
    detects = {r: {n for n in names if rng.random() < 0.3} for r in range(6)}
    early = {r: {n for n in names if rng.random() < 0.1} for r in range(6)}
    runs = 6 + rng.randint(2, 10)
    found = cover(nominal, detects, early, runs)
    chosen = set(found.chosen)
    assert found.value == pytest.approx(_value(chosen, nominal, detects, early, runs))
    assert found.value >= 0.0
    for extra in set(names) - chosen:
        assert _value(chosen | {extra}, nominal, detects, early, runs) <= found.value + 1e-9
    prefix = [set(found.chosen[:k]) for k in range(len(found.chosen) + 1)]
    values = [_value(c, nominal, detects, early, runs) for c in prefix]
    assert values == sorted(values) and len(set(values)) == len(values)  # each step adds worth


def test_the_calibrated_inferred_monitor_wins_when_the_cover_costs_more_than_it_detects() -> None:
    """Eight invariants each unbroken on 6 nominal runs (1/8 each) detect one fault each; the
    whole monitor, whose alarm rule held on the same 6 runs, detects seven of them at 1/8:
    worth 7 - 14/8, beyond a standard error (1) of the empty cover's 0."""
    names = "abcdefgh"
    nominal = {name: Nominal(6, 0) for name in names}
    fail = {Path(f"f{k}"): {name} for k, name in enumerate(names)}
    whole = Whole((*names, "z"), frozenset(Path(f"f{k}") for k in range(7)), frozenset(), 6, 0)
    folds = [[run] for run in fail]
    chosen = monitor_choice(nominal, fail, {}, 14, folds, (), set(), whole)
    assert chosen.worth is not None and chosen.worth.name == "inferred"
    assert chosen.chosen == (*names, "z")
    assert chosen.detected == 7 and chosen.false_alarm == pytest.approx(1 / 8)
    assert chosen.value == pytest.approx(7 - 14 / 8)
    assert [w.name for w in chosen.candidates] == ["cover", "inferred", "none"]


def test_a_lead_chance_explains_keeps_the_smaller_monitor() -> None:
    """The whole monitor detects two of three faults, worth 2 - 9/8 against the empty
    cover's 0: a lead of 0.875 where the paired outcomes' standard error is 1 (the
    one-standard-error rule), so the monitor of fewer invariants is kept: the empty cover,
    which is no monitor (named so)."""
    nominal = {name: Nominal(6, 0) for name in "abc"}
    fail = {Path(f"f{k}"): {name} for k, name in enumerate("abc")}
    whole = Whole(("a", "b", "c", "d"), frozenset({Path("f0"), Path("f1")}), frozenset(), 6, 0)
    chosen = monitor_choice(nominal, fail, {}, 9, [[run] for run in fail], (), set(), whole)
    assert chosen.worth is not None and chosen.worth.name == "none" and chosen.chosen == ()
    inferred = next(w for w in chosen.candidates if w.name == "inferred")
    assert inferred.value == pytest.approx(2 - 9 / 8)  # the best worth, not kept
    assert "worth more than none by more than a standard error" in none_kept_message(chosen)
    assert "inferred 0.88" in none_kept_message(chosen)
    # a detector that detects as many: the smaller monitor again, now beyond noise of none
    detector = {**nominal, "d1": Nominal(30, 0, ceiling=0.01)}
    caught = {run: ids | {"d1"} for run, ids in fail.items() if run != Path("f2")}
    caught[Path("f2")] = fail[Path("f2")]
    kept = monitor_choice(detector, caught, {}, 9, [[r] for r in fail], (), {"d1"}, whole)
    assert kept.worth is not None and kept.worth.name == "detector" and kept.chosen == ("d1",)


def test_an_alarm_before_the_onset_spoils_the_whole_monitor_too() -> None:
    nominal = {"a": Nominal(40, 0)}
    fail = {Path("f0"): {"a"}, Path("f1"): {"a"}}
    early = frozenset(fail)  # it alarms on both failed runs before their onsets
    whole = Whole(("a", "b"), frozenset(), early, 40, 0)
    chosen = monitor_choice(nominal, fail, {}, 4, [[r] for r in fail], (), set(), whole)
    assert chosen.worth is not None and chosen.worth.name == "cover"
    inferred = next(w for w in chosen.candidates if w.name == "inferred")
    assert inferred.detected == 0 and inferred.early == 2


def test_the_whole_monitor_and_detectors_detect_together() -> None:
    nominal = {"a": Nominal(30, 0), "d": Nominal(30, 0, ceiling=0.01)}
    fail = {Path("f0"): {"d"}, Path("f1"): set(), Path("f2"): {"a"}}
    whole = Whole(("a",), frozenset({Path("f1")}), frozenset(), 30, 0)
    chosen = monitor_choice(nominal, fail, {}, 33, [[r] for r in fail], (), {"d"}, whole)
    joint = next(w for w in chosen.candidates if w.name == "inferred+detector")
    assert joint.detected == 2  # f0 by the detector, f1 by the whole monitor's alarm
    assert joint.expected == pytest.approx(33 * (1 - (1 - 1 / 32) * (1 - 0.01)))


def test_the_whole_monitor_counts_alarms_of_held_out_units_and_untrained_runs() -> None:
    document = {
        "invariants": [{"id": "i1"}, {"id": "i2"}],
        "alarms": {"persist": 5, "seconds": None, "distinct": 0, "window": 1.0},
        "calibration": {
            "held_out": [
                {"trace": {"i1": {"point": "p", "persist": 4, "evidence": []}}},
                {"trace": {"i2": {"point": "p", "persist": 7, "evidence": []}}},
                {"trace": {}},
            ]
        },
    }
    fail = {
        Path("early"): RunOutcome(Path("early"), None, 0.0, 30.0, onset=10.0),
        Path("late"): RunOutcome(Path("late"), None, 0.0, 30.0, onset=10.0),
        Path("quiet"): RunOutcome(Path("quiet"), None, 0.0, 30.0, onset=10.0),
    }
    fail[Path("early")].alarms = [{"time": 3.0}, {"time": 12.0}]
    fail[Path("late")].alarms = [{"time": 11.0}]
    nominal = [RunOutcome(Path("ok"), None, 0.0, 30.0), RunOutcome(Path("bad"), None, 0.0, 30.0)]
    nominal[1].alarms = [{"time": 4.0}]
    whole = whole_monitor(document, fail, nominal)
    assert whole is not None and whole.chosen == ("i1", "i2")
    assert whole.detected == {Path("late")} and whole.early == {Path("early")}
    # units: i2 persisted 7 >= 5 (an alarm), i1 4 < 5; runs: one alarmed
    assert (whole.tested, whole.alarmed) == (5, 2)
    assert whole_monitor({"invariants": []}, fail, []) is None


def test_held_out_units_alarm_under_the_rule_their_folds_did_not_set() -> None:
    """The file's rule lies past every unit's episode (the longest one's included); each
    unit judged under the rule the other folds' units give, the long one alarms."""
    lengths = [3, 4, 5, 4, 3, 5, 4, 3, 4, 50]
    units = [
        {"trace": {"i1": {"point": "p", "persist": n, "evidence": []}}, "fold": k}
        for k, n in enumerate(lengths)
    ]
    document = {
        "invariants": [{"id": "i1"}],
        "alarms": {"persist": 400},
        "calibration": {"budget": 0.05, "held_out": units},
    }
    whole = whole_monitor(document, {}, [])
    assert whole is not None and (whole.tested, whole.alarmed) == (10, 1)
    for unit in units:
        del unit["fold"]  # a file that does not say: its own rule
    assert whole_monitor(document, {}, []).alarmed == 0  # type: ignore[union-attr]


def test_cross_validated_runs_are_not_counted_twice_with_calibration_s_units() -> None:
    document = {
        "invariants": [{"id": "i1"}],
        "alarms": {"persist": 5},
        "calibration": {"held_out": [{"trace": {}}, {"trace": {}}]},
    }
    replayed = [RunOutcome(Path("cv"), None, 0.0, 10.0)]
    assert whole_monitor(document, {}, replayed).tested == 3  # type: ignore[union-attr]
    assert whole_monitor(document, {}, replayed, units=False).tested == 1  # type: ignore[union-attr]


def test_no_monitor_is_kept_when_every_candidate_is_worth_less_than_none() -> None:
    """The whole monitor alarms before the onsets of two of three faults and detects one
    (worth below 0), and every invariant that detects a fault breaks before the onset of
    another, so the cover, chosen without each fault and judged on it, is worth no more
    than 0: what no monitor is worth (it detects nothing and raises no false alarm). None
    is kept."""
    nominal = {"a": Nominal(6, 0), "b": Nominal(6, 0)}
    fail = {Path("f0"): {"a"}, Path("f1"): {"a", "b"}, Path("f2"): {"b"}}
    early = {Path("f1"): {"a"}, Path("f2"): {"a", "b"}}
    whole = Whole(("a", "b", "c"), frozenset({Path("f0")}), frozenset(fail) - {Path("f0")}, 6, 0)
    chosen = monitor_choice(nominal, fail, early, 9, [[run] for run in fail], (), set(), whole)
    worths = {w.name: w.value for w in chosen.candidates}
    assert worths["inferred"] == pytest.approx(1 - 2 - 9 / 8)
    assert worths["cover"] <= 0.0 and worths["none"] == 0.0
    assert chosen.worth is not None and chosen.worth.name == "none"
    assert chosen.chosen == () and chosen.detected == 0 and chosen.false_alarm == 0.0
    message = none_kept_message(chosen)
    assert "worth more than none on the held-out" in message and "inferred -2.12" in message
