"""Small bags with a known fault onset for the onset-aware classification tests.

``/x`` (std_msgs/Float64, 10 Hz for 20 s) swings within [0.1, 0.9] on nominal runs; a
faulty run jumps to 5 from its onset (12 s after its start), and a glitchy one also once
at 3 s. ``/failure_status`` (std_msgs/Float64) is 0, then 1 from the onset.
"""

from __future__ import annotations

import math
import shutil
from pathlib import Path

from click.testing import CliRunner

from imrosc.cli import main
from tests.translate import Msg, msg, write_bag

ONSET = 12.0
START = 100.0
RATE = 10
LENGTH = 20.0
FLOAT = "std_msgs/msg/Float64"


def _value(t: float, phase: float) -> float:
    return 0.5 + 0.4 * math.sin(0.7 * t + phase)


def run(
    path: Path,
    *,
    phase: float = 0.0,
    onset: float | None = None,
    glitch: float | None = None,
    label: bool = True,
) -> Path:
    """One run: nominal, or faulty from ``onset`` (with a one-sample glitch at ``glitch``)."""
    messages: list[Msg] = []
    for k in range(int(LENGTH * RATE)):
        t = k / RATE
        faulty = onset is not None and t >= onset
        x = 5.0 if faulty or (glitch is not None and abs(t - glitch) < 1e-9) else _value(t, phase)
        messages.append(msg("/x", START + t, FLOAT, data=x))
        if label and k % 2 == 0:
            messages.append(msg("/failure_status", START + t, FLOAT, data=float(faulty)))
    path.parent.mkdir(parents=True, exist_ok=True)
    return write_bag(path, messages)


def bags(folder: Path) -> None:
    """The standard set: train/ (3 nominal runs), ok/ (1), bad/late.bag (fault at the onset),
    bad/glitch.bag (and a glitch before it), never/never.bag (a fail run whose label stays 0),
    other/other.bag (as late.bag)."""
    for i in range(3):
        run(folder / "bags" / "train" / f"t{i}.bag", phase=0.0, label=False)
    run(folder / "bags" / "ok" / "s0.bag", phase=0.0)
    run(folder / "bags" / "bad" / "late.bag", onset=ONSET)
    run(folder / "bags" / "bad" / "glitch.bag", onset=ONSET, glitch=3.0)
    run(folder / "bags" / "never" / "never.bag")
    run(folder / "bags" / "other" / "other.bag", onset=ONSET)


CONFIG = """<imROS project="p">
  <scope><publish id="a">/x</publish></scope>
  <detect inv="p.inv"><bag>bags/train</bag></detect>
  <check inv="p.inv">
    <success>{success}</success>
    {fails}
  </check>
</imROS>
"""


def project(folder: Path, fails: str, success: str = "bags/ok", infer: bool = True) -> Path:
    """``folder`` with the bags, a configuration of those ``<fail>`` elements, and (when
    ``infer``) its invariants inferred from bags/train."""
    if not (folder / "bags").exists():
        bags(folder)
    config = folder / "p.xml"
    config.write_text(CONFIG.format(success=success, fails=fails))
    if infer and not (folder / "p.inv").exists():
        done = CliRunner().invoke(main, ["infer", str(config), "-q", "-j", "1"])
        assert done.exit_code == 0, done.output
    return config


def copy(source: Path, target: Path) -> Path:
    """A copy of a prepared folder (bags and invariants), so a test may change it."""
    shutil.copytree(source, target, dirs_exist_ok=True)
    return target
