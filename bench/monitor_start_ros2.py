"""How soon the generated ROS 2 monitor relays after it starts, and what numba's compiling of
its checks costs the relay meanwhile.

    python bench/monitor_start_ros2.py [--rounds 3] [--rate 100] [--seconds 8]

The graph of ``bench/latency_ros2.py`` (its 1,000 invariants on a ``sensor_msgs/msg/JointState``
of 56 values, the monitor package built with colcon, blocking the topic): a source publishes
at ``--rate`` all along and a sink listens on the relay ``/m/bench/wide``; then the monitor is
started, once per case in each of ``--rounds`` rounds, each time for ``--seconds``. Cases:

* ``numpy``: ``IMROSC_NUMBA=0`` (numpy checks every sample, as without numba);
* ``numba, first start``: numba's cache of the kernel removed from the install space first
  (the kernel is compiled: the first start after a build);
* ``numba, cached``: the next start (numba loads the kernel from its cache).

Printed per start: seconds from the monitor's start to its start-up line (``checking``), to
the first message the sink received through it, and to the line saying the compiled checks
are in use; the median latency (receipt - stamp) of the messages relayed before that line
and after it. The node compiles in a thread of its own once it relays, so the first relayed
message should come as soon with numba as without (the compiling shows in the latency of the
messages relayed meanwhile, not in when they start). Needs the ROS 2 virtualenv with numba
(``tools/ros2_venv.sh``; ``IMROSC_ROS2_PYTHON``).
"""

from __future__ import annotations

import argparse
import json
import re
import signal
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from bench.latency_ros2 import COMMON, MONITOR, TOPIC, Ros2Bench, ros2_python  # noqa: E402
from bench.monitor_latency import invariants  # noqa: E402
from tests.backends.ros2_support import Reader  # noqa: E402

SOURCE = (
    COMMON
    + r"""
import numpy as np

node = Node("start_source")
publisher = node.create_publisher(JointState, args["topic"], QOS)
rows = np.load(args["rows"]).tolist()
say("source up")
message = JointState()
period = 1.0 / args["rate"]
start = time.monotonic()
k = 0
try:
    while True:
        message.position = rows[k % len(rows)]
        now = time.time()
        message.header.stamp.sec = int(now)
        message.header.stamp.nanosec = int((now - int(now)) * 1e9)
        publisher.publish(message)
        k += 1
        delay = start + k * period - time.monotonic()
        if delay > 0:
            time.sleep(delay)
except KeyboardInterrupt:
    pass
node.destroy_node()
rclpy.try_shutdown()
"""
)
SINK = (
    COMMON
    + r"""
node = Node("start_sink")
received = []


def on_message(message):
    stamp = message.header.stamp
    received.append((time.time(), stamp.sec + stamp.nanosec * 1e-9))


node.create_subscription(JointState, args["topic"], on_message, QOS)
say("sink up")
spin(node)
with open(args["out"], "w") as out:
    json.dump(received, out)
node.destroy_node()
rclpy.try_shutdown()
"""
)
STAMP = re.compile(r"\[(\d+\.\d+)\]")
"""The wall time rclpy's console output gives each log line."""


def logged_at(lines: list[str], text: str) -> float | None:
    """The time stamp of the first log line containing ``text``."""
    for line in lines:
        if text in line:
            found = STAMP.search(line)
            return float(found.group(1)) if found else None
    return None


def one_start(
    bench: Ros2Bench, folder: Path, run: str, args: argparse.Namespace, numba: bool
) -> Any:
    """Start the monitor under a running source and sink; the figures of that start."""
    out = folder / f"sink-{run}.json"
    env = dict(bench.env)
    if not numba:
        env["IMROSC_NUMBA"] = "0"
    bench.run_env = env
    started: list[Reader] = []
    try:
        source = bench.node("source", topic=TOPIC, rows=str(bench.rows), rate=args.rate)
        started.append(source)
        sink = bench.node("sink", topic="/m" + TOPIC, out=str(out))
        started.append(sink)
        source.wait_for("source up", 60)
        sink.wait_for("sink up", 60)
        time.sleep(2.0)
        begun = time.time()
        monitor = Reader([str(bench.install / "lib" / MONITOR / MONITOR)], env)
        started.append(monitor)
        time.sleep(args.seconds)
        monitor.stop(signal.SIGINT, timeout=20)
        sink.stop(signal.SIGINT, timeout=20)
        received = json.loads(out.read_text(encoding="utf-8"))
    finally:
        for process in reversed(started):
            process.stop(signal.SIGINT, timeout=20)
            process.kill()
    checking = logged_at(monitor.lines, f"imrosc monitor /{MONITOR}: checking")
    compiled = logged_at(monitor.lines, "compiled checks in use")
    first = received[0][0] if received else None
    before = [(r - s) * 1e3 for r, s in received if compiled is None or r < compiled]
    after = [(r - s) * 1e3 for r, s in received if compiled is not None and r >= compiled]
    return {
        "checking": None if checking is None else checking - begun,
        "first": None if first is None else first - begun,
        "compiled": None if compiled is None else compiled - begun,
        "received": len(received),
        "before": float(np.median(before)) if before else None,
        "after": float(np.median(after)) if after else None,
        "log": [line for line in monitor.lines if "imrosc" in line],
    }


def show(value: float | None, unit: str = "s") -> str:
    return "-" if value is None else f"{value:.2f} {unit}"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--rounds", type=int, default=3, help="starts of each case")
    parser.add_argument("--rate", type=float, default=100.0, help="the source's rate (Hz)")
    parser.add_argument("--seconds", type=float, default=8.0, help="each start runs this long")
    args = parser.parse_args()
    python = ros2_python()
    if python is None:
        sys.exit("no ROS 2 here: set IMROSC_ROS2_PYTHON (tools/ros2_venv.sh builds one)")
    with tempfile.TemporaryDirectory(prefix="imrosc-start-") as tmp:
        folder = Path(tmp)
        document, rows = invariants(1000)
        np.save(folder / "rows.npy", rows)
        bench = Ros2Bench(folder, python, document, folder / "rows.npy")
        for name, text in (("source", SOURCE), ("sink", SINK)):
            bench.scripts[name].write_text(text, encoding="utf-8")
        caches = list(bench.install.glob("lib/python3*/site-packages/*/imrosc/runtime"))
        print(
            f"live ROS 2 Jazzy, {MONITOR} (1,000 invariants), the source at {args.rate:g} Hz; "
            f"seconds from the monitor's start; median latency of the relayed messages before "
            f"and after the compiled checks took over"
        )
        print(
            f"{'case':<20} {'checking':>9} {'first relayed':>14} {'compiled':>9} "
            f"{'received':>9} {'before':>9} {'after':>9}"
        )
        cases = [("numpy", False, False), ("numba, first start", True, True)]
        cases += [("numba, cached", True, False)]
        for round_ in range(args.rounds):
            for name, numba, cold in cases:
                if cold:
                    for cache in caches:
                        for stale in cache.glob("__pycache__/compiled.clears-*"):
                            stale.unlink()
                run = f"{round_}-{name.replace(' ', '_').replace(',', '')}"
                got = one_start(bench, folder, run, args, numba)
                print(
                    f"{name:<20} {show(got['checking']):>9} {show(got['first']):>14} "
                    f"{show(got['compiled']):>9} {got['received']:>9} "
                    f"{show(got['before'], 'ms'):>9} {show(got['after'], 'ms'):>9}",
                    flush=True,
                )
                if got["first"] is None:
                    print("\n".join(got["log"]), flush=True)


if __name__ == "__main__":
    main()
