"""Alarms: persistence, agreement and events, alone and inside the engine."""

from __future__ import annotations

import math

from imrosc.runtime import Engine, Violation
from imrosc.runtime.alarms import EVERY_VIOLATION, AlarmRule, AlarmTracker, margins_of
from tests.runtime.support import alarm_document


def broken(ident: str, time: float, point: str = "p") -> Violation:
    return Violation(time, point, ident, "bounds", "upper", ident, 2.0, "<= 1")


def test_persistence_needs_consecutive_samples() -> None:
    tracker = AlarmTracker(AlarmRule(persist=3))
    assert tracker.sample("p", 0.0, [broken("a", 0.0)]) == []
    assert tracker.sample("p", 0.1, [broken("a", 0.1)]) == []
    assert tracker.sample("p", 0.2, []) == []  # a clean sample ends the episode
    assert tracker.sample("p", 0.3, [broken("a", 0.3)]) == []
    assert tracker.sample("p", 0.4, [broken("a", 0.4)]) == []
    (alarm,) = tracker.sample("p", 0.5, [broken("a", 0.5)])
    assert (alarm.time, alarm.rule, alarm.invariants) == (0.5, "persist", ("a",))
    assert tracker.sample("p", 0.6, [broken("a", 0.6)]) == []  # once per episode
    assert tracker.take() == [alarm]
    assert tracker.take() == []


def test_persistence_by_duration() -> None:
    tracker = AlarmTracker(AlarmRule(persist=100, seconds=1.0))
    assert tracker.sample("p", 0.0, [broken("a", 0.0)]) == []
    assert tracker.sample("p", 0.9, [broken("a", 0.9)]) == []
    assert [a.rule for a in tracker.sample("p", 1.0, [broken("a", 1.0)])] == ["persist"]


def test_other_points_do_not_end_an_episode() -> None:
    tracker = AlarmTracker(AlarmRule(persist=2))
    tracker.sample("p", 0.0, [broken("a", 0.0)])
    tracker.sample("q", 0.05, [])
    assert len(tracker.sample("p", 0.1, [broken("a", 0.1)])) == 1


def test_agreement_of_distinct_invariants_within_the_window() -> None:
    tracker = AlarmTracker(AlarmRule(persist=50, distinct=3, window=1.0))
    assert tracker.sample("p", 0.0, [broken("a", 0.0)]) == []
    assert tracker.sample("p", 0.8, [broken("b", 0.8)]) == []
    assert tracker.sample("p", 1.6, [broken("c", 1.6)]) == []  # "a" left the window
    (alarm,) = tracker.sample("p", 1.7, [broken("d", 1.7)])
    assert alarm.rule == "agree" and alarm.invariants == ("b", "c", "d")
    assert tracker.sample("p", 1.8, [broken("e", 1.8)]) == []  # the same episode
    assert tracker.sample("p", 5.0, []) == []  # the window emptied: the episode ended
    tracker.sample("p", 5.1, [broken("a", 5.1), broken("b", 5.1)])
    assert [a.rule for a in tracker.sample("p", 5.2, [broken("c", 5.2)])] == ["agree"]


def test_an_agreement_of_invariants_already_in_alarm_raises_none() -> None:
    # every violation an alarm: one alarm, not a persistence and an agreement of the same
    tracker = AlarmTracker(AlarmRule(persist=1, distinct=1, window=1.0))
    assert [a.rule for a in tracker.sample("p", 0.0, [broken("a", 0.0)])] == ["persist"]
    assert tracker.sample("p", 0.1, [broken("a", 0.1)]) == []
    # two invariants in alarm by their own persistence, then a third that is not
    tracker = AlarmTracker(AlarmRule(persist=2, distinct=2, window=1.0))
    assert tracker.sample("p", 0.0, [broken("a", 0.0)]) == []
    assert [a.rule for a in tracker.sample("p", 0.1, [broken("a", 0.1), broken("b", 0.1)])] == [
        "persist",
        "agree",
    ]
    tracker = AlarmTracker(AlarmRule(persist=2, distinct=3, window=1.0))
    tracker.sample("p", 0.0, [broken("a", 0.0), broken("b", 0.0)])
    raised = tracker.sample("p", 0.1, [broken("a", 0.1), broken("b", 0.1)])
    assert sorted(a.invariants for a in raised) == [("a",), ("b",)]  # two of three
    (alarm,) = tracker.sample("p", 0.2, [broken("a", 0.2), broken("b", 0.2), broken("c", 0.2)])
    assert (alarm.rule, alarm.invariants) == ("agree", ("a", "b", "c"))  # "c" is new


def test_violations_in_an_alarmed_episode_are_alarmed() -> None:
    tracker = AlarmTracker(AlarmRule(persist=2))
    first = [broken("a", 0.0)]
    tracker.sample("p", 0.0, first)
    assert tracker.alarmed(first, tracker.take()) == []
    second = [broken("a", 0.1), broken("b", 0.1)]
    tracker.sample("p", 0.1, second)
    assert tracker.alarmed(second, tracker.take()) == second[:1]
    third = [broken("a", 0.2)]  # still the alarmed episode, no new alarm
    tracker.sample("p", 0.2, third)
    assert tracker.take() == [] and tracker.alarmed(third, []) == third
    events = [broken("c", 0.3)]
    assert tracker.alarmed(events, tracker.event(events)) == events


def test_agreement_counts_no_polygon_whose_variable_left_its_range() -> None:
    shapes = {"x_range": (True, ("x",)), "xy": (False, ("x", "y")), "yz": (False, ("y", "z"))}
    tracker = AlarmTracker(AlarmRule(persist=50, distinct=2), record=True, shapes=shapes)
    found = [broken("x_range", 0.0), broken("xy", 0.0)]
    assert tracker.evidence(found) == found[:1]
    assert tracker.sample("p", 0.0, found) == []  # one piece of evidence: x out of range
    assert [f[4] for f in tracker.fed] == [True, False]
    (alarm,) = tracker.sample("p", 0.1, [broken("yz", 0.1)])  # a second, independent one
    assert alarm.invariants == ("x_range", "yz")


def test_events_alarm_at_once_and_reset_forgets() -> None:
    tracker = AlarmTracker(AlarmRule(persist=5))
    assert [a.rule for a in tracker.event([broken("a", 1.0)])] == ["event"]
    tracker.sample("p", 0.0, [broken("b", 0.0)])
    assert tracker.busy("p")
    tracker.reset()
    assert not tracker.busy("p") and tracker.take() == []


def test_rule_from_the_file_and_overrides() -> None:
    assert AlarmRule.from_json(None) == EVERY_VIOLATION
    rule = AlarmRule.from_json({"persist": 4, "seconds": None, "distinct": 3, "window": 2.0})
    assert rule == AlarmRule(4, None, 3, 2.0)
    assert rule.overridden(persist=None, distinct=5) == AlarmRule(4, None, 5, 2.0)
    assert AlarmRule.from_json(rule.as_json()) == rule


def test_a_family_of_its_own_persists_by_its_own_rule() -> None:
    rule = AlarmRule(persist=5, seconds=None, families=(("mean", 2, None),))
    tracker = AlarmTracker(rule)
    mean = Violation(0.0, "p", "m", "mean", "range", "mean(x)", 9.0, "[0, 1]")
    for k in range(4):
        found = tracker.sample("p", 0.1 * k, [broken("b", 0.1 * k), mean._replace(time=0.1 * k)])
        assert [a.invariants for a in found] == ([("m",)] if k == 1 else [])
    (alarm,) = tracker.sample("p", 0.4, [broken("b", 0.4)])
    assert alarm.invariants == ("b",)  # the pooled rule: the fifth sample


def test_a_rule_of_families_round_trips_and_an_override_holds_for_every_family() -> None:
    rule = AlarmRule(40, 2.0, 9, 1.0, (("mean", 8, 0.5), ("rate", 3, None)))
    assert rule.as_json()["families"] == {
        "mean": {"persist": 8, "seconds": 0.5},
        "rate": {"persist": 3, "seconds": None},
    }
    assert AlarmRule.from_json(rule.as_json()) == rule
    assert rule.persistence("mean") == (8, 0.5) and rule.persistence("bounds") == (40, 2.0)
    assert rule.overridden(distinct=2).families == rule.families
    assert rule.overridden(persist=3) == AlarmRule(3, 2.0, 9, 1.0)
    assert rule.overridden(seconds=1.0).persistence("mean") == (40, 1.0)


def test_the_engine_raises_alarms_under_the_files_rule() -> None:
    engine = Engine(alarm_document({"persist": 3, "distinct": 2, "window": 0.5}))
    for k, (v, w) in enumerate([(2.0, 0.0), (2.0, 0.0), (0.0, 0.0), (2.0, 0.0), (2.0, 0.0)]):
        assert len(engine.message("/a/x", 0.1 * k, [v, w])) == (v > 1)
    assert engine.take_alarms() == []
    engine.message("/a/x", 0.5, [2.0, 0.0])
    (alarm,) = engine.take_alarms()
    assert (alarm.rule, alarm.invariants) == ("persist", ("v_max",))
    engine.reset()
    engine.message("/a/x", 0.0, [2.0, 2.0])
    assert [a.rule for a in engine.take_alarms()] == ["agree"]


def test_without_a_rule_every_violation_alarms() -> None:
    engine = Engine(alarm_document(None))
    engine.message("/a/x", 0.0, [2.0, 0.0])
    engine.message("/a/x", 0.1, [0.0, 0.0])
    engine.message("/a/x", 0.2, [2.0, 0.0])
    assert [a.time for a in engine.take_alarms()] == [0.0, 0.2]
    strict = Engine(alarm_document(None), rule=AlarmRule(persist=2))
    strict.message("/a/x", 0.0, [2.0, 0.0])
    assert strict.take_alarms() == []


def frozen(time: float, observed: float = 0.0) -> Violation:
    """The variance lower bound of x broken: by 0 (the window's values all equal) or less."""
    return Violation(time, "p", "x_var", "variance", "range", "1e-4 <= var(x)", observed, ">= 1e-4")


def test_a_frozen_variable_alarms_at_the_first_sample_of_its_episode() -> None:
    tracker = AlarmTracker(AlarmRule(persist=100, distinct=2), record=True)
    assert tracker.sample("p", -1.0, [frozen(-1.0, observed=5e-5)]) == []  # a matter of degree
    (alarm,) = tracker.sample("p", 0.1, [frozen(0.1)])
    assert (alarm.rule, alarm.invariants) == ("event", ("x_var",))
    assert "a frozen variable" in alarm.describe()
    later = [frozen(0.2), broken("a", 0.2)]
    assert tracker.sample("p", 0.2, later) == []  # once per episode; not counted by agreement
    assert tracker.alarmed(later, []) == later[:1]  # its samples stay in alarm
    assert [f[2] for f in tracker.fed] == ["x_var", "a"]  # calibration's persistence: not it
    assert tracker.sample("p", 0.3, []) == []  # the variable moves again: the episode ends
    assert [a.rule for a in tracker.sample("p", 0.4, [frozen(0.4)])] == ["event"]


def test_a_detector_alarms_once_per_episode() -> None:
    tracker = AlarmTracker(AlarmRule(persist=100))
    scored = [Violation(t, "p", "d", "detector", "logistic", "d", 3.0, "<= 1") for t in (0, 1)]
    assert [a.rule for a in tracker.sample("p", 0.0, scored[:1])] == ["event"]
    assert tracker.sample("p", 1.0, scored[1:]) == []
    assert tracker.alarmed(scored[1:], []) == scored[1:]


def ranged(ident: str, time: float, observed: float, family: str = "bounds") -> Violation:
    return Violation(time, "p", ident, family, "range", ident, observed, "[0, 1]")


MARGINS = {
    "b": {"id": "b", "family": "bounds", "params": {"margin": {"max": [1.0, 3.0]}}},
    "v": {"id": "v", "family": "variance", "params": {"margin": {"min": [1.0, 0.01]}}},
}


def test_a_severe_violation_alarms_at_once_and_a_mild_one_waits() -> None:
    rule = AlarmRule(persist=50, severe=1.0, severe_families=("bounds", "variance"))
    tracker = AlarmTracker(rule, margins=margins_of(list(MARGINS.values())))
    assert tracker.sample("p", 0.0, [ranged("b", 0.0, 2.9)]) == []  # 0.95 margins out
    (alarm,) = tracker.sample("p", 0.1, [ranged("b", 0.1, 3.5)])
    assert (alarm.rule, alarm.invariants) == ("severe", ("b",))
    assert "a severe violation" in alarm.describe()
    assert tracker.sample("p", 0.2, [ranged("b", 0.2, 4.0)]) == []  # once per episode
    # a variance's margin is in the logarithm: 0.001 is 1.5 margins below 1 towards 0.01
    (alarm,) = tracker.sample("p", 0.3, [ranged("v", 0.3, 0.001, "variance")])
    assert alarm.rule == "severe"
    assert math.isclose(tracker.severity(ranged("v", 0.3, 0.001, "variance")), 1.5)


def test_severe_alarms_follow_the_threshold_and_the_families() -> None:
    margins = margins_of(list(MARGINS.values()))
    off = AlarmTracker(
        AlarmRule(persist=50, severe=0.0, severe_families=("bounds",)), margins=margins
    )
    assert off.sample("p", 0.0, [ranged("b", 0.0, 9.0)]) == []
    assert off.severity(ranged("b", 0.0, 9.0)) == 4.0  # severe, but the rule has them off
    other = AlarmTracker(
        AlarmRule(persist=50, severe=1.0, severe_families=("rate",)), margins=margins
    )
    assert other.sample("p", 0.0, [ranged("b", 0.0, 9.0)]) == []
    higher = AlarmTracker(
        AlarmRule(persist=50, severe=4.0, severe_families=("bounds",)), margins=margins
    )
    assert higher.sample("p", 0.0, [ranged("b", 0.0, 8.0)]) == []  # 3.5 margins
    assert len(higher.sample("p", 0.1, [ranged("b", 0.1, 9.0)])) == 1  # 4 margins


def test_the_rule_carries_its_severe_alarms_through_json() -> None:
    rule = AlarmRule(persist=9, severe=1.0, severe_families=("step", "mean"))
    assert AlarmRule.from_json(rule.as_json()) == rule
    assert "severe" not in AlarmRule(persist=9).as_json()
    assert AlarmRule.from_json(rule.as_json()).overridden(severe=0.0).severe == 0.0


def test_a_moderate_violation_alarms_once_its_severities_sum_to_the_familys_strength() -> None:
    margins = margins_of([{"id": "m", "family": "mean", "params": {"margin": {"max": [1.0, 3.0]}}}])
    rule = AlarmRule(persist=50, severe=1.0, severe_families=("mean",), strength=(("mean", 1.2),))
    tracker = AlarmTracker(rule, margins=margins)
    # 0.5 margins out each: 0.5, 1.0, then 1.5 >= 1.2 at the third sample
    assert tracker.sample("p", 0.0, [ranged("m", 0.0, 2.0, "mean")]) == []
    assert tracker.sample("p", 0.1, [ranged("m", 0.1, 2.0, "mean")]) == []
    (alarm,) = tracker.sample("p", 0.2, [ranged("m", 0.2, 2.0, "mean")])
    assert (alarm.rule, alarm.invariants) == ("summed", ("m",))
    assert "a lasting shift" in alarm.describe()
    # a clean sample ends the episode: the sum starts again
    assert tracker.sample("p", 0.3, []) == []
    assert tracker.sample("p", 0.4, [ranged("m", 0.4, 2.0, "mean")]) == []
    # a family without a strength of its own waits for the persistence
    other = AlarmTracker(rule._replace(strength=(("rate", 0.1),)), margins=margins)
    assert all(other.sample("p", t, [ranged("m", t, 2.9, "mean")]) == [] for t in (0.0, 0.1, 0.2))


def test_the_rule_carries_its_strengths_through_json_and_an_override_drops_them() -> None:
    rule = AlarmRule(persist=9, strength=(("mean", 1.5), ("rate", 2.0)))
    assert AlarmRule.from_json(rule.as_json()) == rule
    assert "strength" not in AlarmRule(persist=9).as_json()
    assert AlarmRule.from_json(rule.as_json()).overridden(persist=3).strength == ()
