"""Learning fault detectors from good and failed runs (imrosc.detectors)."""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest

from imrosc.detectors import Run, choose, learn, run_of
from imrosc.runtime.detector import Detector

RATE = 20.0
LENGTH = 30.0


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
    return run_of(f"run{seed}", 100.0 * seed, onset, _samples(seed, onset))


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
    assert learnt is not None
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
