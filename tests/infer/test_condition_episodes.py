"""A conditional point's time windows restart with each episode of its condition, in
inference and in the monitor's engine alike (a window never spans a stretch where the
condition did not hold, as it never spans two runs)."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import pytest
from click.testing import CliRunner

from imrosc.cli import main
from imrosc.replay import RunReplayer
from tests.translate import Msg, msg, write_bag

INT, FLOAT = "std_msgs/msg/Int32", "std_msgs/msg/Float64"

CONFIG = """<imROS project="ep">
  <scope>
    <condition id="1"><topic>/mode</topic><value>data == 1</value></condition>
    <publish id="a" conds="1">/x</publish>
  </scope>
  <detect inv="ep.inv" budget="0" discrete="0"><bag>{bag}</bag></detect>
</imROS>
"""


def _run(offset: float, modes: list[tuple[float, int]]) -> list[Msg]:
    """/mode and /x at 10 Hz, /mode holding each ``(seconds, value)`` in turn."""
    found: list[Msg] = []
    t = 0.0
    for seconds, value in modes:
        for _ in range(round(seconds * 10)):
            found.append(msg("/mode", offset + t, INT, "/ctl", data=value))
            found.append(msg("/x", offset + t + 0.01, FLOAT, "/src", data=t % 1.0))
            t += 0.1
    return found


def _inferred(folder: Path, name: str, messages: list[Msg]) -> dict[str, Any]:
    write_bag(folder / f"{name}.bag", messages)
    config = folder / f"{name}.xml"
    config.write_text(CONFIG.format(bag=f"{name}.bag").replace("ep.inv", f"{name}.inv"))
    result = CliRunner().invoke(main, ["infer", str(config), "-j", "1", "-q"])
    assert result.exit_code == 0, result.output
    document: dict[str, Any] = json.loads((folder / f"{name}.inv").read_text())
    return document


def _frequency(document: dict[str, Any]) -> dict[str, Any]:
    found: list[dict[str, Any]] = [
        i for i in document["invariants"] if i["point"] == "a?1" and i["family"] == "frequency"
    ]
    assert len(found) == 1
    return found[0]


def test_a_second_episode_of_the_condition_is_not_a_slow_topic(tmp_path: Path) -> None:
    once = _inferred(tmp_path, "once", _run(0.0, [(3, 0), (5, 1), (3, 0)]))
    assert (_frequency(once)["params"]["min"], _frequency(once)["params"]["max"]) == (10, 10)
    # learnt from a run whose condition holds twice, 1.5 s apart: the same 10 Hz
    twice = _inferred(tmp_path, "twice", _run(0.0, [(3, 1), (1.5, 0), (3, 1)]))
    assert _frequency(twice)["params"]["min"] == 10
    # and a monitor of the first sees no slow topic when the second episode begins
    write_bag(tmp_path / "check.bag", _run(50.0, [(3, 1), (1.5, 0), (3, 1), (2, 0)]))
    for chunked in (True, False):
        replay = RunReplayer(once, plots=False)
        replay.replayer.chunked = chunked
        result, _ = replay(tmp_path / "check.bag")
        assert [v for v in result.violations if v.family == "frequency"] == []


@pytest.mark.parametrize("chunked", [True, False])
def test_windows_still_see_a_slow_topic_within_an_episode(tmp_path: Path, chunked: bool) -> None:
    once = _inferred(tmp_path, "once", _run(0.0, [(3, 0), (5, 1), (3, 0)]))
    slow = _run(50.0, [(3, 1)])
    slow = [
        m for m in slow if not (m.topic == "/x" and 51.0 < m.time < 52.0 and m.time % 0.3 > 0.1)
    ]
    write_bag(tmp_path / "slow.bag", slow)
    replay = RunReplayer(once, plots=False)
    replay.replayer.chunked = chunked
    result, _ = replay(tmp_path / "slow.bag")
    assert [v for v in result.violations if v.family == "frequency"]
