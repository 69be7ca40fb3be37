"""The thesis' case study 1 in closed loop (Table 5.2): the landing system with and without
its generated monitor.

    python bench/casestudy.py [--trials 10] [--scenarios normal,wind,...] [--nominal 20]
                              [--speed 0] [--timeout 120] [--keep DIR]

The pipeline, as a user runs it, on the live ROS 1 system of ``examples/landing_system``
(real roscore on a free port, rospy nodes on simulated time in lockstep with the simulator,
so that a seed gives the same run on a loaded machine; ``--speed`` caps the pace, 0: none;
``tests/live/landing_system.py`` starts it):

1. ``imrosc record`` of ``--nominal`` runs of the normal scenario (seeds 1000, 1001, ...),
   each through the ``--launch`` copy it writes (the servers remapped so it can relay their
   calls). Runs that landed are kept as training runs (``bags/nominal``) but for every
   fifth, kept out as ``<success>`` runs (``bags/success``); runs that failed are
   ``<fail>`` runs (``bags/fail``, scored whole: no fault was injected), as are the
   ``--fail-runs`` recorded runs of each fault scenario (seeds 2000, ...) in which the
   fault acted (whether the run failed or not: its samples from the onset on are faulty),
   with the onset of their fault (``bags/fail_onsets.json``: when the simulator saw the fault
   first act, ``landing_core.World.onset``, as seconds into the bag) so that classification
   can also learn the detectors of ``<check detector>``;
2. ``imrosc infer``, then ``imrosc classify`` (which writes ``landing.refined.inv``) on a
   copy of ``examples/uav_landing.xml`` whose ``<check>`` lists those folders and whose
   ``<monitor>`` checks the refined file (``--invariants inferred``: the inferred one, as
   the example has it; scope, detect and monitor otherwise unchanged);
3. ``imrosc build --backend ros1`` with ``examples/uav_landing.graph.yaml``;
4. per scenario, ``--trials`` trials (seeds 0, 1, ...) through the system's launch file
   (without the monitor) and through the ``system_monitored.launch`` the build rewrote
   (with it: blocking, and commanding the task state when an invariant breaks).

Printed: Table 5.2's layout per scenario (success %, average time to land of the successes,
landings re-initiated, and the invariants whose alarms the monitor raised most often over
its trials), then the overall success with and without, and the last line
``overall success: with monitor X %, without Y %``. Targets (issue 19): with >= 90 %,
without <= 30 %, normal with >= normal without, every scenario with >= the thesis' row.
"""

from __future__ import annotations

import argparse
import collections
import json
import os
import re
import shutil
import signal
import subprocess
import sys
import tempfile
import time
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from imrosc.bags import open_bag  # noqa: E402
from tests.live.harness import Ros, ros_missing  # noqa: E402
from tests.live.landing_system import (  # noqa: E402
    EXAMPLES,
    LAUNCH,
    SCENARIOS,
    Outcome,
    prepare,
    trial,
)

CONFIG = EXAMPLES / "uav_landing.xml"
GRAPH = EXAMPLES / "uav_landing.graph.yaml"
THESIS = {
    "normal": (35, 95),
    "wind": (0, 100),
    "occupied": (0, 100),
    "fragile": (20, 80),
    "slowed": (20, 80),
    "stealing": (20, 80),
    "false_airport": (0, 100),
}
"""Table 5.2: success % without and with the monitor."""
NOMINAL_SEED, FAIL_SEED = 1000, 2000
ALARM = re.compile(r"imrosc: alarm[^:]*: (\S+) broken at ([^:]+): (.*)$")


def imrosc(*args: str, cwd: Path, env: dict[str, str] | None = None) -> str:
    """Run an imrosc command as a user does; exit with its output when it fails."""
    done = subprocess.run(
        [sys.executable, "-m", "imrosc", *args],
        cwd=cwd,
        env=env,
        capture_output=True,
        text=True,
        check=False,
    )
    if done.returncode not in (0, 3, 5):  # findings, not errors: violations, unchecked points
        sys.exit(f"imrosc {' '.join(args)} failed ({done.returncode}):\n{done.stdout}{done.stderr}")
    return done.stdout + done.stderr


def configuration(work: Path, refined: bool = True, select: str = "fscore") -> Path:
    """``uav_landing.xml`` with its ``<check>`` on the bench's folders, choosing invariants by
    ``select`` (``fscore``: with the threshold and beta of the example's ``<check>``), and its
    monitor on the refined invariants (``refined``; else on the inferred ones, as the example
    has it); the launch file and graph beside it."""
    text = CONFIG.read_text(encoding="utf-8")
    check = re.search(r"  <check .*?</check>\n", text, re.S)
    assert check is not None, "uav_landing.xml has no <check>"
    selection = 'select="cover"'
    if select == "fscore":
        selection = " ".join(
            f'{name}="{value}"'
            for name, value in re.findall(r'(select|threshold|beta)="([^"]*)"', check.group(0))
        )
    text = text.replace(
        check.group(0),
        f'  <check inv="landing.inv" {selection}>\n'
        "    <success>bags/success</success>\n"
        '    <fail onsets="bags/fail_onsets.json">bags/fail</fail>\n'
        "  </check>\n",
    )
    if refined:
        text = text.replace(
            '<monitor launch="launch/landing.launch" inv="landing.inv"',
            '<monitor launch="launch/landing.launch" inv="landing.refined.inv"',
        )
    config = work / "uav_landing.xml"
    config.write_text(text, encoding="utf-8")
    shutil.copy(GRAPH, work / GRAPH.name)
    (work / "launch").mkdir(exist_ok=True)
    shutil.copy(LAUNCH, work / "launch" / LAUNCH.name)
    return config


def record(
    ros: Ros,
    work: Path,
    config: Path,
    scenario: str,
    seed: int,
    speed: float,
    timeout: float,
) -> tuple[Outcome, Path]:
    """One recorded run: ``imrosc record`` started, the system launched through its
    ``--launch`` copy, the recorder stopped (Ctrl-C) once the run is over; its outcome and
    bag (in ``bags/recording``)."""
    env = {**os.environ, **ros.env}
    env.pop("LANDING_LOCKSTEP", None)  # the recorder is no part of the robot: not in lockstep
    # the ROS graph's PYTHONPATH (the generated service types) and this tree's imrosc
    env["PYTHONPATH"] = os.pathsep.join(
        p for p in (ros.env.get("PYTHONPATH"), str(ROOT), os.environ.get("PYTHONPATH")) if p
    )
    name = f"{scenario}_{seed}"
    command = [
        sys.executable,
        "-m",
        "imrosc",
        "record",
        config.name,
        "-o",
        "bags/recording",
        "--name",
        name,
        "--graph",
        GRAPH.name,
        "--launch",
        "launch/landing.launch",
        "--force",
        "--period",
        "0.5",
    ]
    log = work / "logs" / f"record_{name}.log"
    log.parent.mkdir(exist_ok=True)
    with log.open("w") as out:
        recorder = subprocess.Popen(
            command, cwd=work, env=env, stdout=out, stderr=subprocess.STDOUT, start_new_session=True
        )
    try:
        deadline = time.monotonic() + 60
        while not (work / "launch" / "landing.record.launch").exists():
            if recorder.poll() is not None or time.monotonic() > deadline:
                sys.exit(f"imrosc record did not start:\n{log.read_text()}")
            time.sleep(0.2)
        time.sleep(3.0)  # rosbag subscribes, the recording node relays
        outcome = trial(
            ros,
            scenario,
            seed,
            launch=work / "launch" / "landing.record.launch",
            speed=speed,
            timeout=timeout,
        )
    finally:
        recorder.send_signal(signal.SIGINT)
        recorder.wait(120)
    return outcome, work / "bags" / "recording" / f"{name}.bag"


def bag_onset(bag: Path, onset: float | None) -> float | None:
    """The fault's onset in ``bag``: seconds from the bag's start (its clock is the
    recorder's, wall time) to the first UAV pose stamped (simulated time, ``/vicon``'s
    clock) at or after the simulated ``onset``; None without an onset."""
    if onset is None:
        return None
    with open_bag(bag) as reader:
        start = reader.start_time / 1e9
        poses = [c for c in reader.connections if c.topic == "/a/subject_pose"]
        for connection, stamp, raw in reader.messages(connections=poses):
            pose: Any = reader.deserialize(raw, connection.msgtype)
            if pose.header.stamp.sec + pose.header.stamp.nanosec * 1e-9 >= onset:
                return round(max(stamp / 1e9 - start, 0.0), 3)
    return None


def note_onset(folder: Path, bag: Path, onset: float | None) -> None:
    """Add the onset of ``bag`` (in ``folder``; seconds after its start, or null: unknown)
    to ``<folder>_onsets.json`` beside the folder (``<fail onsets>``; inside, it would be
    searched for bags)."""
    path = folder.with_name(f"{folder.name}_onsets.json")
    onsets = json.loads(path.read_text()) if path.exists() else {}
    onsets[f"{folder.name}/{bag.name}"] = onset
    path.write_text(json.dumps(onsets, indent=1, sort_keys=True) + "\n")


def keep(bag: Path, folder: Path) -> None:
    """Move a recorded bag into ``folder``."""
    folder.mkdir(parents=True, exist_ok=True)
    shutil.move(str(bag), folder / bag.name)


@dataclass
class Row:
    """A scenario's trials under one system."""

    outcomes: list[Outcome]

    @property
    def success(self) -> float:
        return 100.0 * sum(o.success for o in self.outcomes) / max(len(self.outcomes), 1)

    @property
    def time_to_land(self) -> float | None:
        landed = [o.time for o in self.outcomes if o.success and o.outcome == "landed"]
        return sum(landed) / len(landed) if landed else None

    @property
    def reinitiated(self) -> float:
        return sum(o.reinitiated for o in self.outcomes) / max(len(self.outcomes), 1)


def alarms(ros: Ros) -> collections.Counter[str]:
    """The invariants the monitor alarmed on, from its log (``rosout``), by text."""
    found: collections.Counter[str] = collections.Counter()
    for log in (ros.home / "ros_log").rglob("*monitor*.log"):
        for line in log.read_text(errors="replace").splitlines():
            match = ALARM.search(line)
            if match:
                found[f"{match.group(2)}: {match.group(3)[:90]}"] += 1
    return found


def record_runs(ros: Ros, work: Path, config: Path, args: argparse.Namespace) -> None:
    """Record ``--nominal`` normal runs and ``--fail-runs`` runs of each fault, sorted into
    ``bags/nominal``, ``bags/success`` and ``bags/fail`` (with ``bags/fail_onsets.json``)."""
    print(
        f"== recording {args.nominal} normal runs and {args.fail_runs} of each fault "
        f"(speed {args.speed:g}x) ==",
        flush=True,
    )
    for k in range(args.nominal):
        seed = NOMINAL_SEED + k
        outcome, bag = record(ros, work, config, "normal", seed, args.speed, args.timeout)
        folder = "fail" if not outcome.success else ("success" if k % 5 == 4 else "nominal")
        keep(bag, work / "bags" / folder)
        if folder == "fail":  # no fault was injected: its samples cannot be labelled
            note_onset(work / "bags" / "fail", bag, None)
        print(f"  normal seed {seed}: {outcome.outcome} -> bags/{folder}", flush=True)
    for scenario in SCENARIOS[1:]:
        for k in range(args.fail_runs):
            seed = FAIL_SEED + k
            outcome, bag = record(ros, work, config, scenario, seed, args.speed, args.timeout)
            onset = bag_onset(bag, outcome.onset)
            if outcome.success and onset is None:  # the fault never acted: not used
                bag.unlink()
                print(f"  {scenario} seed {seed}: {outcome.outcome} (not used)", flush=True)
                continue
            keep(bag, work / "bags" / "fail")
            note_onset(work / "bags" / "fail", bag, onset)
            print(
                f"  {scenario} seed {seed}: {outcome.outcome} -> bags/fail "
                f"(onset {outcome.onset} s simulated, {onset} s into the bag)",
                flush=True,
            )


def main(argv: Sequence[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--trials", type=int, default=10)
    parser.add_argument("--scenarios", default=",".join(SCENARIOS))
    parser.add_argument("--nominal", type=int, default=20, help="recorded normal runs")
    parser.add_argument("--fail-runs", type=int, default=1, help="recorded runs per fault")
    parser.add_argument(
        "--speed",
        type=float,
        default=0.0,
        help="at most times real time (0: as fast as the lockstep goes)",
    )
    parser.add_argument("--timeout", type=float, default=120.0, help="simulated s per trial")
    parser.add_argument("--keep", type=Path, help="work in this folder and keep it")
    parser.add_argument(
        "--reuse",
        action="store_true",
        help="with --keep: use the runs an earlier bench recorded there (its bags/) instead "
        "of recording them again; infer, classify, build and the trials run anew",
    )
    parser.add_argument(
        "--invariants",
        choices=("refined", "inferred"),
        default="refined",
        help="what the monitor checks: classify's refined file or infer's",
    )
    parser.add_argument(
        "--select",
        choices=("fscore", "cover"),
        default="fscore",
        help="how classify chooses the refined file's invariants (<check select>; default: "
        "the example's: fscore with its threshold and beta)",
    )
    args = parser.parse_args(argv)
    scenarios = [s.strip() for s in args.scenarios.split(",") if s.strip()]
    unknown = [s for s in scenarios if s not in SCENARIOS]
    if unknown:
        parser.error(f"unknown scenario(s) {', '.join(unknown)}; from {', '.join(SCENARIOS)}")
    missing = ros_missing()
    if missing:
        sys.exit(f"the case study needs ROS 1 here: {missing}")
    if args.reuse and (args.keep is None or not (args.keep / "bags" / "nominal").is_dir()):
        parser.error("--reuse needs --keep DIR holding an earlier run's bags/nominal")
    work = args.keep or Path(tempfile.mkdtemp(prefix="imrosc-casestudy-"))
    work.mkdir(parents=True, exist_ok=True)
    started = time.monotonic()
    config = configuration(work, refined=args.invariants == "refined", select=args.select)
    onsets = work / "bags" / "fail_onsets.json"  # <fail onsets>: there even with no failed run
    onsets.parent.mkdir(parents=True, exist_ok=True)
    if not onsets.exists():
        onsets.write_text("{}\n")
    if args.reuse:  # the earlier run's logs (its alarms) and monitor package go
        shutil.rmtree(work / "ros", ignore_errors=True)
        shutil.rmtree(work / "build", ignore_errors=True)
    ros = Ros(work / "ros")
    prepare(ros)
    ros.start()
    # the launch file sets it too, but only once started: a recorder started before the
    # first launch would stamp its bag with wall time, the later ones with simulated time
    ros.set_param("/use_sim_time", True)
    try:
        if args.reuse:
            print(f"== reusing the runs recorded in {work / 'bags'} ==", flush=True)
        else:
            record_runs(ros, work, config, args)
        print("== imrosc infer, classify, build ==", flush=True)
        print(imrosc("infer", config.name, "-j", "2", cwd=work).strip(), flush=True)
        print(imrosc("classify", config.name, "-j", "2", cwd=work).strip()[-1500:], flush=True)
        imrosc("build", config.name, "--backend", "ros1", "--graph", GRAPH.name, cwd=work)
        build = next((work / "build").glob("*-ros1"))
        monitored = next(build.glob("*/launch/system_monitored.launch"))
        ros.add_package_path(build)
        rows: dict[tuple[str, bool], Row] = {}
        print(f"== {args.trials} trials per scenario, without and with the monitor ==", flush=True)
        for scenario in scenarios:
            for monitor in (False, True):
                outcomes = []
                for seed in range(args.trials):
                    launch = monitored if monitor else work / "launch" / LAUNCH.name
                    outcome = trial(
                        ros, scenario, seed, launch=launch, speed=args.speed, timeout=args.timeout
                    )
                    outcomes.append(outcome)
                    print(
                        f"  {scenario:13s} {'with' if monitor else 'without':7s} seed {seed}: "
                        f"{outcome.outcome} ({outcome.detail}), {outcome.time:.1f} s",
                        flush=True,
                    )
                rows[(scenario, monitor)] = Row(outcomes)
        report(rows, scenarios, alarms(ros))
    finally:
        ros.shutdown()
        if args.keep is None:
            shutil.rmtree(work, ignore_errors=True)
    print(f"({time.monotonic() - started:.0f} s)")


def report(
    rows: dict[tuple[str, bool], Row], scenarios: Sequence[str], broken: collections.Counter[str]
) -> None:
    def cell(value: float | None, digits: int = 1) -> str:
        return "-" if value is None else f"{value:.{digits}f}"

    print("\nTable 5.2 (thesis figures in brackets)")
    print(
        f"  {'scenario':14s} {'without %':>14s} {'time s':>7s} | {'with %':>12s} "
        f"{'time s':>7s} {'re-init':>7s}"
    )
    for scenario in scenarios:
        off, on = rows[(scenario, False)], rows[(scenario, True)]
        was_off, was_on = THESIS[scenario]
        print(
            f"  {scenario:14s} {off.success:6.0f} [{was_off:3d}]  {cell(off.time_to_land):>7s}"
            f" | {on.success:4.0f} [{was_on:3d}] {cell(on.time_to_land):>7s} "
            f"{on.reinitiated:7.1f}"
        )
    print("invariants the monitor alarmed on most often:")
    for text, count in broken.most_common(8):
        print(f"  {count:5d}x {text}")
    total_off = [o for s in scenarios for o in rows[(s, False)].outcomes]
    total_on = [o for s in scenarios for o in rows[(s, True)].outcomes]
    every = total_off + total_on
    print(
        f"lockstep: {sum(o.stalls for o in every)} steps went on unsettled in {len(every)} "
        f"trials; {sum(o.wall for o in every) / max(len(every), 1):.1f} s per trial "
        "(wall, start-up included)"
    )
    with_ = 100.0 * sum(o.success for o in total_on) / max(len(total_on), 1)
    without = 100.0 * sum(o.success for o in total_off) / max(len(total_off), 1)
    print(f"overall success: with monitor {with_:.1f} %, without {without:.1f} %")


if __name__ == "__main__":
    main()
