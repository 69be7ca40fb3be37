"""Fault detection (thesis 5.1): each scenario class injected into a nominal run is found by
replay with the family expected to see it.

Invariants are inferred from nominal runs of the embedded landing system. Each faulty bag is
a copy of one of those very runs (same seed) with the fault from 10 s on, so the run
without the fault replays with no violation at all and every violation of the faulty copy
comes from the fault.
"""

from __future__ import annotations

import shutil
from pathlib import Path
from typing import Any

import pytest

from imrosc.demo import example_configs
from imrosc.detect import run_detect
from imrosc.replay import replay
from imrosc.sim import FAMILIES, SCENARIO_KINDS, Scenario, write_run, write_runs

START = 10.0


@pytest.fixture(scope="module")
def learnt(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, dict[str, Any]]:
    out = tmp_path_factory.mktemp("faults")
    source = next(p for p in example_configs() if p.name == "landing_sim.xml")
    shutil.copyfile(source, out / "landing_sim.xml")
    write_runs(out / "bags" / "nominal", runs=4, seed=0, fmt="ros1")
    result = run_detect(out / "landing_sim.xml", workers=2)
    assert result.document is not None, [d.as_text() for d in result.diagnostics]
    return out, result.document


def test_the_nominal_runs_replay_without_violations(learnt: tuple[Path, dict[str, Any]]) -> None:
    out, document = learnt
    runs = replay(document, sorted((out / "bags" / "nominal").glob("*.bag")))
    assert [r.violations for r in runs] == [[]] * 4
    assert all(r.messages > 5000 and r.error is None for r in runs)


@pytest.mark.parametrize("kind", SCENARIO_KINDS)
def test_each_fault_is_found_by_its_family(learnt: tuple[Path, dict[str, Any]], kind: Any) -> None:
    out, document = learnt
    bag = write_run(
        out / "bags" / "fail" / f"{kind}.bag",
        seed=1,
        fmt="ros1",
        scenario=Scenario(kind, start=START),
    )
    (run,) = replay(document, [bag])
    assert run.error is None
    families = {v.family for v in run.violations}
    expected = set(FAMILIES[kind])
    assert families & expected, f"{kind}: found {sorted(families)}, expected {sorted(expected)}"
    # nothing before the fault: the same run without it has no violation
    assert min(v.time for v in run.violations) >= run.start + START - 1.0
