"""Trials of the closed-loop landing system (``examples/landing_system``) on a live graph.

:func:`prepare` makes a :class:`~tests.live.harness.Ros` able to start it: the package's
service types generated with genpy (Debian's ``/usr/lib/genpy/gensrv_py.py``) into a folder
on ``PYTHONPATH``, and ``examples/`` on ``ROS_PACKAGE_PATH``. :func:`trial` runs one
scenario and seed through a launch file (the system's own, or the copy ``imrosc build``
rewrote to put the monitor in) and returns the outcome ``/vicon`` wrote.
"""

from __future__ import annotations

import json
import os
import subprocess
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from tests.casestudy.core import landing_core
from tests.live.harness import ROS_PYTHON, Ros

ROOT = Path(__file__).resolve().parents[2]
EXAMPLES = ROOT / "examples"
PACKAGE = EXAMPLES / "landing_system"
LAUNCH = EXAMPLES / "launch" / "landing.launch"
LOCKSTEP = PACKAGE / "lockstep"
"""``rospy_lockstep`` and the ``sitecustomize`` that loads it into every rospy process."""
GENSRV = Path("/usr/lib/genpy/gensrv_py.py")
SCENARIOS: tuple[str, ...] = landing_core.SCENARIOS  # type: ignore[attr-defined]
"""Table 5.1's scenarios, s1 to s7."""


def generate_services(out: Path) -> Path:
    """The package's service types as Python (``out/landing_system/srv``); returns ``out``."""
    target = out / "landing_system" / "srv"
    target.mkdir(parents=True, exist_ok=True)
    for srv in sorted((PACKAGE / "srv").glob("*.srv")):
        command = [str(ROS_PYTHON), str(GENSRV), "-p", "landing_system", "-o", str(target)]
        subprocess.run([*command, str(srv)], check=True, capture_output=True)
    command = [str(ROS_PYTHON), str(GENSRV), "--initpy", "-p", "landing_system"]
    subprocess.run([*command, "-o", str(target)], check=True, capture_output=True)
    (target.parent / "__init__.py").write_text("")
    return out


def prepare(ros: Ros, lockstep: bool = True) -> None:
    """Let ``ros`` start the landing system (before its first process that needs it); with
    ``lockstep``, its processes run in lockstep with the simulator (``LOCKSTEP``)."""
    generated = generate_services(ros.home / "generated")
    paths = [str(generated), *([str(LOCKSTEP)] if lockstep else [])]
    ros.env["PYTHONPATH"] = os.pathsep.join(paths)
    if lockstep:
        ros.env["LANDING_LOCKSTEP"] = "1"
    else:
        ros.env.pop("LANDING_LOCKSTEP", None)
    ros.add_package_path(EXAMPLES)


@dataclass(frozen=True)
class Outcome:
    """How a trial ended, as ``/vicon`` decided it (``sim.py``), and its wall time."""

    scenario: str
    seed: int
    outcome: str
    success: bool
    detail: str
    time: float
    reinitiated: int
    wall: float
    onset: float | None = None
    """When the fault first acted (simulated s; ``landing_core.World.onset``)."""
    stalls: int = 0
    """Steps at which the lockstep went on without the graph settled (0: deterministic)."""

    @classmethod
    def of(cls, data: dict[str, Any], wall: float) -> Outcome:
        return cls(
            str(data["scenario"]),
            int(data["seed"]),
            str(data["outcome"]),
            bool(data["success"]),
            str(data["detail"]),
            float(data["time"]),
            int(data["reinitiated"]),
            wall,
            None if data.get("onset") is None else float(data["onset"]),
            int(data.get("stalls", 0)),
        )


def written(path: Path) -> bool:
    """Whether the simulator has written its whole outcome to ``path`` (one line of JSON)."""
    try:
        return path.read_text(encoding="utf-8").endswith("\n")
    except OSError:
        return False


def trial(
    ros: Ros,
    scenario: str,
    seed: int,
    *,
    launch: Path = LAUNCH,
    speed: float = 3.0,
    timeout: float = 90.0,
    **args: str,
) -> Outcome:
    """Run one trial to its end; raises ``RuntimeError`` (with the launch's log) when the
    system ends without an outcome or overruns its simulated ``timeout`` by far."""
    out = ros.home / f"outcome-{scenario}-{seed}-{time.monotonic_ns()}.json"
    started = time.monotonic()
    proc = ros.launch(
        launch,
        scenario=scenario,
        seed=str(seed),
        speed=str(speed),
        timeout=str(timeout),
        outcome=str(out),
        **args,
    )
    # lockstep runs as fast as the graph goes, so a loaded machine slows it down
    limit = started + 60.0 + 4.0 * timeout + (timeout / speed if speed > 0 else 0.0)
    while proc.alive and time.monotonic() < limit and not written(out):
        time.sleep(0.1)
    if proc.alive:  # over (or overdue): stop every node at once, not one after the other
        ros.stop(proc)
    if not out.exists():
        raise RuntimeError(f"the {scenario} trial (seed {seed}) gave no outcome:\n{proc.tail()}")
    return Outcome.of(json.loads(out.read_text()), round(time.monotonic() - started, 2))
