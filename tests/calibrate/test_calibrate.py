"""Calibration end to end: bags in, a file whose next normal run raises no alarm."""

from __future__ import annotations

import math
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from imrosc.calibrate.rule import held_out_runs, rule_for
from imrosc.detect import run_detect
from imrosc.replay import Replayer
from imrosc.runtime.alarms import AlarmRule
from imrosc.runtime.families import WINDOW
from tests.translate import Msg, msg, write_bag

FLOAT = "std_msgs/msg/Float64"
RATE = 20.0


def run(
    path: Path,
    seed: int,
    seconds: float = 20.0,
    fault_at: float | None = None,
    extra: Sequence[Msg] = (),
    start: float = 100.0,
) -> Path:
    """A noisy sine on ``/a/x`` at 20 Hz from ``start``; from ``fault_at`` on, shifted by 3;
    and ``extra``."""
    rng = np.random.default_rng(seed)
    phase = rng.uniform(0, 2 * math.pi)
    messages: list[Msg] = []
    for k in range(int(seconds * RATE)):
        t = start + k / RATE
        value = math.sin(0.7 * k / RATE + phase) + rng.normal(0, 0.05)
        if fault_at is not None and k / RATE >= fault_at:
            value += 3.0
        messages.append(msg("/a/x", t, FLOAT, data=value))
    return write_bag(path, [*messages, *extra])


def config(folder: Path, bags: list[Path], budget: str = "") -> Path:
    listed = "".join(f"<bag>{b.name}</bag>" for b in bags)
    path = folder / "c.xml"
    path.write_text(
        f'<imROS project="c"><scope><publish id="a">/a/x</publish></scope>'
        f'<detect inv="c.inv"{budget}>{listed}</detect></imROS>'
    )
    return path


@pytest.fixture(scope="module")
def learnt(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, dict[str, Any]]:
    folder = tmp_path_factory.mktemp("calibrate")
    bags = [run(folder / f"good_{k}.bag", k) for k in range(6)]
    result = run_detect(config(folder, bags), workers=1)
    assert result.document is not None and result.calibration is not None
    return folder, result.document


def test_the_file_records_the_rule_and_what_calibration_did(
    learnt: tuple[Path, dict[str, Any]],
) -> None:
    _, document = learnt
    calibration = document["calibration"]
    assert calibration["units"] == "runs" and calibration["count"] == 6
    assert calibration["budget"] == 0.05
    assert sum(calibration["widened"].values()) > 0
    assert len(calibration["held_out"]) == 6
    assert {"persist", "seconds", "distinct", "window"} <= set(document["alarms"])
    assert set(document["alarms"].get("families", {})) <= WINDOW


def test_bounds_widen_beyond_the_training_extremes(learnt: tuple[Path, dict[str, Any]]) -> None:
    folder, document = learnt
    exact = run_detect(config(folder, sorted(folder.glob("good_*.bag")), ' budget="0"'))
    assert exact.document is not None and "alarms" not in exact.document
    (bound,) = [i for i in document["invariants"] if i["family"] == "bounds"]
    (before,) = [i for i in exact.document["invariants"] if i["id"] == bound["id"]]
    assert bound["params"]["max"] > before["params"]["max"]
    assert bound["params"]["min"] < before["params"]["min"]
    assert bound["text"].startswith(f"{bound['params']['min']!r}"[:4])


def test_a_new_normal_run_raises_no_alarm_and_a_fault_does(
    learnt: tuple[Path, dict[str, Any]],
) -> None:
    folder, document = learnt
    replayer = Replayer(document)
    for seed in (100, 101, 102):
        assert replayer.run(run(folder / f"new_{seed}.bag", seed)).alarms == []
    faulty = replayer.run(run(folder / "fault.bag", 7, fault_at=12.0))
    assert faulty.alarms
    assert faulty.alarms[0].time - faulty.start >= 12.0
    assert faulty.alarms[0].time - faulty.start < 13.0


def test_the_training_runs_replay_without_alarms(learnt: tuple[Path, dict[str, Any]]) -> None:
    folder, document = learnt
    replayer = Replayer(document)
    for bag in sorted(folder.glob("good_*.bag")):
        assert replayer.run(bag).alarms == []


def test_one_bag_is_split_into_pseudo_runs(tmp_path: Path) -> None:
    bag = run(tmp_path / "only.bag", 1, seconds=30.0)
    result = run_detect(config(tmp_path, [bag]))
    assert result.calibration is not None and result.document is not None
    assert result.calibration.units == "segments" and result.calibration.count == 6
    assert "pseudo-runs" in result.calibration.summary()
    spans = [h["span"] for h in result.document["calibration"]["held_out"]]
    assert all(span is not None for span in spans) and len(spans) == 6
    assert Replayer(result.document).run(bag).alarms == []


def test_workers_do_not_change_the_file(tmp_path: Path) -> None:
    bags = [run(tmp_path / f"r{k}.bag", k, seconds=8.0) for k in range(4)]
    path = config(tmp_path, bags)
    one, two = run_detect(path, workers=1), run_detect(path, workers=2)
    assert one.document == two.document


def test_the_file_keeps_what_the_rule_of_a_subset_needs(
    learnt: tuple[Path, dict[str, Any]],
) -> None:
    _, document = learnt
    everything = {i["id"] for i in document["invariants"]}
    rule = rule_for(document, everything)
    assert rule is not None
    assert rule.persist <= document["alarms"]["persist"] or document["calibration"]["unstable"]
    own = AlarmRule.from_json(document["alarms"])
    # the rule of no invariant: nothing persists or agrees; the severe alarms are the file's
    assert rule_for(document, set()) == AlarmRule(
        persist=1,
        seconds=0.001,
        distinct=1,
        window=1.0,
        severe=own.severe,
        severe_families=own.severe_families,
    )
    assert rule_for({"calibration": {}}, everything) is None


def test_held_out_units_name_the_invariants_their_fold_could_not_test(tmp_path: Path) -> None:
    """Runs 0 and 1 alone publish /a/y: they are held out together (the first block), so the
    invariants of /a/y, learnt from them, were absent from their fold's document; a successful
    run scored from its held-out replays is no evidence about those."""
    extra = [msg("/a/y", 100.0 + i / RATE, FLOAT, data=float(i % 7)) for i in range(160)]
    bags = [
        run(tmp_path / f"good_{k}.bag", k, seconds=8.0, extra=extra if k < 2 else ())
        for k in range(6)
    ]
    path = tmp_path / "c.xml"
    path.write_text(
        '<imROS project="c"><scope><publish id="a">/a/x</publish><publish id="b">/a/y</publish>'
        '</scope><detect inv="c.inv">'
        + "".join(f"<bag>{b.name}</bag>" for b in bags)
        + "</detect></imROS>"
    )
    result = run_detect(path, workers=1)
    assert result.document is not None
    of_b = {i["id"] for i in result.document["invariants"] if i["point"] == "b"}
    assert of_b
    absent = {
        Path(u["bag"]).name: set(u["absent"]) for u in result.document["calibration"]["held_out"]
    }
    assert absent == {
        b.name: (of_b if b.name in ("good_0.bag", "good_1.bag") else set()) for b in bags
    }
    seen = held_out_runs(result.document, tmp_path)
    assert seen[(tmp_path / "good_0.bag").resolve()].untested == of_b
    assert seen[(tmp_path / "good_4.bag").resolve()].untested == frozenset()


def test_a_held_out_unit_breaks_a_set_its_fold_never_saw_whole(tmp_path: Path) -> None:
    """/a/z takes the values 0 and 1 in every run, and also 2 in the last: held out (the
    last block alone), that run brings a value the others never had."""
    bags = []
    for k in range(6):
        values = (0.0, 1.0, 2.0) if k == 5 else (0.0, 1.0)
        extra = [
            msg("/a/z", 100.0 + i / RATE, FLOAT, data=values[i % len(values)]) for i in range(160)
        ]
        bags.append(run(tmp_path / f"good_{k}.bag", k, seconds=8.0, extra=extra))
    path = tmp_path / "c.xml"
    path.write_text(
        '<imROS project="c"><scope><publish id="a">/a/x</publish><publish id="z">/a/z</publish>'
        '</scope><detect inv="c.inv">'
        + "".join(f"<bag>{b.name}</bag>" for b in bags)
        + "</detect></imROS>"
    )
    result = run_detect(path, workers=1)
    assert result.document is not None
    sets = {
        i["id"]
        for i in result.document["invariants"]
        if i["point"] == "z" and i["family"] == "one-of"
    }
    assert len(sets) == 1
    breaks = {
        Path(u["bag"]).name: set(u["set_breaks"])
        for u in result.document["calibration"]["held_out"]
    }
    assert breaks == {b.name: (sets if b.name == "good_5.bag" else set()) for b in bags}
    seen = held_out_runs(result.document, tmp_path)
    assert sets <= seen[(tmp_path / "good_5.bag").resolve()].broken
    assert not sets & seen[(tmp_path / "good_5.bag").resolve()].untested


def test_calibration_holds_out_whole_sessions() -> None:
    """Runs of one session (minutes apart) are held out together, whatever the block
    sizes: a held-out run is not explained by a neighbour of its own session. Evenly spaced
    units (the segments of one run) still get near-equal blocks."""
    from imrosc.calibrate import blocks
    from imrosc.infer.engine import Unit

    day = 86400.0
    starts = [0.0, 120.0, 260.0, day, day + 200.0, 2 * day, 2 * day + 90.0, 2 * day + 300.0]
    units = [Unit(Path(f"run_{k}.bag"), [], start=s) for k, s in enumerate(starts)]
    assert blocks(units, 3) == [[0, 1, 2], [3, 4], [5, 6, 7]]
    even = [
        Unit(Path("one.bag"), [], span=(10.0 * k, 10.0 * k + 10), start=10.0 * k) for k in range(6)
    ]
    assert blocks(even, 5) == [[0, 1], [2], [3], [4], [5]]


def test_calibration_folds_runs_of_simulated_time_evenly() -> None:
    """Runs recorded under simulated time all start near 0 on their bag clocks, a first
    message's jitter apart (the case study's 15 landings: 13 at 0.01 s, one at 0.03 s, one
    at 0.07 s): their starts say nothing of sessions. Cut at those jitters, the blocks were
    3, 3, 7, 1 and 1 runs, and the fold of 7 learnt from 8 runs a frequency minimum that a
    held-out landing's clock stall broke. Overlapping runs have no gap between them: near-
    equal blocks. Runs that follow each other on one clock keep their session blocks."""
    from imrosc.calibrate import blocks
    from imrosc.infer.engine import Unit

    starts = [0.01] * 13 + [0.03, 0.07]
    lengths = [22, 25, 22, 23, 38, 40, 32, 23, 60, 22, 26, 21, 32, 30, 22]
    units = [
        Unit(Path(f"normal_{k}.bag"), [], start=s, end=s + n)
        for k, (s, n) in enumerate(zip(starts, lengths, strict=True))
    ]
    assert [len(b) for b in blocks(units, 5)] == [3, 3, 3, 3, 3]
    day = 86400.0
    starts = [0.0, 120.0, 260.0, day, day + 200.0, 2 * day, 2 * day + 90.0, 2 * day + 300.0]
    timed = [Unit(Path(f"run_{k}.bag"), [], start=s, end=s + 60.0) for k, s in enumerate(starts)]
    assert blocks(timed, 3) == [[0, 1, 2], [3, 4], [5, 6, 7]]


def test_runs_on_restarted_clocks_are_held_out_in_even_blocks(tmp_path: Path) -> None:
    """End to end: each unit carries its bag's end, so runs whose clocks all start at 100 s
    (their first messages 0 to 0.07 s apart) are held out in blocks of two, not cut at the
    jitters of their starts (2, 2, 4, 1, 1)."""
    jitter = [0.0] * 8 + [0.03, 0.07]
    bags = [
        run(tmp_path / f"r{k}.bag", k, seconds=4.0 + k % 3, start=100.0 + j)
        for k, j in enumerate(jitter)
    ]
    result = run_detect(config(tmp_path, bags), workers=1)
    assert result.calibration is not None
    sizes: dict[int, int] = {}
    for unit in result.calibration.held_out:
        sizes[unit.fold] = sizes.get(unit.fold, 0) + 1
    assert sorted(sizes.values()) == [2, 2, 2, 2, 2]
