"""``imrosc record --ros2`` on a real ROS 2 graph, then ``imrosc infer`` on its MCAP bag.

The system (one rclpy process, :data:`SYSTEM`): ``/sys/server`` publishes ``/sys/level``
best effort at 20 Hz, serves ``/sys/switch`` (``std_srvs/srv/SetBool``) and declares the
parameter ``gain``; ``/sys/client`` listens to ``/sys/level``, publishes a counter on
``/sys/cmd`` (reliable) for each level it hears and calls ``/sys/switch`` twice a second,
asking off and on in turn.
Both enable service introspection with contents. ``imrosc record`` runs as a user runs it
(its own process, the graph's environment, the ROS 2 Python named by
``IMROSC_ROS2_PYTHON``) and is stopped with SIGINT in the middle of the traffic, as Ctrl-C
does. Then the bag is read with rosbags (through :func:`imrosc.bags.open_bag`) and
``imrosc infer`` learns from it.
"""

from __future__ import annotations

import contextlib
import json
import os
import signal
import subprocess
import sys
import time
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any, cast

import pytest
from rosbags.typesys import Stores, get_typestore

from imrosc import records
from imrosc.bags import open_bag
from tests.backends.ros2_support import Reader, require_ros2, ros2_environment

pytestmark = pytest.mark.live

ROOT = Path(__file__).resolve().parent.parent.parent
JAZZY = get_typestore(Stores.ROS2_JAZZY)

SYSTEM = r"""
import rclpy
from rclpy.executors import ExternalShutdownException, MultiThreadedExecutor
from rclpy.node import Node
from rclpy.qos import QoSProfile, ReliabilityPolicy, qos_profile_system_default
from rclpy.service_introspection import ServiceIntrospectionState
from std_msgs.msg import Float64
from std_srvs.srv import SetBool

rclpy.init()
server = Node("server", namespace="/sys")
server.declare_parameter("gain", 2.5)
client = Node("client", namespace="/sys")
CONTENTS = ServiceIntrospectionState.CONTENTS
BEST_EFFORT = QoSProfile(depth=10, reliability=ReliabilityPolicy.BEST_EFFORT)
level = server.create_publisher(Float64, "/sys/level", BEST_EFFORT)


def serve(request, response):
    response.success = request.data
    response.message = "on" if request.data else "off"
    return response


service = server.create_service(SetBool, "/sys/switch", serve)
service.configure_introspection(server.get_clock(), qos_profile_system_default, CONTENTS)
cmd = client.create_publisher(Float64, "/sys/cmd", 100)
sent = [0]


def on_level(message):
    sent[0] += 1
    cmd.publish(Float64(data=float(sent[0])))


client.create_subscription(Float64, "/sys/level", on_level, BEST_EFFORT)
caller = client.create_client(SetBool, "/sys/switch")
caller.configure_introspection(client.get_clock(), qos_profile_system_default, CONTENTS)
ticks = [0]
calls = [0]


def tick():
    ticks[0] += 1
    level.publish(Float64(data=float(ticks[0] % 10)))


def call():
    if caller.service_is_ready():
        # off and on in turn, whatever the timers' timing: both answers ("off", "on") are in
        # the bag from its second call on, so inference justifies their string one-of with
        # three calls. (Read from the 20 Hz tick count, the request depended on which of two
        # timers due at the same instants the executor ran first: a bag could hold one
        # answer until its last call, and a one-of whose set changed on the last sample is
        # not justified.)
        calls[0] += 1
        caller.call_async(SetBool.Request(data=calls[0] % 2 == 0))


server.create_timer(0.05, tick)
client.create_timer(0.5, call)
executor = MultiThreadedExecutor()
executor.add_node(server)
executor.add_node(client)
print("system up", flush=True)
try:
    executor.spin()
except (KeyboardInterrupt, ExternalShutdownException):
    pass
"""

CONFIG = """<imROS project="recsys2">
  <scope>
    <publish id="a" relative="1">/sys/cmd</publish>
    <publish id="b"><topic>/sys/level</topic><param>/sys/server/gain</param></publish>
    <call id="c">/sys/switch</call>
    <param id="p">/sys/server/gain</param>
    <arch id="d"/>
  </scope>
  <detect inv="recsys2.inv" confidence="0.5" budget="0"><bag>rec</bag></detect>
</imROS>
"""


@dataclass
class Run:
    """A finished ``imrosc record --ros2``: its status, output and bag."""

    status: int
    output: str
    bag: Path
    folder: Path
    environment: dict[str, str]
    leftovers: list[int]


def imrosc(*args: str, env: dict[str, str]) -> Reader:
    """``imrosc`` as a user runs it, from this checkout."""
    return Reader([sys.executable, "-m", "imrosc", *args], env, cwd=ROOT)


def children_of(pid: int) -> list[int]:
    """The processes still running that ``imrosc record`` (pid ``pid``) started: its bag tap
    and recorder node, named after it."""
    names = (f"_imrosc_bag_{pid}".encode(), f"imrosc_recorder_{pid}".encode())
    found = []
    for entry in Path("/proc").iterdir():
        if not entry.name.isdigit():
            continue
        try:
            command = (entry / "cmdline").read_bytes()
        except OSError:
            continue
        if any(name in command for name in names):
            found.append(int(entry.name))
    return found


@dataclass
class System:
    """The running system and the environment of its ROS 2 graph."""

    folder: Path
    environment: dict[str, str]


@pytest.fixture(scope="module")
def system(tmp_path_factory: pytest.TempPathFactory) -> Iterator[System]:
    python = require_ros2()
    folder = tmp_path_factory.mktemp("ros2record")
    environment = ros2_environment(folder, IMROSC_ROS2_PYTHON=python)
    environment.pop("ROS_VERSION", None)
    (folder / "recsys2.xml").write_text(CONFIG, encoding="utf-8")
    process = Reader([python, "-c", SYSTEM], environment)
    try:
        process.wait_for("system up", 60)
        time.sleep(1.0)
        yield System(folder, environment)
    finally:
        process.stop(signal.SIGINT)


@contextlib.contextmanager
def recording(system: System, out: str, *args: str) -> Iterator[Reader]:
    """``imrosc record --ros2`` into ``out``, killed with what it started if it outlives
    the block."""
    config = str(system.folder / "recsys2.xml")
    process = imrosc(
        "record", config, "-o", str(system.folder / out), "--ros2", *args, env=system.environment
    )
    try:
        yield process
    finally:
        for pid in children_of(process.popen.pid):
            os.kill(pid, signal.SIGKILL)
        process.kill()


@pytest.fixture(scope="module")
def run(system: System) -> Iterator[Run]:
    with recording(system, "rec") as process:
        process.wait_for("recording ", 90)
        # calls are recorded once the recorder has discovered the service's event topic,
        # which takes seconds on a loaded machine: 6 s leave room for at least 3 of the
        # client's 12 calls
        time.sleep(6.0)
        status = process.stop(signal.SIGINT, timeout=60)  # Ctrl-C, with messages flowing
        leftovers = children_of(process.popen.pid)
        yield Run(
            status,
            process.output,
            system.folder / "rec" / "recsys2",
            system.folder,
            system.environment,
            leftovers,
        )


def test_ctrl_c_stops_the_recording_cleanly(run: Run) -> None:
    assert run.status == 0, run.output
    assert "Traceback" not in run.output
    assert run.leftovers == [], run.output
    assert "stopping..." in run.output
    assert "not in the bag" not in run.output  # every message the tap received is in it
    assert "warning" not in run.output, run.output
    assert f"wrote {run.bag}: " in run.output
    assert sorted(p.name for p in run.bag.iterdir()) == ["metadata.yaml", "recsys2.mcap"]


def messages(bag: Path) -> dict[str, list[tuple[int, Any]]]:
    found: dict[str, list[tuple[int, Any]]] = {}
    with open_bag(bag) as reader:
        for connection, stamp, raw in reader.messages():
            value = reader.deserialize(raw, connection.msgtype)
            found.setdefault(connection.topic, []).append((stamp, value))
    return found


def test_the_bag_holds_the_scope_s_topics_with_their_types_and_qos(run: Run) -> None:
    with open_bag(run.bag) as reader:
        connections = {c.topic: c for c in reader.connections}
    assert set(connections) == {"/sys/cmd", "/sys/level", *records.RECORD_TOPICS}
    for topic in ("/sys/cmd", "/sys/level"):
        assert connections[topic].msgtype == "std_msgs/msg/Float64"
        assert connections[topic].digest == JAZZY.hash_rihs01("std_msgs/msg/Float64")
    level = connections["/sys/level"].ext.offered_qos_profiles  # type: ignore[union-attr]
    assert [q.reliability.name for q in level] == ["BEST_EFFORT"]
    arch = connections[records.ARCH_TOPIC].ext.offered_qos_profiles  # type: ignore[union-attr]
    assert [q.durability.name for q in arch] == ["TRANSIENT_LOCAL"]


def test_nothing_received_before_ctrl_c_is_lost(run: Run) -> None:
    found = messages(run.bag)
    counter = [cast(Any, value).data for _, value in found["/sys/cmd"]]
    assert len(counter) >= 20, run.output
    # reliable: from the first message the tap heard, every one up to the last is there
    assert counter == [float(k) for k in range(int(counter[0]), int(counter[-1]) + 1)]
    stamps = [stamp for stamp, _ in found["/sys/cmd"]]
    assert stamps == sorted(stamps)  # receive times
    assert len(found["/sys/level"]) >= 20


def test_the_records_are_the_system_s_graph_parameters_and_calls(run: Run) -> None:
    found = messages(run.bag)
    archs = [records.decode_arch(cast(Any, v).data) for _, v in found[records.ARCH_TOPIC]]
    last = archs[-1]
    assert last.services.get("/sys/switch") == frozenset({"/sys/server"})
    assert last.topics["/sys/level"].pubs == frozenset({"/sys/server"})
    assert last.topics["/sys/level"].subs == frozenset({"/sys/client"})
    assert last.topics["/sys/cmd"].pubs == frozenset({"/sys/client"})
    names = {n for a in archs for t in a.topics.values() for n in t.pubs | t.subs}
    assert not any("imrosc" in name for name in names)  # the tap and the recorder are not the robot
    params = [records.decode_params(cast(Any, v).data) for _, v in found[records.PARAMS_TOPIC]]
    assert params[-1].params == {"/sys/server/gain": 2.5}
    calls = [records.decode_call(cast(Any, v).data) for _, v in found[records.SRVS_TOPIC]]
    assert len(calls) >= 3, run.output
    stamps = sorted(call.stamp for call in calls)  # one record a call (made every 0.5 s)
    assert len(stamps) <= (stamps[-1] - stamps[0]) / 0.5 + 2, stamps
    for call in calls:
        assert (call.service, call.client, call.server, call.ok) == (
            "/sys/switch",
            "/sys/client",
            "/sys/server",
            True,
        )
        assert call.response == {
            "success": call.request["data"],
            "message": "on" if call.request["data"] else "off",
        }


def test_imrosc_info_and_infer_read_the_bag(run: Run) -> None:
    info = subprocess.run(
        [sys.executable, "-m", "imrosc", "info", str(run.bag), "--format", "json"],
        cwd=ROOT,
        capture_output=True,
        text=True,
        check=False,
    )
    assert info.returncode == 0, info.stderr
    assert "/sys/cmd" in info.stdout
    inferred = subprocess.run(
        # --budget 0: what the bag holds, not how calibration splits a few seconds of it
        [
            *(sys.executable, "-m", "imrosc", "infer", str(run.folder / "recsys2.xml")),
            *("-j", "1", "--budget", "0"),
        ],
        cwd=ROOT,
        capture_output=True,
        text=True,
        check=False,
    )
    assert inferred.returncode == 0, inferred.stdout + inferred.stderr
    document = json.loads((run.folder / "recsys2.inv").read_text())
    points = document["points"]
    assert points["a"]["inputs"] == ["/sys/level"]  # relative=1 from the live ROS 2 graph
    assert points["c"]["kind"] == "call" and points["c"]["support"]["samples"] >= 3
    assert points["b"]["params"] == ["/sys/server/gain"]
    found = {(i["point"], i["family"]) for i in document["invariants"]}
    assert {("a", "bounds"), ("b", "frequency"), ("c", "string-one-of")} <= found, found
    assert ("d", "architecture") in found and ("p", "one-of") in found, found
    gain = [i for i in document["invariants"] if i["point"] == "p"]
    assert "2.5" in gain[0]["text"], gain


def test_the_duration_ends_the_recording(system: System) -> None:
    with recording(system, "timed", "--duration", "2", "--name", "short") as process:
        process.popen.wait(90)
        process.read_to_the_end()
        status = process.popen.returncode
        assert status == 0, process.output
        assert "for 2 s" in process.output
        assert children_of(process.popen.pid) == []
    found = messages(system.folder / "timed" / "short")
    assert len(found["/sys/level"]) >= 10
    assert found[records.ARCH_TOPIC]


def test_a_killed_tap_fails_the_recording_and_keeps_what_it_sent(system: System) -> None:
    with recording(system, "killed") as process:
        process.wait_for("recording ", 90)
        time.sleep(1.5)
        taps = [p for p in children_of(process.popen.pid) if b".tap" in cmdline(p)]
        assert len(taps) == 1
        os.kill(taps[0], signal.SIGKILL)
        process.popen.wait(60)
        process.read_to_the_end()
        assert process.popen.returncode == 1, process.output
        last = process.lines[-1]
        assert last.startswith("imrosc record: the bag tap was killed (signal 9)"), process.output
        assert "Traceback" not in process.output
        assert children_of(process.popen.pid) == []  # the recorder was stopped too
    found = messages(system.folder / "killed" / "recsys2")
    assert len(found["/sys/cmd"]) >= 5


def cmdline(pid: int) -> bytes:
    try:
        return Path(f"/proc/{pid}/cmdline").read_bytes()
    except OSError:
        return b""
