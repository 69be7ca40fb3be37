"""The generated ROS 2 monitor node on a live ROS 2 graph (rclpy, DDS on this machine).

Runs where an interpreter with rclpy is found (``tests/backends/ros2_support.py``):
``IMROSC_ROS2_PYTHON`` names it (``make test`` builds a ROS 2 Jazzy virtualenv with
``tools/ros2_venv.sh`` and sets it), or the test interpreter has rclpy itself. Without one
the tests are skipped, or fail under ``IMROSC_REQUIRE_ROS2=1`` (``make test``, CI).

The monitor of a small system is built with ``--backend ros2`` and started as its own
process; a driver process plays the system: a reliable publisher of a blocked command, a
best-effort publisher of a plain ``std_msgs`` topic (the monitor must switch to best effort
to hear it), a node with a parameter, a service server, a rogue publisher, and the
subscriber the launch file would remap to ``/m/<topic>``.
"""

from __future__ import annotations

import contextlib
import json
import signal
import subprocess
from pathlib import Path

import pytest

from tests.backends.monitor_support import config_text, write_case, write_package
from tests.backends.ros2_build import build_ros2, ros2_document
from tests.backends.ros2_live_support import (
    DRIVER,
    assert_monitored,
    demo_package,
    drive,
    invariant,
    start_monitor,
)
from tests.backends.ros2_support import Reader, require_ros2, ros2_environment

pytestmark = pytest.mark.live


@pytest.fixture
def ros2_python() -> str:
    """The interpreter with rclpy (skipped without one; failed under IMROSC_REQUIRE_ROS2)."""
    return require_ros2()


def test_the_generated_node_checks_blocks_acts_and_warns_on_a_live_ros2_graph(
    tmp_path: Path, ros2_python: str
) -> None:
    package = demo_package(tmp_path)
    environment = ros2_environment(tmp_path, PYTHONPATH=str(package))
    monitor = start_monitor(ros2_python, package, environment)
    try:
        driver = drive(ros2_python, DRIVER, environment, 240)
    finally:
        monitor.terminate()
        try:
            log, _ = monitor.communicate(timeout=20)
        except subprocess.TimeoutExpired:
            monitor.kill()
            log, _ = monitor.communicate()
    assert driver.returncode == 0, driver.stdout + driver.stderr + log
    assert_monitored(driver.stdout, log)


WATCHDOG_DRIVER = r"""
import json, os, sys, threading, time
import rclpy
from rclpy.executors import MultiThreadedExecutor
from rclpy.node import Node
from std_msgs.msg import UInt8
from std_srvs.srv import SetBool

rclpy.init()
executor = MultiThreadedExecutor(num_threads=4)
driver = Node("driver", namespace="/a")
listener = Node("listener", namespace="/a")
for node in (driver, listener):
    executor.add_node(node)
threading.Thread(target=executor.spin, daemon=True).start()
out = {"relayed": [], "served": []}

def serve(request, response):
    out["served"].append(bool(request.data))
    response.success = True
    return response

cmd = driver.create_publisher(UInt8, "/a/cmd", 10)
driver.create_service(SetBool, "/a/reset", serve)
listener.create_subscription(UInt8, "/m/a/cmd", lambda m: out["relayed"].append(m.data), 10)
client = listener.create_client(SetBool, "/m/a/reset")

def wait(what, timeout=30.0):
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        if what():
            return True
        time.sleep(0.05)
    return False

def watchdog_relays():
    return any(
        i.node_name == WATCHDOG for i in listener.get_publishers_info_by_topic("/m/a/cmd")
    )

out["failed_open"] = wait(lambda: watchdog_relays() and client.service_is_ready())
time.sleep(0.5)
cmd.publish(UInt8(data=9))  # unchecked while the monitor is silent
wait(lambda: 9 in out["relayed"], 10.0)
answer = client.call_async(SetBool.Request(data=True))
wait(answer.done, 10.0)
out["answer"] = answer.result().success if answer.done() else None
print("@@monitor", flush=True)  # the test starts the monitor now
sys.stdin.readline()
out["stopped"] = wait(lambda: not watchdog_relays(), 30.0)
print("@@out " + json.dumps(out), flush=True)
os._exit(0)  # the driver's own teardown is not under test
"""


@pytest.mark.parametrize("late", [False, True], ids=["served", "served-late"])
def test_the_watchdog_fails_open_while_the_monitor_is_silent(
    tmp_path: Path, ros2_python: str, late: bool
) -> None:
    """The watchdog relays the blocked topic and service unchecked while the monitor is
    silent and stops when its heartbeat comes; ``served-late``: the system's publisher and
    service appear only after the watchdog failed open (and found neither)."""
    package = demo_package(tmp_path)
    environment = ros2_environment(tmp_path, PYTHONPATH=str(package))
    started: list[Reader] = []

    def start(code: str, *args: str) -> Reader:
        started.append(Reader([ros2_python, "-c", code, *args], environment, stdin=True))
        return started[-1]

    try:
        watchdog = start("from demo_monitor import main; main.watchdog()")
        if late:
            watchdog.wait_for("cannot relay /a/reset")  # failed open before it was served
        driver = start(WATCHDOG_DRIVER.replace("WATCHDOG", repr("demo_monitor_watchdog")))
        driver.wait_for("@@monitor", 90)
        start(
            "from demo_monitor import main; main.monitor()",
            *("--ros-args", "-p", f"invariants:={package / 'config' / 'invariants.json'}"),
        )
        driver.send("go")
        line = driver.wait_for("@@out ", 60)
        assert driver.popen.wait(timeout=30) == 0, driver.output
    finally:
        for process in started:
            process.stop(signal.SIGTERM)
    out = json.loads(line.split("@@out ", 1)[1])
    context = json.dumps(out) + "\n" + "\n\n".join(p.output for p in started)
    assert out["failed_open"], context
    assert 9 in out["relayed"], context  # relayed unchecked
    assert out["answer"] is True and out["served"] == [True], context
    assert out["stopped"], context  # the heartbeat is back: the watchdog stops
    if late:
        assert "relaying /a/reset now" in watchdog.output, context


FAILURE_DRIVER = r"""
import json, os, threading, time
import rclpy
from rclpy.executors import MultiThreadedExecutor
from rclpy.node import Node
from rclpy.qos import QoSProfile, ReliabilityPolicy
from std_msgs.msg import Float64, String, UInt8

rclpy.init()
executor = MultiThreadedExecutor(num_threads=2)
driver = Node("driver", namespace="/a")
executor.add_node(driver)
threading.Thread(target=executor.spin, daemon=True).start()
out = {"warnings": [], "relayed": []}
driver.create_subscription(String, "/m/broken_inv", lambda m: out["warnings"].append(
    json.loads(m.data)), 100)
driver.create_subscription(UInt8, "/m/a/cmd", lambda m: out["relayed"].append(m.data), 10)
level = driver.create_publisher(
    Float64, "/a/level", QoSProfile(depth=10, reliability=ReliabilityPolicy.BEST_EFFORT)
)
cmd = driver.create_publisher(UInt8, "/a/cmd", 10)

def wait(what, timeout=30.0):
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        if what():
            return True
        time.sleep(0.05)
    return False

def listens():
    return any(i.node_name == MONITOR for i in driver.get_subscriptions_info_by_topic("/a/level"))

out["ready"] = wait(listens) and wait(lambda: driver.count_publishers("/m/broken_inv") > 0)
time.sleep(1.0)
failures = lambda: [w for w in out["warnings"] if w["kind"] == "failure"]
end = time.monotonic() + 60.0
while time.monotonic() < end:  # until the monitor hears one (best effort: a loaded machine
    level.publish(Float64(data=20.0))  # may take seconds to match the monitor's reader)
    if wait(failures, 0.25):
        break
out["failures"] = failures()
cmd.publish(UInt8(data=1))  # the monitor stopped: nothing is relayed unchecked
time.sleep(1.0)
print(json.dumps(out), flush=True)
os._exit(0)
"""


def test_a_check_that_raises_stops_the_ros2_monitor(tmp_path: Path, ros2_python: str) -> None:
    """A check that raises is published on /m/broken_inv (kind ``failure``), the node relays
    nothing from then on and exits with status 1 (issue 18: it used to log the exception
    and go on, unchecked)."""
    package = demo_package(tmp_path)
    engine = package / "demo_monitor" / "imrosc" / "runtime" / "engine.py"
    source = engine.read_text(encoding="utf-8")
    needle = "        found = self.advance(time) if self._timed else []\n        if publisher"
    assert source.count(needle) == 1
    injected = '        if topic == "/a/level":\n            raise RuntimeError("injected")\n'
    engine.write_text(source.replace(needle, injected + needle), encoding="utf-8")
    environment = ros2_environment(tmp_path, PYTHONPATH=str(package))
    monitor = start_monitor(ros2_python, package, environment)
    status = None
    try:
        driver = drive(ros2_python, FAILURE_DRIVER, environment, 180)
        with contextlib.suppress(subprocess.TimeoutExpired):
            status = monitor.wait(timeout=30)
    finally:
        if monitor.poll() is None:
            monitor.kill()
        log, _ = monitor.communicate()
    assert driver.returncode == 0, driver.stdout + driver.stderr + log
    out = json.loads(driver.stdout.strip().splitlines()[-1])
    context = json.dumps(out, indent=1) + "\n" + log
    assert out["ready"], context
    (failure,) = out["failures"]
    assert failure["error"] == {
        "where": "message on /a/level",
        "type": "RuntimeError",
        "message": "injected",
    }, context
    assert (failure["alarm"], failure["rule"]) == (True, "failure"), context
    assert out["relayed"] == [], context
    assert status == 1, context
    assert "checking failed" in log, context


TOPIC_ONLY_SCOPE = '<publish id="a">/a/cmd</publish>'
TOPIC_ONLY_MONITOR = """<monitor inv="demo.inv" period="0.2">
    <block>/a/cmd</block>
    <action id="f"><topic>/a/cmd</topic><value>{data: 0}</value></action>
    <violation>a -> f</violation>
  </monitor>"""
TOPIC_ONLY_DRIVER = r"""
import json, os, threading, time
import rclpy
from rclpy.executors import MultiThreadedExecutor
from rclpy.node import Node
from std_msgs.msg import String, UInt8
from builtin_interfaces.msg import Time

rclpy.init()
node = Node("driver", namespace="/a")
executor = MultiThreadedExecutor(num_threads=2)
executor.add_node(node)
threading.Thread(target=executor.spin, daemon=True).start()
out = {"relayed": [], "warnings": [], "beats": 0}
node.create_subscription(UInt8, "/m/a/cmd", lambda m: out["relayed"].append(m.data), 1000)
node.create_subscription(String, "/m/broken_inv", lambda m: out["warnings"].append(m.data), 100)

def beat(message):
    out["beats"] += 1

node.create_subscription(Time, "/m/heartbeat", beat, 10)
cmd = node.create_publisher(UInt8, "/a/cmd", 1000)

def wait(what, timeout=30.0):
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        if what():
            return True
        time.sleep(0.05)
    return False

# the command publisher's own side of the match (the graph may list the monitor's
# subscription before this writer matched it, and a volatile writer drops what it
# publishes before), and both of the monitor's publishers on /m/a/cmd in the graph: the
# relay and action f's
out["ready"] = wait(
    lambda: cmd.get_subscription_count() > 0 and node.count_publishers("/m/a/cmd") >= 2, 60
)
time.sleep(1.0)  # their side of the match with this node's subscription
for value in (1, 2, 9):
    cmd.publish(UInt8(data=value))
    time.sleep(0.3)
wait(lambda: 0 in out["relayed"], 10.0)
for k in range(300):  # a burst: every message relayed, in order
    cmd.publish(UInt8(data=1 + k % 3))
    time.sleep(0.001)
wait(lambda: len(out["relayed"]) >= 303, 20.0)
wait(lambda: out["beats"] > 0, 10.0)
print(json.dumps(out), flush=True)
os._exit(0)
"""


@pytest.mark.parametrize("checks", ["compiled", "numpy"])
def test_a_node_that_relays_no_service_checks_relays_and_acts_in_one_thread(
    tmp_path: Path, ros2_python: str, checks: str
) -> None:
    """Without relayed services the node spins a SingleThreadedExecutor (``executor_for``):
    it still checks and relays in order, acts (its action's publisher, the action thread)
    and beats. Both ways of checking: compiled by numba (the ROS 2 virtualenv has it; the
    driver starts once the node logged that the compiled checks are in use) and numpy
    alone (``IMROSC_NUMBA=0``, as where numba is missing); the start-up line says which."""
    document = ros2_document({"/a/cmd": "std_msgs/msg/UInt8"})
    document["invariants"] = [
        invariant("cmd_range", "a", "bounds", "range", variables=["cmd.data"], min=0.0, max=3.0)
    ]
    config = write_case(
        tmp_path, config_text(scope=TOPIC_ONLY_SCOPE, monitor=TOPIC_ONLY_MONITOR), document
    )
    result = build_ros2(config)
    assert result.ok, [d.as_text() for d in result.diagnostics]
    package = write_package(result.files, tmp_path / "out")
    environment = ros2_environment(tmp_path, PYTHONPATH=str(package))
    if checks == "numpy":
        environment["IMROSC_NUMBA"] = "0"
    monitor = Reader(
        [
            ros2_python,
            "-c",
            "from demo_monitor import main; main.monitor()",
            *("--ros-args", "-p", f"invariants:={package / 'config' / 'invariants.json'}"),
        ],
        environment,
    )
    try:
        started = monitor.wait_for("imrosc monitor /demo_monitor: checking", 120)
        if checks == "compiled":
            assert "numba" in started and "compiles the checks" in started, started
            monitor.wait_for("imrosc: compiled checks in use (numba", 120)
        else:
            assert "numpy checks every sample" in started, started
        driver = drive(ros2_python, TOPIC_ONLY_DRIVER, environment, 180)
    finally:
        returncode = monitor.stop(signal.SIGINT, timeout=20)
    log = monitor.output
    assert driver.returncode == 0, driver.stdout + driver.stderr + log
    out = json.loads(driver.stdout.strip().splitlines()[-1])
    context = json.dumps(out)[:3000] + "\n" + log
    if checks == "compiled":
        assert "compiled checks in use (numba" in log and "on 1 of 1 points," in log, log
    else:
        assert "compiled checks" not in log, log
    assert out["ready"] and out["beats"] > 0, context
    relayed = out["relayed"]
    assert relayed[:2] == [1, 2] and 9 not in relayed, context
    assert relayed[2] == 0, context  # action f, on the relay
    assert relayed[3:] == [1 + k % 3 for k in range(300)], context  # in order, none lost
    (warning,) = [json.loads(w) for w in out["warnings"]]
    assert (warning["invariant"], warning["observed"], warning["actions"]) == (
        "cmd_range",
        9.0,
        ["f"],
    ), context
    assert returncode == 0, context
