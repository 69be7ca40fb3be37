"""bench/casestudy.py's own parts: the configuration it derives from the example, and the
table it prints (the trials themselves need the live graph: ``tests/live``)."""

from __future__ import annotations

import collections
from pathlib import Path

import pytest

from bench import casestudy as c
from imrosc.classify import load_project
from tests.live.landing_system import LAUNCH, Outcome


def test_the_configuration_is_the_example_with_the_benchs_folders(tmp_path: Path) -> None:
    config = c.configuration(tmp_path)
    project, problems = load_project(config)
    assert project is not None and not [p for p in problems if p.severity.value == "error"]
    assert project.check is not None and project.check.select == "fscore"
    assert (project.check.success, project.check.fail) == (("bags/success",), ("bags/fail",))
    assert project.check.onsets[0].file == "bags/fail_onsets.json"  # the bench writes it
    assert project.monitor is not None and project.monitor.inv == "landing.refined.inv"

    def outside_check(text: str) -> str:
        return text[: text.index("  <check ")] + text[text.index("</check>") :]

    derived = config.read_text().replace('inv="landing.refined.inv"', 'inv="landing.inv"')
    assert outside_check(derived) == outside_check(c.CONFIG.read_text())  # scope, detect, monitor
    assert (tmp_path / "launch" / "landing.launch").read_text() == LAUNCH.read_text()


def _outcome(scenario: str, outcome: str, success: bool, time: float = 30.0) -> Outcome:
    return Outcome(scenario, 0, outcome, success, "", time, 1, 10.0)


def test_the_table_ends_with_the_overall_line(capsys: pytest.CaptureFixture[str]) -> None:
    rows = {
        ("normal", False): c.Row(
            [_outcome("normal", "landed", True), _outcome("normal", "crashed", False)]
        ),
        ("normal", True): c.Row([_outcome("normal", "landed", True)] * 2),
        ("occupied", False): c.Row([_outcome("occupied", "landed_elsewhere", False)] * 2),
        ("occupied", True): c.Row([_outcome("occupied", "timeout", True, 120.0)] * 2),
    }
    c.report(rows, ["normal", "occupied"], collections.Counter({"a?1: z <= 1": 3}))
    lines = capsys.readouterr().out.strip().splitlines()
    assert lines[-1] == "overall success: with monitor 100.0 %, without 25.0 %"
    normal = next(line for line in lines if line.strip().startswith("normal"))
    assert "50 [ 35]" in normal and "100 [ 95]" in normal and "30.0" in normal
    assert any("3x a?1: z <= 1" in line for line in lines)


def test_the_lanes_run_tasks_at_once_one_per_lane_in_the_tasks_order() -> None:
    import threading
    import time

    lanes = [c.Lane(None, Path(f"lane{n}"), Path()) for n in range(3)]  # type: ignore[arg-type]
    busy: set[int] = set()
    overlap: list[int] = []
    lock = threading.Lock()
    ended: list[int] = []

    def run(lane: c.Lane, task: int) -> tuple[int, str]:
        with lock:
            assert id(lane) not in busy  # a lane runs one task at a time
            busy.add(id(lane))
            overlap.append(len(busy))
        time.sleep(0.02 * (task % 4))
        with lock:
            busy.discard(id(lane))
        return task * 10, lane.work.name

    results = c.on_lanes(lanes, list(range(12)), run, lambda task, _: ended.append(task))
    assert [r[0] for r in results] == [k * 10 for k in range(12)]  # the tasks' order
    assert {r[1] for r in results} == {"lane0", "lane1", "lane2"}
    assert max(overlap) == 3 and sorted(ended) == list(range(12))


def test_a_failing_task_stops_the_lanes() -> None:
    lanes = [c.Lane(None, Path("lane"), Path())]  # type: ignore[arg-type]
    begun: list[int] = []

    def run(_lane: c.Lane, task: int) -> int:
        begun.append(task)
        if task == 1:
            raise RuntimeError("no outcome")
        return task

    with pytest.raises(RuntimeError, match="no outcome"):
        c.on_lanes(lanes, list(range(5)), run)
    assert begun == [0, 1]  # nothing begun after the failure


def test_the_trials_start_at_the_first_seed() -> None:
    assert c.trial_tasks(["wind"], 2, first_seed=10) == [
        ("wind", False, 10),
        ("wind", False, 11),
        ("wind", True, 10),
        ("wind", True, 11),
    ]
    assert [seed for _, _, seed in c.trial_tasks(["normal"], 3)] == [0, 1, 2] * 2


def test_the_trials_that_stay_up_start_first_then_those_with_the_monitor() -> None:
    tasks = c.trial_tasks(["normal", "occupied", "false_airport"], 2)
    order = c.start_order(tasks)
    assert sorted(order) == list(range(len(tasks)))  # every trial, once
    started = [tasks[k] for k in order]
    assert started[:4] == [
        ("occupied", True, 0),
        ("occupied", True, 1),
        ("false_airport", True, 0),
        ("false_airport", True, 1),
    ]
    assert started[4:6] == [("normal", True, 0), ("normal", True, 1)]
    assert all(not monitor for _, monitor, _ in started[6:])
    assert [seed for _, _, seed in started[6:]] == [0, 1] * 3  # the tasks' order otherwise
