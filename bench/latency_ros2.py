"""The ROS 2 half of ``bench/monitor_latency.py``: the same four paths on live ROS 2 Jazzy.

The nodes are rclpy scripts run by the ROS 2 interpreter (``IMROSC_ROS2_PYTHON``, the
virtualenv ``tools/ros2_venv.sh`` builds: rclpy, rmw_fastrtps, colcon), on a DDS domain of
their own with discovery kept on the machine (``tests/backends/ros2_support.py``). ROS 2
message packages cannot be generated under those wheels (no rosidl generators), so the
message is ``sensor_msgs/msg/JointState``: a header and the 56 float64 values in
``position`` (``name``, ``velocity`` and ``effort`` empty), the ROS 1 bench's shape with a
sequence length in front of the values. The invariants are the ROS 1 bench's, their
variables read from ``position[0]`` .. ``position[55]``.

* ``direct``: source -> sink;
* ``plain relay``: a bare rclpy relay (``rclpy.spin``, a subscription that decodes, a
  publisher that encodes) -> sink (the target's baseline);
* ``raw relay``: the same relay with ``raw=True``: it republishes the CDR bytes;
* ``monitor``: the package ``imrosc build --backend ros2`` renders, built with ``colcon``,
  blocking the topic (it subscribes raw, reads the 56 values from the CDR bytes, checks
  them and republishes the same bytes on ``/m/bench/wide``: ``imrosc/onboard/monitor_ros2/cdr.py``),
  started as its installed console script; measured once it logged
  that its checks are compiled, where numba compiles them;
* ``monitor, numpy`` (``bench/monitor_latency.py --numpy-too``): the same with
  ``IMROSC_NUMBA=0``.

Every endpoint is reliable, volatile, keep-last 100 (the monitor's relay takes its source's
QoS, depth 100). The source is started first and waits for a go file; the harness writes it
once the sink matched a publisher (a matched event: a compatible QoS), a bare relay's
writer matched the sink, and the monitor's polls (every second, as in the ROS 1 bench) had
time to settle its QoS on the source's; the source then waits for its writer's side of the
match and publishes a pre-roll (``frame_id`` "pre", not counted) until the sink has heard
one. Each run has a DDS domain of its own. Latency =
receipt (the sink's ``time.time()``) - ``header.stamp`` (the source's ``time.time()`` right
before ``publish``).
"""

from __future__ import annotations

import json
import math
import os
import shutil
import signal
import subprocess
import sys
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

from tests.backends.ros2_support import Reader, private_domain, ros2_environment

TOPIC = "/bench/wide"
RELAYED = "/bench/relayed"
MSGTYPE = "sensor_msgs/msg/JointState"
PROJECT = "bench_latency"
MONITOR = f"{PROJECT}_monitor"
PATHS = ("direct", "plain relay", "raw relay", "monitor")
CONFIG = f"""<imROS project="{PROJECT}">
  <scope>
    <publish id="a">{TOPIC}</publish>
  </scope>
  <monitor inv="bench.inv">
    <block>{TOPIC}</block>
  </monitor>
</imROS>
"""

COMMON = r"""
import json, os, signal, sys, threading, time
import rclpy
from rclpy.executors import ExternalShutdownException
from rclpy.node import Node
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy
from sensor_msgs.msg import JointState

QOS = QoSProfile(
    history=HistoryPolicy.KEEP_LAST,
    depth=100,
    reliability=ReliabilityPolicy.RELIABLE,
    durability=DurabilityPolicy.VOLATILE,
)
args = json.loads(sys.argv[1])
rclpy.init()


def say(text):
    print(text, flush=True)


def spin(node):
    try:
        rclpy.spin(node)
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
"""

SOURCE = (
    COMMON
    + r"""
import numpy as np

node = Node("bench_source")
publisher = node.create_publisher(JointState, args["topic"], QOS)
rows = np.load(args["rows"]).tolist()
echoed = [None]
if args["echo"]:  # lockstep: the next message once the path delivered this one

    def on_echo(message):
        if message.header.frame_id != "pre":
            echoed[0] = (message.header.stamp.sec, message.header.stamp.nanosec)

    node.create_subscription(JointState, args["echo"], on_echo, QOS)
say("source up")
while not os.path.exists(args["go"]):
    time.sleep(0.01)
# the writer's side of the match (the readers may have matched it long before: DDS
# discovery is asymmetric, and a volatile writer drops what it publishes before)
while publisher.get_subscription_count() < 1:
    time.sleep(0.01)
message = JointState()
period = 1.0 / args["rate"]
# pre-roll, marked "pre" and not counted, until the harness saw the sink receive one: a
# relay's writer may match the sink seconds after the sink matched it
# (the rows in turn, as after it: the invariants follow the rows' sequence)
message.header.frame_id = "pre"
row = 0
deadline = time.monotonic() + 60.0
while not os.path.exists(args["start"]) and time.monotonic() < deadline:
    message.position = rows[row % len(rows)]
    row += 1
    publisher.publish(message)
    time.sleep(period)
message.header.frame_id = ""
start = time.monotonic()
end = start + args["seconds"]
k = 0
while time.monotonic() < end:
    message.position = rows[(row + k) % len(rows)]
    now = time.time()
    message.header.stamp.sec = int(now)
    message.header.stamp.nanosec = int((now - int(now)) * 1e9)
    publisher.publish(message)
    k += 1
    if args["echo"]:
        stamp = (message.header.stamp.sec, message.header.stamp.nanosec)
        waited = time.monotonic() + 0.5
        while echoed[0] != stamp and time.monotonic() < waited:
            rclpy.spin_once(node, timeout_sec=0.05)
    delay = start + k * period - time.monotonic()
    if delay > 0:
        time.sleep(delay)
with open(args["out"], "w") as out:
    out.write(f"{k}\n")
time.sleep(1.0)  # a reliable writer drops what was not acknowledged when it goes
node.destroy_node()
rclpy.try_shutdown()
"""
)

RELAY = (
    COMMON
    + r"""
node = Node("bench_relay")
raw = args["raw"]
publisher = node.create_publisher(JointState, args["output"], QOS)
node.create_subscription(JointState, args["input"], publisher.publish, QOS, raw=raw)
say("relay up")


def matched():
    while publisher.get_subscription_count() < 1:
        time.sleep(0.01)
    say("relay matched")


threading.Thread(target=matched, daemon=True).start()
if os.environ.get("IMROSC_BENCH_RELAY_EXECUTOR") == "multi":  # as the monitor spins
    from rclpy.executors import MultiThreadedExecutor

    executor = MultiThreadedExecutor(num_threads=4)
    executor.add_node(node)
    try:
        executor.spin()
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
else:
    spin(node)
node.destroy_node()
rclpy.try_shutdown()
"""
)

SINK = (
    COMMON
    + r"""
node = Node("bench_sink")
received, latencies, pre = [], [], []


def on_message(message):
    now = time.time()
    if message.header.frame_id == "pre":
        if not pre:
            say("sink heard the pre-roll")
        pre.append(now)
        return
    stamp = message.header.stamp
    latencies.append(now - (stamp.sec + stamp.nanosec * 1e-9))
    received.append(now)


from rclpy.event_handler import SubscriptionEventCallbacks

matched = [0]


def on_matched(info):
    matched[0] = info.current_count
    say(f"sink matched {info.current_count}")


events = SubscriptionEventCallbacks(matched=on_matched)
node.create_subscription(
    JointState, args["topic"], on_message, QOS, event_callbacks=events
)
say("sink up")
spin(node)
with open(args["out"], "w") as out:
    json.dump({"received": received, "latency": latencies}, out)
node.destroy_node()
rclpy.try_shutdown()
"""
)


def ros2_document(document: dict[str, Any]) -> dict[str, Any]:
    """The ROS 1 bench's invariants document with its topic's variables read from
    ``position[i]`` of a ``sensor_msgs/msg/JointState`` (the i-th float64 field)."""
    copy: dict[str, Any] = json.loads(json.dumps(document))
    copy["topics"][TOPIC]["type"] = MSGTYPE
    layouts = [copy["topics"][TOPIC]["variables"]]
    layouts += [point["variables"] for point in copy["points"].values()]
    for layout in layouts:
        for index, variable in enumerate(layout):
            variable["path"] = f"position[{index}]"
    return copy


class Ros2Bench:
    """The ROS 2 graph of the bench: the monitor package built, the nodes' scripts written,
    one process per node, each stopped with SIGINT."""

    def __init__(self, folder: Path, python: str, document: dict[str, Any], rows: Path) -> None:
        self.folder = folder
        self.python = python
        self.bin = Path(python).parent
        self.rows = rows
        self.runs = 0
        self.profile: Path | None = None
        """A folder: the monitor runs under cProfile, its statistics written there."""
        self.lockstep = False
        """The source publishes the next message once it heard this one at the path's end
        (or after 0.5 s), at most at the rate: every message crosses the path alone, so the
        relay's CPU time per message does not depend on how far the machine's load let it
        fall behind (it takes the messages that piled up at once, which costs less)."""
        self.scripts: dict[str, Path] = {}
        for name, text in (("source", SOURCE), ("relay", RELAY), ("sink", SINK)):
            self.scripts[name] = folder / f"bench_{name}.py"
            self.scripts[name].write_text(text, encoding="utf-8")
        self.install = self.build_monitor(ros2_document(document))
        prefixes = os.pathsep.join((str(self.install), str(self.bin.parent)))
        # what install/setup.sh would add: the package's prefix and its Python packages
        site = sorted(str(p) for p in self.install.glob("lib/python3*/site-packages"))
        self.env = ros2_environment(
            folder,
            AMENT_PREFIX_PATH=prefixes,
            PYTHONPATH=os.pathsep.join(site),
            OPENBLAS_NUM_THREADS="1",
        )
        self.run_env = self.env

    def build_monitor(self, document: dict[str, Any]) -> Path:
        """``imrosc build --backend ros2``, then ``colcon build``; the package's prefix."""
        from imrosc.invariants import dumps

        (self.folder / "bench.inv").write_text(dumps(document), encoding="utf-8")
        config = self.folder / "bench.xml"
        config.write_text(CONFIG, encoding="utf-8")
        workspace = self.folder / "ws"
        command = [sys.executable, "-m", "imrosc", "build", str(config), "--backend", "ros2"]
        root = Path(__file__).resolve().parent.parent
        subprocess.run(
            [*command, "-o", str(workspace / "src")], check=True, capture_output=True, cwd=root
        )
        colcon = self.bin / "colcon"
        if not colcon.exists():
            sys.exit(f"no colcon in {self.bin} (tools/ros2_venv.sh installs it)")
        env = {**os.environ, "PATH": f"{self.bin}{os.pathsep}{os.environ.get('PATH', '')}"}
        env["AMENT_PREFIX_PATH"] = str(self.bin.parent)
        done = subprocess.run(
            [str(colcon), "build", "--base-paths", "src"],
            cwd=workspace,
            env=env,
            capture_output=True,
            text=True,
            check=False,
            timeout=300,
        )
        if done.returncode != 0:
            sys.exit(f"colcon build failed:\n{done.stdout}{done.stderr}")
        return workspace / "install" / MONITOR

    def node(self, name: str, **args: Any) -> Reader:
        command = [self.python, str(self.scripts[name]), json.dumps(args)]
        return Reader(command, self.run_env)

    def measure(self, path: str, rate: float, seconds: float, warmup: float) -> dict[str, Any]:
        """One run of ``path`` at ``rate``: messages sent and received, latencies (ms) after
        the warm-up."""
        self.runs += 1
        # the run's number in every file name: the go and start files of an earlier round
        # of the same path and rate would start the source at once, before the path is up
        # (the messages lost at the start of every run after the first round, on every path)
        tag = f"{self.runs}-{path.replace(' ', '_')}-{rate:g}"
        go = self.folder / f"go-{tag}"
        out = self.folder / f"sink-{tag}.json"
        sent_file = self.folder / f"sent-{tag}"
        started: list[Reader] = []
        # a DDS domain of its own: the endpoints of the previous run, which the others may
        # still count until their lease ends, must not count as this run's matches, nor
        # may a test's graph on this machine
        self.run_env = {**self.env, "ROS_DOMAIN_ID": str(private_domain())}
        sink_topic = {"direct": TOPIC, "plain relay": RELAYED, "raw relay": RELAYED}.get(
            path, "/m" + TOPIC
        )
        try:
            source = self.node(
                "source",
                echo=sink_topic if self.lockstep else "",
                topic=TOPIC,
                rows=str(self.rows),
                rate=rate,
                seconds=seconds + warmup,
                go=str(go),
                start=str(go.with_name(f"start-{tag}")),
                out=str(sent_file),
            )
            started.append(source)
            source.wait_for("source up", 60)
            if path in ("plain relay", "raw relay"):
                relay = self.node("relay", input=TOPIC, output=RELAYED, raw=path == "raw relay")
                started.append(relay)
                relay.wait_for("relay up", 60)
            elif path in ("monitor", "monitor, numpy"):
                script = self.install / "lib" / MONITOR / MONITOR
                command = [str(script)]
                if self.profile is not None:  # under cProfile, one file per run
                    stats = self.profile / f"monitor-{tag}.prof"
                    command = [self.python, "-m", "cProfile", "-o", str(stats), str(script)]
                environment = self.run_env
                if path == "monitor, numpy":
                    environment = {**self.run_env, "IMROSC_NUMBA": "0"}
                monitor = Reader(command, environment)
                started.append(monitor)
                line = monitor.wait_for(f"imrosc monitor /{MONITOR}: checking", 120)
                if "compiles the checks" in line:  # numba compiles them in the background
                    monitor.wait_for("imrosc: compiled checks in use", 120)
            sink = self.node("sink", topic=sink_topic, out=str(out))
            started.append(sink)
            sink.wait_for("sink matched 1", 60)  # a publisher of a compatible QoS
            if path in ("plain relay", "raw relay"):
                started[1].wait_for("relay matched", 60)  # and the relay's side of it
            time.sleep(2.5)  # the monitor's polls (its period: 1 s) settled its QoS
            if sink.lines[-1] != "sink matched 1":  # its relay was made anew: match again
                _wait(lambda: sink.lines[-1] == "sink matched 1", 30)
                time.sleep(0.5)
            go.write_text("go\n")
            try:
                sink.wait_for("sink heard the pre-roll", 60)
            except AssertionError:  # counted anyway: the run's received count shows it
                print(f"{tag}: the sink did not hear the pre-roll in 60 s", file=sys.stderr)
            middle = started[1] if len(started) > 2 else None  # a relay or the monitor
            go.with_name(f"start-{tag}").write_text("start\n")
            cpu_before = cpu_seconds(middle.popen.pid) if middle is not None else math.nan
            # the source writes the count once it published the last message
            _wait(sent_file.exists, seconds + warmup + 90, 0.01)
            cpu = cpu_seconds(middle.popen.pid) - cpu_before if middle is not None else math.nan
            _wait(lambda: source.popen.poll() is not None, 90)
            time.sleep(1.0)  # the last messages through a relay that fell behind
            sink.stop(signal.SIGINT, timeout=30)
            record = json.loads(out.read_text(encoding="utf-8"))
            sent = int(sent_file.read_text(encoding="utf-8"))
        finally:
            for process in reversed(started):
                process.stop(signal.SIGINT, timeout=20)
                process.kill()
        first = record["received"][0] if record["received"] else 0.0
        kept = [
            latency * 1e3
            for latency, received in zip(record["latency"], record["received"], strict=True)
            if received >= first + warmup
        ]
        return {
            "received": len(record["latency"]),
            "sent": sent,
            "latencies": kept,
            "cpu": cpu,
        }


def cpu_seconds(pid: int) -> float:
    """The CPU time (user and system, all threads) process ``pid`` has used so far, from
    ``/proc``: what a relay costs per message, which the machine's other load does not
    change as it changes latencies."""
    fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")


def _wait(done: Callable[[], bool], timeout: float, every: float = 0.05) -> None:
    deadline = time.monotonic() + timeout
    while not done():
        if time.monotonic() > deadline:
            raise TimeoutError("the source did not finish")
        time.sleep(every)


def ros2_python() -> str | None:
    """The interpreter with rclpy (``IMROSC_ROS2_PYTHON``, else the virtualenv's default
    place), or ``None``."""
    candidates = [
        os.environ.get("IMROSC_ROS2_PYTHON"),
        str(Path.home() / ".cache" / "imrosc" / "ros2-jazzy" / "bin" / "python"),
    ]
    for candidate in candidates:
        if candidate and shutil.which(candidate):
            probe = subprocess.run(
                [candidate, "-c", "import rclpy, sensor_msgs.msg"], capture_output=True, check=False
            )
            if probe.returncode == 0:
                return candidate
    return None


def numba_of(python: str) -> str | None:
    """numba's version under ``python``, or ``None``."""
    probe = subprocess.run(
        [python, "-c", "import numba; print(numba.__version__)"],
        check=False,
        capture_output=True,
        text=True,
    )
    return probe.stdout.strip() if probe.returncode == 0 else None
