"""imrosc.selection: the set of invariants a monitor keeps (``<check select="cover">``)."""

from __future__ import annotations

import random

import pytest

from imrosc.selection import Cover, Nominal, cover, detected_by


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
