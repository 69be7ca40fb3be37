"""The alarm rule from held-out units' figures: pooled, and per window family."""

from __future__ import annotations

from typing import Any

from imrosc.calibrate.rule import (
    Figures,
    alarms_under,
    covered,
    rule_for,
    rule_from,
    summed_threshold,
    trace_of,
    unseen_alarms,
)
from imrosc.calibrate.tolerance import exponential_bound
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


QUIET = Figures(0, 0.0, 0, False)
"""A held-out unit that broke nothing."""


def test_a_window_family_gets_its_own_persistence_once_the_units_certify_it() -> None:
    """A landing broke a polygon for 9 s; window means broke for 0.2 s at most: with 60
    units a mean out for 0.3 s alarms, a polygon out for 5 s does not."""
    figures = [
        Figures(90, 9.0, 2, False, {"polygon": (90, 9.0), "mean": (20, 0.2)}),
        Figures(4, 0.05, 1, False, {"bounds": (4, 0.05), "mean": (3, 0.02)}),
        *[QUIET] * 58,
    ]
    rule, certified = rule_from(figures, 0.05)
    assert certified
    assert (rule.persist, rule.seconds) == (91, 9.001)
    assert rule.families == (("mean", 21, 0.201),)
    assert rule.persistence("polygon") == rule.persistence("bounds") == (91, 9.001)
    assert rule.persistence("variance") == (91, 9.001)  # no unit broke one: pooled
    assert alarms_under(Figures(30, 0.3, 0, False, {"mean": (30, 0.3)}), rule)
    assert not alarms_under(Figures(60, 5.0, 0, False, {"polygon": (60, 5.0)}), rule)
    assert not alarms_under(Figures(20, 0.2, 0, False, {"mean": (20, 0.2)}), rule)
    # a trace without families (an older file) is judged by the pooled rule
    assert not alarms_under(Figures(30, 0.3, 0, False), rule)


def test_too_few_units_keep_one_pooled_persistence() -> None:
    """Each family's largest episode of a few units would be exceeded by a new run with
    probability up to 1/(n+1) per family: the pooled rule stays."""
    figures = [
        Figures(90, 9.0, 2, False, {"polygon": (90, 9.0), "mean": (20, 0.2)}),
        Figures(4, 0.05, 1, False, {"bounds": (4, 0.05), "mean": (3, 0.02)}),
        *[QUIET] * 20,
    ]
    rule, certified = rule_from(figures, 0.05)
    assert not certified and rule.families == ()
    assert not alarms_under(Figures(30, 0.3, 0, False, {"mean": (30, 0.3)}), rule)


def test_each_family_shares_the_budget_of_persistence() -> None:
    """Two window families: each at budget/6, which 60 units do not certify, 120 do."""
    two = [Figures(12, 0.6, 3, False, {"rate": (12, 0.6), "mean": (40, 2.5)})]
    assert rule_from(two + [QUIET] * 59, 0.05)[0].families == ()
    rule, _ = rule_from(two + [QUIET] * 119, 0.05)
    assert rule.families == (("mean", 41, 2.501), ("rate", 13, 0.601))
    # the pooled rank (budget/3) lies below the one unit that broke anything
    assert (rule.persist, rule.distinct) == (1, 1)


def test_the_rule_of_a_subset_comes_from_the_file_s_traces() -> None:
    units = [
        {"trace": {"m": entry("p", "mean", 5, 0.05), "q": entry("p", "polygon", 50, 5.0)}},
        {"trace": {"m": entry("p", "mean", 9, 0.09)}},
        *[{"trace": {}}] * 58,
    ]
    document = {"calibration": {"budget": 0.05, "held_out": units}}
    whole = rule_for(document, {"m", "q"})
    only_mean = rule_for(document, {"m"})
    assert whole is not None and only_mean is not None
    assert whole.persistence("mean") == only_mean.persistence("mean") == (10, 0.091)
    assert whole.persist == 51 and only_mean.persist == 10
    assert isinstance(whole, AlarmRule)


def test_too_few_units_set_the_rule_past_a_prediction_bound_of_one_more() -> None:
    """Six units cannot certify the budget by rank: the rule lies past the prediction bound
    of one more unit's figures, normal or log-normal whichever reaches further (the maxima
    are non-negative and skewed: 0 to 11 invariants, 0 to 762 samples), so a new
    run that goes a little beyond every unit seen (a landing harder than the training
    flight's) raises no alarm; a fault far beyond them still does."""
    distinct = [0, 4, 1, 1, 7, 11]  # Crazyflie sine_1's six segments, largest agreements
    persist = [0, 193, 83, 1, 762, 92]
    lasting = [0.0, 1.91, 0.82, 0.0, 15.19, 1.81]
    figures = [Figures(p, s, d, False) for p, s, d in zip(persist, lasting, distinct, strict=True)]
    rule, certified = rule_from(figures, 0.05)
    assert not certified
    assert rule.distinct == 46  # the largest seen is 11: the first rule alarmed at 12, the
    # normal bound alone at 18
    assert rule.seconds is not None
    assert rule.persist > max(persist) + 1 and rule.seconds > max(lasting)
    assert not alarms_under(Figures(0, 0.0, 12, False), rule)
    assert alarms_under(Figures(0, 0.0, 60, False), rule)
    # units that all agree still leave room for one more count (the counts' resolution)
    same, _ = rule_from([Figures(5, 0.5, 3, False)] * 6, 0.05)
    assert same.distinct >= 4 and same.persist >= 6


def test_a_skewed_agreement_is_bounded_past_a_new_session() -> None:
    """Held-out ALFA flights' largest agreements (fold 0 of ``bench/efficacy.py``: 16 runs,
    one of them at 21 invariants, most under 8) are right-skewed. The normal bound of one
    more flight fell below their largest, so the rule asked for 22 invariants (just past the
    largest), and two flights of a session none of them came from broke 24 and 28 at
    take-off. The bound taken in ``log(1 + d)`` as well reaches further: 24."""
    from imrosc.calibrate.tolerance import prediction_bound

    distinct = [8, 0, 21, 3, 2, 1, 1, 7, 3, 0, 2, 0, 2, 6, 8, 4]
    figures = [Figures(0, 0.0, d, False) for d in distinct]
    normal = prediction_bound([d + 1 for d in distinct], 0.05 / 3, 1.0)
    assert normal is not None and normal < 22  # the old rule: just past the largest, 21
    rule, certified = rule_from(figures, 0.05)
    assert not certified
    assert rule.distinct == 24
    assert not alarms_under(Figures(0, 0.0, 23, False), rule)
    assert alarms_under(Figures(0, 0.0, 24, False), rule)


def test_a_window_family_s_summed_severity_gets_its_own_bound() -> None:
    """Units whose window means left their envelopes by a few hundredths of a margin for
    some samples: a mean out by half a margin for a second alarms, a polygon out for as
    long does not (it has no margins), and the share of persistence shrinks."""
    figures = [
        Figures(40, 0.4, 1, False, {"mean": (40, 0.4)}, {"mean": 1.2}),
        Figures(30, 0.3, 1, False, {"mean": (30, 0.3)}, {"mean": 0.8}),
        Figures(90, 9.0, 1, False, {"polygon": (90, 9.0)}),
        *[QUIET] * 3,
    ]
    rule, certified = rule_from(figures, 0.05)
    assert not certified
    ((name, summed),) = rule.strength
    assert name == "mean" and 1.2 < summed < 100
    assert alarms_under(Figures(100, 1.0, 0, False, {"mean": (100, 1.0)}, {"mean": 50.0}), rule)
    assert not alarms_under(Figures(100, 1.0, 0, False, {"polygon": (100, 1.0)}), rule)
    without, _ = rule_from([f._replace(strength={}) for f in figures], 0.05)
    assert without.strength == () and without.persist < rule.persist


def test_covered_keeps_the_largest_summed_severity_of_the_window_means_only() -> None:
    """A window mean estimates a level, whose shift the summed severity tests; a variance
    (spread), a rate (slope), a step (one sample) or a range of values does not."""
    trace = {
        "a": dict(entry("p", "mean", 3, 0.2), strength=0.5),
        "b": dict(entry("p", "mean", 7, 0.1), strength=2.0),
        "c": dict(entry("p", "bounds", 90, 9.0), strength=80.0),
        "d": dict(entry("p", "variance", 40, 4.0), strength=30.0),
        "e": dict(entry("p", "rate", 40, 4.0), strength=30.0),
        "f": dict(entry("p", "step", 1, 0.0), strength=3.0),
    }
    assert covered(trace, set(trace)).strength == {"mean": 2.0}
    assert covered(trace, {"a"}).strength == {"mean": 0.5}
    assert covered(trace, {"c", "d", "e", "f"}).strength == {}


def test_the_summed_threshold_is_the_exponential_bound_of_one_more_unit_s_sum() -> None:
    """Crazyflie's six segments (both flights): three summed nothing of a window mean, three
    5 to 11 margins. The threshold lies within the exponential tail, not the log-normal
    one's hundreds, and past every unit's sum."""
    sums = [0.0, 0.0, 11.22, 0.0, 5.87, 5.41]
    share = 0.05 / 4 / 2
    found = summed_threshold(sums, share)
    assert found == exponential_bound(sums, share)
    assert 11.22 < found < 40
    units = [Figures(0, 0.0, 0, False, {}, {"mean": s} if s else {}) for s in sums]
    rule, _ = rule_from(units, 0.05, 4)
    assert rule.strength == (("mean", found),)
    assert summed_threshold([3.0, 0.0], 0.5) == 3.0  # never below the largest sum


def test_a_trace_sums_each_episode_s_severities_and_keeps_the_largest_sum() -> None:
    fed = [
        (0.0, "p", "m", 1, True, 0.0, "mean", 0.5),
        (0.1, "p", "m", 2, True, 0.1, "mean", 0.5),
        (0.2, "p", "m", 3, True, 0.2, "mean", 0.25),
        (0.5, "p", "m", 1, True, 0.0, "mean", 0.75),  # a new episode: the sum starts again
        (0.6, "p", "m", 2, True, 0.1, "mean", 0.5),
        (0.7, "p", "q", 1, True, 0.0, "polygon", 0.0),
    ]
    trace = trace_of(fed, [], 1.0)
    assert trace["m"]["strength"] == 1.25 and trace["m"]["severity"] == 0.75
    assert "strength" not in trace["q"]


def test_a_unit_alarms_under_the_rule_its_fold_did_not_set() -> None:
    """Ten folds of alike units and one unit whose episode is ten times longer: the file's
    rule, set from every unit, lies past it, so it does not alarm there; the rule of the
    other folds' units does not, and a run like it, new, would alarm."""
    lengths = [3, 4, 5, 4, 3, 5, 4, 3, 4, 50]
    traces = [{"a": entry("p", "bounds", n, n / 10)} for n in lengths]
    units: list[dict[str, Any]] = [{"trace": t, "fold": k} for k, t in enumerate(traces)]
    own, _ = rule_from([covered(t, {"a"}) for t in traces], 0.05)
    document = {"alarms": own.as_json(), "calibration": {"budget": 0.05, "held_out": units}}
    assert not any(alarms_under(covered(t, {"a"}), own) for t in traces)
    assert unseen_alarms(document, {"a"}) == [False] * 9 + [True]
    # kept without the invariant, nothing alarms; without folds, nothing says which
    assert unseen_alarms(document, set()) == [False] * 10
    for unit in units:
        del unit["fold"]
    assert unseen_alarms(document, {"a"}) is None


def test_a_severe_violation_alarms_only_in_a_family_the_file_alarms_at_once_on() -> None:
    units = [{"trace": {}, "fold": k, "severe": ["step"] if k == 0 else []} for k in range(6)]
    calibration = {"budget": 0.05, "held_out": units, "severe": {"families": ["bounds"]}}
    document = {
        "alarms": {"severe": 1.0, "severe_families": ["bounds"]},
        "calibration": calibration,
    }
    assert unseen_alarms(document, set()) == [False] * 6
    document["alarms"] = {"severe": 1.0, "severe_families": ["bounds", "step"]}
    assert unseen_alarms(document, set()) == [True] + [False] * 5
