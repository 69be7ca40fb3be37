"""What the generated monitor adds to the latency of a relayed topic, on live ROS 1 and ROS 2.

    python bench/monitor_latency.py [--rates 100,1000] [--seconds 5] [--invariants 1000]
                                    [--rounds N] [--middleware ros1,ros2] [--numpy-too]
                                    [--lockstep]

Two tables, one per middleware (``--middleware`` chooses; both by default), each with the
ratio of the monitor to a bare relay of that middleware. ROS 2 is described in
``bench/latency_ros2.py``: the same paths with rclpy nodes on ROS 2 Jazzy (the virtualenv of
``tools/ros2_venv.sh``, or ``IMROSC_ROS2_PYTHON``), the monitor package built with colcon, the
message a ``sensor_msgs/msg/JointState`` carrying the 56 values, the same invariants; with
``--numpy-too`` the ROS 2 table has a fifth path, the same monitor with ``IMROSC_NUMBA=0``,
run in the same rounds (the compiled checks and numpy's on the same machine load). The ROS 2
table also has the CPU time the relay or monitor process used per message sent (from
``/proc``); with ``--lockstep`` the ROS 2 source sends the next message only once it heard
the last one at the path's end, so that figure does not depend on how far the machine's
load let a relay fall behind (one that fell behind takes the piled-up messages at once,
which costs less per message). What follows describes ROS 1.

Needs Debian's ROS 1 (``make test`` installs it as root): a roscore on a free port of
127.0.0.1 (the live tests' harness, ``tests/live/harness.py``), rospy nodes under
``/usr/bin/python3``. A source node publishes a message of 56 float64 fields and a header
(``imrosc_bench/Wide``, generated with genpy into a temporary folder) at each rate, its
``header.stamp`` set right before publishing; a sink takes receipt time minus stamp. Four
paths, measured one after the other in the same run, at each rate:

* ``direct``: source -> sink;
* ``plain relay``: source -> a rospy node that decodes and republishes -> sink (the target's
  baseline);
* ``raw relay``: source -> a rospy node that republishes the bytes it receives
  (``rospy.AnyMsg``) -> sink;
* ``monitor``: source -> the monitor that ``imrosc build --backend ros1`` generates, blocking
  the topic (it reads the values from the bytes, checks the invariants with
  ``imrosc.runtime``, and republishes the bytes on ``/m/bench/wide``) -> sink.

The monitor relays a blocked topic as bytes (``imrosc/onboard/monitor_ros1/wire.py``), so it is also
compared with the raw relay, which does the same less the checks.

The monitor's invariants are those ``bench/check.py`` uses: inferred by imrosc from 20,000
rows of a thesis-scale point (Daikon's families and polygons), the first ``--invariants`` of
them kept, all on the relayed topic; the source publishes rows of the training data, so no
message breaks one and every message is relayed (a run where one is dropped says so).
Printed: messages received, median and 99th percentile latency, and the ratio of monitor to
plain relay (target: within 1.2x). The first 0.5 s of each run is warm-up and not counted.
The relays subscribe with TCP_NODELAY, as the monitor does on the topics it relays (without
it a burst from the source waits for Linux's delayed acknowledgement: 40 ms stalls in the
monitor's 99th percentile); the sink uses rospy's default (Nagle on). Queues of 100 everywhere,
as the monitor's. The monitor's checks are compiled by numba where Debian's python imports
it (``python3-numba``, which ``make test`` installs; the header line says which);
``IMROSC_NUMBA=0`` in the environment measures numpy alone.
"""

from __future__ import annotations

import argparse
import importlib.util
import json
import math
import os
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable
from pathlib import Path
from types import ModuleType
from typing import Any

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from imrosc.invariants import dumps  # noqa: E402
from imrosc.runtime import Engine  # noqa: E402
from tests.live.harness import (  # noqa: E402
    ROS_PYTHON,
    Proc,
    Ros,
    ros_missing,
    ros_python_version_of,
    wait_until,
)

TOPIC = "/bench/wide"
RELAYED = "/bench/relayed"
PACKAGE = "imrosc_bench"
MSGTYPE = f"{PACKAGE}/Wide"
PROJECT = "bench_latency"
MONITOR = f"{PROJECT}_monitor"
PATHS = ("direct", "plain relay", "raw relay", "monitor")
NUMPY_MONITOR = "monitor, numpy"
"""With ``--numpy-too`` (ROS 2): the monitor again with ``IMROSC_NUMBA=0``, in the same
rounds, so that the compiled checks and numpy's are compared on the same machine load."""
COLUMNS = 56
WARMUP = 0.5
HEADER_MSG = "uint32 seq\ntime stamp\nstring frame_id\n"  # std_msgs/Header, for genpy
CONFIG = f"""<imROS project="{PROJECT}">
  <scope>
    <publish id="a">{TOPIC}</publish>
  </scope>
  <monitor inv="bench.inv">
    <block>{TOPIC}</block>
  </monitor>
</imROS>
"""
GENERATE = """
import os, sys, genpy.generator, genpy.generate_initpy
source, headers, out = sys.argv[1:4]
folder = os.path.join(out, "imrosc_bench", "msg")
os.makedirs(folder)
status = genpy.generator.MsgGenerator().generate_messages(
    "imrosc_bench", [source], folder, {"std_msgs": [headers]})
genpy.generate_initpy.write_modules(folder)
open(os.path.join(out, "imrosc_bench", "__init__.py"), "w").close()
sys.exit(status)
"""


def load_check() -> ModuleType:
    """``bench/check.py``: its training data and inferred invariants."""
    spec = importlib.util.spec_from_file_location("bench_check", ROOT / "bench" / "check.py")
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def invariants(count: int) -> tuple[dict[str, Any], np.ndarray]:
    """The first ``count`` invariants of bench/check.py's point, moved to the relayed topic,
    and rows of its training data (which break none of them)."""
    check = load_check()
    data = check.training_data()
    document: dict[str, Any] = check.keep(check.inferred(data), count)
    text = json.dumps(document).replace('"/t"', json.dumps(TOPIC))
    document = json.loads(text.replace('"bench/msg/T"', json.dumps(f"{PACKAGE}/msg/Wide")))
    rows = data[:: check.ROWS // 2000][:2000]
    engine = Engine(document)
    with np.errstate(all="ignore"):
        broken = [v for k, r in enumerate(rows.tolist()) for v in engine.message(TOPIC, k, r)]
    assert not broken, broken[:3]
    return document, rows


def generate_type(folder: Path) -> Path:
    """``imrosc_bench/Wide`` (a header and v00..v55, float64) as a rospy message package."""
    source = folder / "Wide.msg"
    fields = "".join(f"float64 v{i:02d}\n" for i in range(COLUMNS))
    source.write_text("Header header\n" + fields, encoding="utf-8")
    headers = folder / "std_msgs"
    headers.mkdir()
    (headers / "Header.msg").write_text(HEADER_MSG, encoding="utf-8")
    out = folder / "python"
    command = [str(ROS_PYTHON), "-c", GENERATE, str(source), str(headers), str(out)]
    subprocess.run(command, check=True, capture_output=True)
    return out


def build_monitor(folder: Path, document: dict[str, Any]) -> Path:
    """The monitor package ``imrosc build --backend ros1`` renders; returns its parent."""
    (folder / "bench.inv").write_text(dumps(document), encoding="utf-8")
    config = folder / "bench.xml"
    config.write_text(CONFIG, encoding="utf-8")
    out = folder / "build"
    command = [sys.executable, "-m", "imrosc", "build", str(config), "--backend", "ros1"]
    subprocess.run([*command, "-o", str(out)], check=True, capture_output=True, cwd=ROOT)
    return out


def measure(
    ros: Ros, path: str, rate: float, seconds: float, rows: Path, launch: Path
) -> dict[str, Any]:
    """One run: start the path's relay and the sink, publish; the messages sent and received
    and the latencies (ms) after the warm-up."""
    started: list[Proc] = []
    typed = ("--type", MSGTYPE)
    sink_topic = TOPIC
    try:
        if path in ("plain relay", "raw relay"):
            raw = ("--raw",) if path == "raw relay" else ()
            relay = ros.node("bench_relay.py", *typed, "--input", TOPIC, "--output", RELAYED, *raw)
            started.append(relay)
            ros.wait_subscriber(TOPIC, "/bench_relay", 30, started)
            ros.wait_publisher(RELAYED, "/bench_relay", 30, started)
            sink_topic = RELAYED
        elif path == "monitor":
            monitor = ros.launch(launch)
            started.append(monitor)
            sink_topic = "/m" + TOPIC
            ros.wait_subscriber(TOPIC, "/" + MONITOR, 60, started)
            ros.wait_publisher(sink_topic, "/" + MONITOR, 60, started)
        out = ros.home / f"sink-{path.replace(' ', '_')}-{rate:g}.json"
        sink = ros.node("bench_sink.py", *typed, "--topic", sink_topic, "--out", str(out))
        started.append(sink)
        ros.wait_subscriber(sink_topic, "/bench_sink", 30, started)
        time.sleep(0.5)  # the relay's outgoing connection to the sink
        source = ros.node(
            "bench_source.py",
            *typed,
            "--topic",
            TOPIC,
            "--rows",
            str(rows),
            "--rate",
            f"{rate:g}",
            "--seconds",
            f"{seconds + WARMUP:g}",
            "--out",
            str(out.with_suffix(".sent")),
        )
        wait_until(lambda: source.popen.poll() is not None, "the source", seconds + 60, started)
        time.sleep(0.3)
        ros.stop(sink)
        record = json.loads(out.read_text(encoding="utf-8"))
        sent = int(out.with_suffix(".sent").read_text(encoding="utf-8"))
    finally:
        ros.stop(*started)
    first = record["received"][0] if record["received"] else 0.0
    kept = [
        latency * 1e3
        for latency, received in zip(record["latency"], record["received"], strict=True)
        if received >= first + WARMUP
    ]
    return {"received": len(record["latency"]), "sent": sent, "latencies": kept}


Results = dict[tuple[float, str], dict[str, Any]]
Measure = Callable[[str, float], dict[str, Any]]


def run_rounds(
    rates: list[float], rounds: int, measure_one: Measure, paths: tuple[str, ...] = PATHS
) -> Results:
    """Every path at every rate, ``rounds`` times, interleaved (every other round in the
    reverse order, so that no path always runs last)."""
    results: Results = {
        (rate, path): {"received": 0, "sent": 0, "latencies": [], "rounds": [], "cpu": 0.0}
        for rate in rates
        for path in paths
    }
    for round_ in range(rounds):
        for rate in rates:
            for path in paths if round_ % 2 == 0 else paths[::-1]:
                run = measure_one(path, rate)
                total = results[(rate, path)]
                total["received"] += run["received"]
                total["sent"] += run["sent"]
                total["latencies"] += run["latencies"]
                total["cpu"] += run.get("cpu", math.nan)
                total["rounds"].append(
                    float(np.median(run["latencies"])) if run["latencies"] else math.nan
                )
    return results


def bench_ros1(args: argparse.Namespace, folder: Path, document: dict[str, Any]) -> None:
    """The ROS 1 table."""
    rates = [float(r) for r in args.rates.split(",")]
    load = os.getloadavg()[0]
    python = generate_type(folder)
    build = build_monitor(folder, document)
    ros = Ros(folder / "ros")
    ros.env["PYTHONPATH"] = str(python)  # the message package, for every node
    ros.add_package_path(build)
    launch = build / MONITOR / "launch" / f"{MONITOR}.launch"
    try:
        ros.start()
        results = run_rounds(
            rates,
            args.rounds,
            lambda path, rate: measure(ros, path, rate, args.seconds, folder / "rows.npy", launch),
        )
    finally:
        ros.shutdown()
    print(
        f"live ROS 1 (rospy, 127.0.0.1), {MSGTYPE}: a header and {COLUMNS} float64; "
        f"{len(document['invariants'])} invariants on the relayed topic; {args.rounds} x "
        f"{args.seconds:g} s per path and rate after {WARMUP:g} s of warm-up; latency = "
        f"receipt - header.stamp; load average {load:.1f} before, {os.getloadavg()[0]:.1f} after; "
        f"the monitor's checks {checks_compiled()}"
    )
    report(results)


def bench_ros2(
    args: argparse.Namespace, folder: Path, document: dict[str, Any], python: str
) -> None:
    """The ROS 2 table (``bench/latency_ros2.py``)."""
    from bench.latency_ros2 import MSGTYPE as ROS2_MSGTYPE
    from bench.latency_ros2 import Ros2Bench, numba_of

    rates = [float(r) for r in args.rates.split(",")]
    load = os.getloadavg()[0]
    (folder / "ros2").mkdir()
    ros2 = Ros2Bench(folder / "ros2", python, document, folder / "rows.npy")
    ros2.lockstep = args.lockstep
    paths = (*PATHS, NUMPY_MONITOR) if args.numpy_too else PATHS
    results = run_rounds(
        rates,
        args.rounds,
        lambda path, rate: ros2.measure(path, rate, args.seconds, WARMUP),
        paths,
    )
    numba = numba_of(python)
    compiled = (
        "not compiled (IMROSC_NUMBA=0: numpy alone)"
        if os.environ.get("IMROSC_NUMBA", "1") == "0"
        else f"compiled by numba {numba}"
        if numba
        else f"not compiled (no numba for {python}: numpy alone)"
    )
    print(
        f"live ROS 2 Jazzy (rclpy, rmw_fastrtps, localhost), {ROS2_MSGTYPE}: a header and "
        f"{COLUMNS} float64 in position; {len(document['invariants'])} invariants on the "
        f"relayed topic; {args.rounds} x {args.seconds:g} s per path and rate after "
        f"{WARMUP:g} s of warm-up; latency = receipt - header.stamp; load average {load:.1f} "
        f"before, {os.getloadavg()[0]:.1f} after; the monitor's checks {compiled}"
        + ("; lockstep (a message once the last one arrived)" if args.lockstep else "")
    )
    report(results)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--rates", default="100,1000", help="Hz, comma-separated")
    parser.add_argument("--seconds", type=float, default=5.0, help="per run, after warm-up")
    parser.add_argument("--invariants", type=int, default=1000)
    parser.add_argument("--rounds", type=int, default=1, help="runs of each path, interleaved")
    parser.add_argument(
        "--middleware", default="ros1,ros2", help="ros1, ros2 or both (comma-separated)"
    )
    parser.add_argument(
        "--numpy-too",
        action="store_true",
        help=f"ROS 2: also the path {NUMPY_MONITOR!r}, the same monitor with IMROSC_NUMBA=0",
    )
    parser.add_argument(
        "--lockstep",
        action="store_true",
        help="ROS 2: the source sends the next message once the last one arrived",
    )
    args = parser.parse_args()
    chosen = [m.strip() for m in args.middleware.split(",") if m.strip()]
    if not chosen or set(chosen) - {"ros1", "ros2"}:
        sys.exit(f"--middleware: ros1, ros2 or both, not {args.middleware!r}")
    missing = ros_missing() if "ros1" in chosen else None
    if missing:
        sys.exit(f"no ROS 1 here: {missing} (--middleware ros2 measures ROS 2 alone)")
    python = None
    if "ros2" in chosen:
        from bench.latency_ros2 import ros2_python

        python = ros2_python()
        if python is None:
            sys.exit(
                "no ROS 2 here: set IMROSC_ROS2_PYTHON to a python with rclpy "
                "(tools/ros2_venv.sh builds one; --middleware ros1 measures ROS 1 alone)"
            )
    with tempfile.TemporaryDirectory(prefix="imrosc-latency-") as tmp:
        folder = Path(tmp)
        document, rows = invariants(args.invariants)
        np.save(folder / "rows.npy", rows)
        if "ros1" in chosen:
            bench_ros1(args, folder, document)
        if python is not None:
            if "ros1" in chosen:
                print()
            bench_ros2(args, folder, document, python)


def checks_compiled() -> str:
    """Whether the monitor's checks are compiled by numba (``imrosc/runtime/compiled.py``):
    numba importable by Debian's python, and not turned off by ``IMROSC_NUMBA=0``."""
    if os.environ.get("IMROSC_NUMBA", "1") == "0":
        return "not compiled (IMROSC_NUMBA=0: numpy alone)"
    version = ros_python_version_of("numba")
    if version is None:
        return "not compiled (no numba for Debian's python: numpy alone)"
    return f"compiled by numba {version}"


def report(results: dict[tuple[float, str], dict[str, Any]]) -> None:
    """The table: per rate and path, messages, median and p99, and (ROS 2) the CPU time the
    relay or monitor process used per message sent; monitor / plain relay."""
    print(
        f"{'rate':>8}  {'path':<12} {'received':>13}  {'median ms':>9}  {'p99 ms':>8}"
        f"  {'CPU us/msg':>10}"
    )
    figures: dict[tuple[float, str], tuple[float, float]] = {}
    for (rate, path), total in results.items():
        values = np.array(total["latencies"])
        median, p99 = (
            (float(np.median(values)), float(np.percentile(values, 99)))
            if len(values)
            else (float("nan"), float("nan"))
        )
        figures[(rate, path)] = median, p99
        received = f"{total['received']}/{total['sent']}"
        cpu = total["cpu"] / total["sent"] * 1e6 if total["sent"] else math.nan
        shown_cpu = "" if math.isnan(cpu) else f"{cpu:>10.0f}"
        print(f"{rate:>6g}Hz  {path:<12} {received:>13}  {median:>9.3f}  {p99:>8.3f}  {shown_cpu}")
        if path in ("monitor", NUMPY_MONITOR):
            for baseline, note in (("plain relay", "  (target: within 1.2x)"), ("raw relay", "")):
                base_median, base_p99 = figures[(rate, baseline)]
                print(
                    f"{'':>8}  {path} / {baseline}: median {median / base_median:.2f}x "
                    f"(+{median - base_median:.3f} ms), p99 {p99 / base_p99:.2f}x{note}"
                )
                paired = paired_ratios(total["rounds"], results[(rate, baseline)]["rounds"])
                if len(paired) > 1:
                    shown = ", ".join(f"{r:.2f}" for r in paired)
                    print(
                        f"{'':>8}    per round (medians of the same round): {shown}; "
                        f"their median {float(np.median(paired)):.2f}x"
                    )


def paired_ratios(monitor: list[float], baseline: list[float]) -> list[float]:
    """Round by round, the monitor's median over the baseline's: the two paths ran minutes
    apart at most, so a neighbour loading the shared machine for a while moves both."""
    return [m / b for m, b in zip(monitor, baseline, strict=True) if b > 0 and not math.isnan(m)]


if __name__ == "__main__":
    main()
