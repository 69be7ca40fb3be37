"""The alarm rule from held-out units' figures: pooled, and per window family."""

from __future__ import annotations

from imrosc.calibrate.rule import Figures, alarms_under, covered, rule_for, rule_from
from imrosc.runtime.alarms import AlarmRule


def entry(point: str, family: str, persist: int, lasting: float) -> dict[str, object]:
    return {
        "point": point,
        "family": family,
        "persist": persist,
        "lasting": lasting,
        "evidence": [[0.0, 1.0]],
    }


def test_covered_keeps_each_family_s_longest_episode() -> None:
    trace = {
        "a": entry("p", "mean", 3, 0.2),
        "b": entry("p", "mean", 7, 0.1),
        "c": entry("p", "polygon", 90, 9.0),
    }
    figures = covered(trace, {"a", "b", "c"})
    assert (figures.persist, figures.lasting) == (90, 9.0)
    assert figures.families == {"mean": (7, 0.2), "polygon": (90, 9.0)}
    assert covered(trace, {"a"}).families == {"mean": (3, 0.2)}


def test_a_window_family_gets_its_own_persistence_and_value_families_the_pooled() -> None:
    """A landing broke a polygon for 9 s; window means broke for 0.2 s at most: a mean
    out for 0.3 s alarms, a polygon out for 5 s does not."""
    figures = [
        Figures(90, 9.0, 2, False, {"polygon": (90, 9.0), "mean": (20, 0.2)}),
        Figures(4, 0.05, 1, False, {"bounds": (4, 0.05), "mean": (3, 0.02)}),
        Figures(0, 0.0, 0, False, {}),
    ]
    rule, certified = rule_from(figures, 0.05)
    assert not certified  # three units cannot certify 0.05
    assert (rule.persist, rule.seconds) == (91, 9.001)
    assert rule.families == (("mean", 21, 0.201),)
    assert rule.persistence("polygon") == rule.persistence("bounds") == (91, 9.001)
    assert rule.persistence("variance") == (91, 9.001)  # no unit broke one: pooled
    assert alarms_under(Figures(30, 0.3, 0, False, {"mean": (30, 0.3)}), rule)
    assert not alarms_under(Figures(60, 5.0, 0, False, {"polygon": (60, 5.0)}), rule)
    assert not alarms_under(Figures(20, 0.2, 0, False, {"mean": (20, 0.2)}), rule)
    # a trace without families (an older file) is judged by the pooled rule
    assert not alarms_under(Figures(30, 0.3, 0, False), rule)


def test_every_held_out_unit_passes_the_rule_set_from_them() -> None:
    figures = [
        Figures(12, 0.6, 3, False, {"rate": (12, 0.6), "bounds": (5, 0.1)}),
        Figures(40, 2.5, 1, False, {"mean": (40, 2.5)}),
        Figures(2, 0.01, 4, False, {"frequency": (2, 0.01), "polygon": (1, 0.0)}),
    ]
    rule, _ = rule_from(figures, 0.05)
    assert {name for name, _, _ in rule.families} == {"rate", "mean", "frequency"}
    assert not any(alarms_under(f, rule) for f in figures)


def test_the_rule_of_a_subset_comes_from_the_file_s_traces() -> None:
    units = [
        {"trace": {"m": entry("p", "mean", 5, 0.05), "q": entry("p", "polygon", 50, 5.0)}},
        {"trace": {"m": entry("p", "mean", 9, 0.09)}},
    ]
    document = {"calibration": {"budget": 0.05, "held_out": units}}
    whole = rule_for(document, {"m", "q"})
    only_mean = rule_for(document, {"m"})
    assert whole is not None and only_mean is not None
    assert whole.persistence("mean") == only_mean.persistence("mean") == (10, 0.091)
    assert whole.persist == 51 and only_mean.persist == 10
    assert isinstance(whole, AlarmRule)
