"""Checking on real Crazyflie flights: self-replay, one engine, comparison, stability."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import pytest
from click.testing import CliRunner

from imrosc.bags import open_bag
from imrosc.classify import run_check
from imrosc.cli import main
from imrosc.detect import run_detect
from imrosc.graph.bags import publisher_starts
from imrosc.replay import replay
from imrosc.report import render
from imrosc.runtime import Engine, Violation
from imrosc.runtime.flatten import make_flattener
from imrosc.stability import run_stability

ROOT = Path(__file__).resolve().parent.parent.parent
CONFIG = ROOT / "examples" / "crazyflie.xml"
BAGS = ROOT.parent / "shared" / "data" / "real" / "crazyflie"
pytestmark = pytest.mark.skipif(not (BAGS / "sine_1.bag").exists(), reason="shared data missing")


@pytest.fixture(scope="module")
def document() -> dict[str, Any]:
    result = run_detect(CONFIG, workers=2)
    assert result.document is not None
    return result.document


def test_invariants_replay_on_their_own_bags_without_violations(
    document: dict[str, Any],
) -> None:
    runs = replay(document, [BAGS / "sine_1.bag", BAGS / "sine_2.bag"])
    assert [(r.error, r.violations) for r in runs] == [(None, [])] * 2
    assert [r.messages for r in runs] == [7677, 8087]
    families = {i["family"] for i in document["invariants"]}
    assert {"bounds", "frequency", "polygon", "architecture", "interval"} <= families


def test_ids_are_unique(document: dict[str, Any]) -> None:
    ids = [i["id"] for i in document["invariants"]]
    assert len(ids) == len(set(ids))


def _direct(document: dict[str, Any], bag: Path) -> list[Violation]:
    """What a monitor node does: a callback per message, flattened, into the engine."""
    engine = Engine(document)
    flatteners = {t: make_flattener(i["variables"]) for t, i in document["topics"].items()}
    found: list[Violation] = []
    with open_bag(bag) as reader:
        # a publisher is known from its connection's first message (the bag's index)
        starts = publisher_starts(reader)
        publishers: dict[str, set[str]] = {}

        def graph(until: int) -> None:
            nonlocal found
            while starts and starts[0].time <= until:
                at = starts[0].time
                while starts and starts[0].time == at:
                    publishers.setdefault(starts[0].topic, set()).add(starts.pop(0).node)
                snapshot = {"pub": {t: frozenset(nodes) for t, nodes in publishers.items()}}
                found += engine.graph(at / 1e9, snapshot, ("pub",))

        wanted = [c for c in reader.connections if c.topic in flatteners]
        for connection, stamp, raw in reader.messages(connections=wanted):
            graph(stamp)
            message = reader.deserialize(raw, connection.msgtype)
            found += engine.message(
                connection.topic, stamp / 1e9, flatteners[connection.topic](message)
            )
        graph(reader.end_time)
    return found


def test_replay_and_a_direct_engine_run_are_one_implementation(
    document: dict[str, Any],
) -> None:
    bag = BAGS / "maze_short_wc.bag"
    (run,) = replay(document, [bag])
    direct = _direct(document, bag)
    assert len(run.violations) > 1000
    assert run.violations == direct


def test_comparison_against_another_task_reports_per_family(tmp_path: Path) -> None:
    inv = tmp_path / "crazyflie.inv"
    runner = CliRunner()
    done = runner.invoke(main, ["infer", str(CONFIG), "-o", str(inv), "-q", "-j", "2"])
    assert done.exit_code == 0, done.output
    result = run_check(CONFIG, inv=inv, workers=2)
    report = result.report
    assert report["mode"] == "compare" and result.refined is None
    expected = [(BAGS / "maze_short_wc.bag").resolve()]
    assert [Path(b).resolve() for b in report["reference"]] == expected
    families = report["families"]
    assert families["polygon"]["broken"] > 0 and families["bounds"]["broken"] > 0
    for counts in families.values():
        assert counts["broken"] + counts["unbroken"] == counts["total"]
    assert sum(c["total"] for c in families.values()) == len(report["scores"])
    done = runner.invoke(main, ["classify", str(CONFIG), "--inv", str(inv), "--format", "json"])
    # the maze flight has no message of point i's topics: its invariants go unchecked there,
    # which classify says with its own exit status (README, "Exit status")
    assert done.exit_code == 5, done.output
    shown = json.loads(done.stdout)
    assert shown["families"] == families
    assert [points for points in shown["unchecked"].values()] == [["i"]]


def test_leave_one_out_stability_over_the_four_flights() -> None:
    report, problems = run_stability(ROOT / "examples" / "crazyflie_fleet.xml", workers=2)
    assert report is not None
    # the maze flight's message type was renamed: a warning, its fields matched by name
    assert {d.code for d in problems} == {"bag-type-drift"}
    assert report["folds"] == 4 and len(report["rounds"]) == 4
    flights = sorted(b.resolve() for b in BAGS.glob("*.bag"))
    for held_out, round_ in zip(flights, report["rounds"], strict=True):
        assert [Path(b).resolve() for b in round_["held_out"]] == [held_out]
        assert held_out not in [Path(b).resolve() for b in round_["trained_on"]]
        assert all(round_["violated"][f] <= round_["total"][f] for f in round_["total"])
    assert set(report["families"]) >= {"bounds", "frequency", "polygon", "architecture"}
    html = render(report, "html")
    assert html.startswith("<!-- generated by imrosc") and html.count("<svg") >= 1
