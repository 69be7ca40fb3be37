"""What the recording node's service relay adds to a service call's latency, on live ROS 1.

    python bench/record.py [--calls 2000]

Needs Debian's ROS 1: a roscore on a free port of 127.0.0.1 (the live tests' harness,
``tests/live/harness.py``), rospy nodes under ``/usr/bin/python3``. One server node serves
the same handler (``imrosc_rec_test/Scale``, generated with genpy; it answers at once) under
two names: ``/bench/direct``, which nothing relays, and ``/rec/bench/relayed``, the remapped
name of ``/bench/relayed``, which ``imrosc record`` relays and records while the client runs.
The client calls both, alternating in blocks of 50 so that both see the same machine load,
in two ways rospy clients call services:

* ``persistent``: one ``ServiceProxy(persistent=True)``, one connection for every call;
* ``per call``: a new proxy per call (rospy's default: master lookup, connect, call).

Printed: median and 99th percentile of the call time as the client sees it, the relay's
overhead (difference of the medians), and how many relayed calls the bag holds (every one
must be there). The first 100 calls of each kind are warm-up and not counted.
"""

from __future__ import annotations

import argparse
import json
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from imrosc import records  # noqa: E402
from imrosc.bags import open_bag  # noqa: E402
from tests.live.harness import ROS_PYTHON, Ros, ros_missing, wait_until  # noqa: E402
from tests.live.record_support import generate_service_type  # noqa: E402

DIRECT = "/bench/direct"
RELAYED = "/bench/relayed"
WARMUP = 100
BLOCK = 50

SERVER = """
import rospy
from imrosc_rec_test.srv import Scale, ScaleResponse

def scale(request):
    return ScaleResponse(y=2.0 * request.x * request.k, note="ok")

rospy.init_node("bench_server")
rospy.Service("%(direct)s", Scale, scale)
rospy.Service("/rec%(relayed)s", Scale, scale)
rospy.spin()
"""

CLIENT = """
import json, sys, time
import rospy
from imrosc_rec_test.srv import Scale

calls, block = int(sys.argv[1]), int(sys.argv[2])
rospy.init_node("bench_client")
names = {"direct": "%(direct)s", "relayed": "%(relayed)s"}
for name in names.values():
    rospy.wait_for_service(name, timeout=30)
proxies = {k: rospy.ServiceProxy(n, Scale, persistent=True) for k, n in names.items()}
times = {f"{k} {mode}": [] for k in names for mode in ("persistent", "per call")}
clock = time.perf_counter
for mode in ("persistent", "per call"):
    for start in range(0, calls, block):
        for key, name in names.items():
            out = times[f"{key} {mode}"]
            for i in range(start, min(calls, start + block)):
                proxy = proxies[key] if mode == "persistent" else rospy.ServiceProxy(name, Scale)
                began = clock()
                proxy(x=float(i %% 5), k=1 + i %% 3)
                out.append(clock() - began)
print(json.dumps(times))
"""

CONFIG = f"""<imROS project="bench_record">
  <scope><call id="c">{RELAYED}</call></scope>
</imROS>
"""


def percentiles(values: list[float]) -> tuple[float, float]:
    """Median and 99th percentile in milliseconds, warm-up left out."""
    kept = np.array(values[WARMUP:]) * 1e3
    return float(np.median(kept)), float(np.percentile(kept, 99))


def relayed_calls(bag: Path) -> int:
    with open_bag(bag) as reader:
        return sum(c.msgcount for c in reader.connections if c.topic == records.SRVS_TOPIC)


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--calls", type=int, default=2000, help="calls per path and mode")
    options = parser.parse_args()
    missing = ros_missing()
    if missing:
        print(f"bench/record.py: cannot run: {missing}", file=sys.stderr)
        return 1
    values = {"direct": DIRECT, "relayed": RELAYED}
    with tempfile.TemporaryDirectory(prefix="imrosc-bench-record-") as scratch:
        home = Path(scratch)
        ros = Ros(home / "ros")
        try:
            ros.start()
            ros.env["PYTHONPATH"] = str(generate_service_type(home / "srv"))
            server = ros.spawn("bench_server", [str(ROS_PYTHON), "-c", SERVER % values])
            wait_until(
                lambda: {DIRECT, "/rec" + RELAYED} <= set(ros.system_state().services),
                "the bench server",
                30,
                (server,),
            )
            config = home / "bench.xml"
            config.write_text(CONFIG)
            out, err = (home / "record.out").open("w"), (home / "record.err").open("w")
            recorder = subprocess.Popen(
                [sys.executable, "-m", "imrosc", "record", str(config), "-o", str(home / "bag")],
                cwd=ROOT,
                env=ros.env,
                stdout=out,
                stderr=err,
            )
            wait_until(
                lambda: (
                    "recording " in (home / "record.out").read_text() or recorder.poll() is not None
                ),
                "imrosc record",
                60,
            )
            if recorder.poll() is not None:
                print((home / "record.err").read_text(), file=sys.stderr)
                return 1
            wait_until(lambda: RELAYED in ros.system_state().services, "the relay", 30)
            started = time.monotonic()
            client = subprocess.run(
                [str(ROS_PYTHON), "-c", CLIENT % values, str(options.calls), str(BLOCK)],
                env=ros.env,
                capture_output=True,
                text=True,
                check=False,
                timeout=3600,
            )
            seconds = time.monotonic() - started
            recorder.send_signal(signal.SIGINT)
            recorder.wait(120)
            if client.returncode:
                print(client.stderr, file=sys.stderr)
                return 1
            times: dict[str, list[float]] = json.loads(client.stdout.strip().splitlines()[-1])
            stored = relayed_calls(home / "bag" / "bench_record.bag")
        finally:
            ros.shutdown()
    report(times, options.calls, stored, seconds)
    return 0


def report(times: dict[str, Any], calls: int, stored: int, seconds: float) -> None:
    print(f"service-call latency, {calls} calls per row ({WARMUP} warm-up calls not counted)")
    print(f"{'path':<22}{'median ms':>11}{'p99 ms':>10}")
    figures = {key: percentiles(values) for key, values in times.items()}
    for key, (median, p99) in figures.items():
        print(f"{key:<22}{median:>11.3f}{p99:>10.3f}")
    for mode in ("persistent", "per call"):
        direct, relayed = figures[f"direct {mode}"], figures[f"relayed {mode}"]
        print(
            f"relay overhead, {mode}: median +{relayed[0] - direct[0]:.3f} ms, "
            f"p99 +{relayed[1] - direct[1]:.3f} ms"
        )
    expected = 2 * calls
    print(f"relayed calls in the bag: {stored} of {expected} ({seconds:.1f} s of calls)")


if __name__ == "__main__":
    sys.exit(main())
