"""Learning fault detectors from good and failed runs (imrosc.detectors)."""

from __future__ import annotations

import dataclasses
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from imrosc import classify, detectors
from imrosc.classify import RunOutcome
from imrosc.detectors import Choice, Learnt, Refused, Run, Sampled, choose, learn, run_of
from imrosc.runtime.detector import Detector

RATE = 20.0
LENGTH = 30.0


def _sampled(samples: list[tuple[float, Any]]) -> Sampled:
    """Samples ``(time, values)`` as classification collects them."""
    return Sampled(np.array([t for t, _ in samples]), np.array([v for _, v in samples]))


def _samples(seed: int, onset: float | None) -> list[tuple[float, Any]]:
    """Two noisy variables at 20 Hz; from ``onset`` on the first one shakes (its spread
    triples), as a loose actuator would."""
    rng = np.random.default_rng(seed)
    found = []
    for k in range(int(LENGTH * RATE)):
        t = 100.0 * seed + k / RATE
        spread = 3.0 if onset is not None and k / RATE >= onset else 1.0
        found.append((t, np.array([rng.normal(0.0, spread), rng.normal(2.0, 1.0)])))
    return found


def _run(seed: int, onset: float | None) -> Run:
    return run_of(f"run{seed}", 100.0 * seed, onset, _sampled(_samples(seed, onset)))


@pytest.fixture(scope="module")
def runs() -> list[Run]:
    return [_run(seed, None) for seed in range(1, 5)] + [_run(seed, 12.0) for seed in range(5, 11)]


def test_no_failed_run_no_detector() -> None:
    assert learn("p", ["x", "y"], [_run(1, None), _run(2, None)]) is None


def test_held_out_failed_runs_are_detected_after_their_onset(runs: list[Run]) -> None:
    choice = choose(runs)
    assert choice is not None
    assert len(choice.detected) >= 4  # of the 6 failed runs, each scored held out
    assert all(0.0 <= delay < 5.0 for delay in choice.delays.values())
    assert choice.nominal == len(runs)  # every run has nominal samples


def test_the_learnt_detector_checks_new_runs_as_it_was_learnt(runs: list[Run]) -> None:
    learnt = learn("p", ["x", "y"], runs)
    assert isinstance(learnt, Learnt)
    invariant = learnt.invariant
    assert invariant["family"] == "detector" and invariant["variables"] == ["x", "y"]
    assert invariant["params"]["threshold"] == learnt.choice.threshold

    def first_alarm(samples: list[tuple[float, Any]]) -> float | None:
        detector = Detector(invariant, {"x": 0, "y": 1})
        for t, row in samples:
            if detector.sample(t, row) is not None:
                return t
        return None

    quiet = [first_alarm(_samples(seed, None)) for seed in range(20, 24)]
    assert quiet.count(None) >= 3  # the threshold is the largest held-out nominal score
    faulty = [first_alarm(_samples(seed, 10.0)) for seed in range(30, 34)]
    found = [t - 100.0 * seed for t, seed in zip(faulty, range(30, 34), strict=True) if t]
    assert len(found) >= 3 and all(t >= 10.0 for t in found)


def _spiky(seed: int, onset: float | None) -> list[tuple[float, Any]]:
    """One noisy variable at 20 Hz. A good run has a moment that passes: two samples of 8
    at a random time. From ``onset`` on, a failed run's variable drifts 0.6 up and stays."""
    rng = np.random.default_rng(seed)
    spike = int(rng.integers(40, int(LENGTH * RATE) - 40))
    found = []
    for k in range(int(LENGTH * RATE)):
        value = rng.normal(0.0, 1.0)
        if k in (spike, spike + 1):
            value = 8.0
        if onset is not None and k / RATE >= onset:
            value += 0.6
        found.append((100.0 * seed + k / RATE, np.array([value])))
    return found


def test_the_evidence_of_a_lasting_fault_outweighs_a_good_run_s_passing_moment(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    runs = [run_of(f"r{s}", 100.0 * s, None, _sampled(_spiky(s, None))) for s in range(1, 7)]
    runs += [run_of(f"r{s}", 100.0 * s, 15.0, _sampled(_spiky(s, 15.0))) for s in range(7, 13)]
    smoothed = choose(runs)
    assert smoothed is not None and smoothed.smooth > 0.0
    assert len(smoothed.detected) >= 5  # of the 6 failed runs, each scored held out
    assert all(0.0 <= delay <= 4.0 + 1.0 for delay in smoothed.delays.values())
    learnt = learn("p", ["x"], runs)
    assert isinstance(learnt, Learnt) and learnt.invariant["params"]["smooth"] == smoothed.smooth
    assert f"mean score over {smoothed.smooth:g} s" in learnt.invariant["text"]
    monkeypatch.setattr(detectors, "SMOOTHING", (0.0,))  # each sample's own score
    instant = choose(runs)

    def mean_delay(choice: Choice) -> float:
        return sum(choice.delays.values()) / len(choice.delays)

    # each sample's own score must wait for the passing moments' level: later, or never
    assert instant is None or (
        len(instant.detected) < len(smoothed.detected)
        or mean_delay(instant) > mean_delay(smoothed) + 0.5
    )


def test_a_smaller_share_of_the_budget_never_lowers_the_threshold(runs: list[Run]) -> None:
    extremes = [0.5, 1.0, 1.5, 2.0, 4.0]
    assert detectors.threshold_of(extremes, 1.0) == 4.0  # the largest held-out value
    assert detectors.threshold_of(extremes, 0.3) == 4.0  # the bound lies lower
    assert detectors.threshold_of(extremes, 0.05) > 4.0  # a twentieth per run: beyond
    tight = detectors.threshold_of(extremes, 0.001)
    assert tight > 4.0  # a thousandth per run: beyond what five runs reached
    assert detectors.threshold_of([2.0, 2.0], 0.001) == 2.0  # no spread, nothing to add
    assert detectors.threshold_of(extremes, 0.0) == 4.0  # a budget of 0: calibration off
    loose, strict = choose(runs), choose(runs, 0.0005)
    assert loose is not None
    assert loose.false_alarm == pytest.approx(1 / (loose.nominal + 1))  # the largest's rank
    assert strict is None or strict.threshold >= loose.threshold
    if strict is not None:
        assert strict.false_alarm == pytest.approx(0.0005)  # the share, below 1/(n+1)


def _outcome(seed: int, onset: float | None, points: tuple[str, ...]) -> RunOutcome:
    sampled = _sampled(_samples(seed, onset))
    return RunOutcome(
        Path(f"run{seed}.bag"),
        start=100.0 * seed,
        onset=onset,
        samples=dict.fromkeys(points, sampled),
    )


def test_the_detectors_of_a_document_share_its_false_alarm_budget(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """Each of ``m`` detectors is set at ``budget / m`` (Bonferroni), so that a monitor of
    several detectors keeps the budget per run."""
    shares: list[float] = []
    learnt = detectors.learn

    def spy(key: str, variables: Any, runs: Any, alpha: float = 1.0) -> Any:
        shares.append(alpha)
        return learnt(key, variables, runs, alpha)

    monkeypatch.setattr(classify, "learn", spy)
    point = {
        "kind": "publish",
        "variables": [{"name": "x", "type": "float"}, {"name": "y", "type": "float"}],
    }
    for names in (("p",), ("p", "q", "r", "s")):
        shares.clear()
        document = {"points": dict.fromkeys(names, point), "calibration": {"budget": 0.08}}
        success = {o.bag: o for o in (_outcome(s, None, names) for s in range(1, 5))}
        failed = {o.bag: o for o in (_outcome(s, 12.0, names) for s in range(5, 11))}
        found, _ = classify.learn_detectors(document, success, failed)
        assert shares == [pytest.approx(0.08 / len(names))] * len(names)
        assert {d.invariant["point"] for d in found} <= set(names)


def test_a_detector_whose_held_out_detections_chance_explains_is_refused(
    runs: list[Run],
) -> None:
    """A failed run's largest evidence, were the detector blind to faults, would be one more
    draw beside the ``n`` held-out nominal extremes: above them all with probability
    ``1/(n+1)``. A detector is kept only when chance explains its held-out detections at
    most as often as its share of the budget allows."""
    assert detectors.binomial_tail(2, 7, 1 / 14) == pytest.approx(0.0842, abs=1e-4)
    assert detectors.binomial_tail(0, 7, 0.5) == 1.0 and detectors.binomial_tail(8, 7, 0.5) == 0
    # a lasting fault: most held-out failed runs detected, far beyond chance
    strong = choose(runs, 0.05)
    assert strong is not None and strong.failed == 6 and strong.tried == 30
    assert strong.prompt == len(strong.detected)  # each soon after its onset
    assert strong.chance <= 0.05 and strong.separates
    assert isinstance(learn("p", ["x", "y"], runs, 0.05), Learnt)
    # "failed" runs that are not: an onset with no fault after it
    blind = [_run(seed, None) for seed in range(1, 5)]
    blind += [run_of(f"run{s}", 100.0 * s, 12.0, _sampled(_samples(s, None))) for s in range(5, 11)]
    found = choose(blind, 0.05)
    assert found is not None and found.detected  # the best of 30 pairs "detects" some
    # by chance, most of them long after the onset, where a failed run's stretch is longer
    # than the shortest nominal one and its largest evidence no fair draw beside them
    assert found.horizon < 12.0 and found.prompt < len(found.detected)
    assert found.chance > 0.05 and not found.separates
    refused = learn("p", ["x", "y"], blind, 0.05)
    assert isinstance(refused, Refused) and refused.point == "p"
    # with no share asked (1: calibration's budget off) a detection is kept as before
    one = Choice(1.0, 0.0, 1.0, frozenset({"r"}), {"r": 0.5}, 13, 1.0, 7, 30, horizon=9.0)
    assert one.chance == pytest.approx(1 - (13 / 14) ** 7) and one.separates
    assert not dataclasses.replace(one, alpha=0.0125).separates


def test_classification_reports_the_refused_detectors(monkeypatch: pytest.MonkeyPatch) -> None:
    point = {
        "kind": "publish",
        "variables": [{"name": "x", "type": "float"}, {"name": "y", "type": "float"}],
    }
    document = {"points": {"p": point}, "calibration": {"budget": 0.05}}
    success = {o.bag: o for o in (_outcome(s, None, ("p",)) for s in range(1, 5))}
    failed = {o.bag: o for o in (_outcome(s, 12.0, ("p",)) for s in range(5, 11))}
    blind = Choice(1.0, 0.0, 1.0, frozenset({"run5.bag"}), {"run5.bag": 0.5}, 10, 0.05, 6, 30)
    monkeypatch.setattr(detectors, "choose", lambda runs, alpha=1.0: blind)
    found, refused = classify.learn_detectors(document, success, failed)
    assert found == [] and [r.point for r in refused] == ["p"]
    entry = classify.refused_entry(refused[0])
    assert entry["held_out_failed"] == 6 and entry["detected"] == ["run5.bag"]
    assert entry["chance"] == pytest.approx(1 - (10 / 11) ** 6)
