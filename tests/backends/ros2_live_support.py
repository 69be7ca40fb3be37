"""The small system the live ROS 2 monitor tests share (``test_ros2_live.py``,
``test_ros2_launch_live.py``, ``test_ros2_burst_live.py``, ``tests/live/test_watchdog_live.py``):
its configuration (``SCOPE``, ``MONITOR``), invariants (``demo_document``, ``invariant``), the
driver that plays it (``DRIVER``, checked by ``assert_monitored``), and how a test builds the
package, starts its monitor node and runs a driver against it."""

from __future__ import annotations

import json
import subprocess
from pathlib import Path
from typing import Any

from tests.backends.monitor_support import config_text, write_case, write_package
from tests.backends.ros2_build import build_ros2, ros2_document

SCOPE = """<publish id="a">/a/cmd</publish>
    <publish id="l">/a/level</publish>
    <call id="c">/a/reset</call>
    <param id="p">/a/ctrl/gain</param>
    <param id="q">/a/ctrl/unset</param>
    <arch id="d">pub</arch>"""
MONITOR = """<monitor inv="demo.inv" period="0.2">
    <block>/a/cmd, /a/reset</block>
    <action id="f"><topic>/a/cmd</topic><value>{data: 0}</value></action>
    <violation>a -> f</violation>
  </monitor>"""


def invariant(ident: str, point: str, family: str, kind: str, **params: Any) -> dict[str, Any]:
    variables = params.pop("variables")
    return {
        "id": ident,
        "family": family,
        "kind": kind,
        "point": point,
        "condition": None,
        "variables": variables,
        "params": params,
        "text": f"{ident} holds",
        "support": {"samples": 10, "runs": 1},
        "confidence": 1.0,
    }


def demo_document() -> dict[str, Any]:
    document = ros2_document({"/a/cmd": "std_msgs/msg/UInt8", "/a/level": "std_msgs/msg/Float64"})
    points = document["points"]
    points["l"] = points.pop("b")
    points["c"] = {
        **points["a"],
        "kind": "call",
        "trigger": "/a/reset",
        "variables": [
            {
                "name": "reset.request.data",
                "type": "float",
                "topic": "/a/reset",
                "path": "request.data",
                "derived": None,
                "trigger": True,
            }
        ],
    }
    points["p"] = {
        **points["a"],
        "kind": "param",
        "trigger": "/a/ctrl/gain",
        "variables": [
            {
                "name": "/a/ctrl/gain",
                "type": "float",
                "topic": "/a/ctrl/gain",
                "path": "",
                "derived": None,
                "trigger": True,
            }
        ],
    }
    # a parameter the node never declares: asked along with the gain, it must not hide it
    points["q"] = {
        **points["p"],
        "trigger": "/a/ctrl/unset",
        "variables": [
            {**points["p"]["variables"][0], "name": "/a/ctrl/unset", "topic": "/a/ctrl/unset"}
        ],
    }
    points["d"] = {
        **points["a"],
        "kind": "arch",
        "trigger": "",
        "variables": [
            {
                "name": "pubs(/a/cmd)",
                "type": "set",
                "topic": "/a/cmd",
                "path": "pub",
                "derived": None,
                "trigger": True,
            }
        ],
    }
    document["invariants"] = [
        invariant("cmd_range", "a", "bounds", "range", variables=["cmd.data"], min=0.0, max=3.0),
        invariant("level_max", "l", "bounds", "upper", variables=["level.data"], max=50.0),
        invariant(
            "reset_no", "c", "one-of", "one-of", variables=["reset.request.data"], values=[0.0]
        ),
        invariant("gain", "p", "bounds", "range", variables=["/a/ctrl/gain"], min=1.0, max=2.0),
        invariant(
            "cmd_pubs",
            "d",
            "architecture",
            "max_pubs",
            variables=["pubs(/a/cmd)"],
            resource="/a/cmd",
            nodes=["/a/driver"],
        ),
    ]
    return document


DRIVER = r"""
import json, os, sys, threading, time
import rclpy
from rclpy.executors import MultiThreadedExecutor
from rclpy.node import Node
from rclpy.parameter import Parameter
from rclpy.qos import QoSProfile, ReliabilityPolicy
from std_msgs.msg import Float64, String, UInt8
from std_srvs.srv import SetBool

rclpy.init()
executor = MultiThreadedExecutor(num_threads=4)
driver = Node("driver", namespace="/a")
sensor = Node("sensor", namespace="/a")
ctrl = Node("ctrl", namespace="/a", parameter_overrides=[Parameter("gain", value=1.5)])
ctrl.declare_parameter("gain", 1.5)
server = Node("server", namespace="/a")
listener = Node("listener", namespace="/a")
for node in (driver, sensor, ctrl, server, listener):
    executor.add_node(node)
threading.Thread(target=executor.spin, daemon=True).start()

out = {"relayed": [], "warnings": [], "served": [], "beats": 0}
lock = threading.Lock()

def on_relay(message):
    with lock:
        out["relayed"].append(int(message.data))

def on_warning(message):
    with lock:
        out["warnings"].append(json.loads(message.data))

def on_beat(message):
    with lock:
        out["beats"] += 1

def serve(request, response):
    with lock:
        out["served"].append(bool(request.data))
    response.success, response.message = True, "done"
    return response

cmd = driver.create_publisher(UInt8, "/a/cmd", 10)
level = sensor.create_publisher(
    Float64, "/a/level", QoSProfile(depth=10, reliability=ReliabilityPolicy.BEST_EFFORT)
)
server.create_service(SetBool, "/a/reset", serve)
listener.create_subscription(UInt8, "/m/a/cmd", on_relay, 10)  # remapped by the launch file
listener.create_subscription(String, "/m/broken_inv", on_warning, 100)
from builtin_interfaces.msg import Time
listener.create_subscription(Time, "/m/heartbeat", on_beat, 10)
client = listener.create_client(SetBool, "/m/a/reset")

def wait(what, timeout=30.0):
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        if what():
            return True
        time.sleep(0.05)
    return False

def warned(ident):
    with lock:
        return [w for w in out["warnings"] if w["invariant"] == ident]

def monitor_listens(topic):
    return any(i.node_name == MONITOR for i in listener.get_subscriptions_info_by_topic(topic))

monitor_ready = wait(lambda: monitor_listens("/a/level") and client.service_is_ready())
out["ready"] = monitor_ready
# the monitor switches /a/level to best effort once it sees the publisher
out["level_best_effort"] = wait(lambda: any(
    int(i.qos_profile.reliability) == 2
    for i in listener.get_subscriptions_info_by_topic("/a/level")
    if i.node_name == MONITOR
))
out["relay_publishers"] = wait(lambda: listener.count_publishers("/m/a/cmd") > 0)
time.sleep(0.5)
for value in (1, 2):
    cmd.publish(UInt8(data=value))
    time.sleep(0.1)
wait(lambda: len(out["relayed"]) >= 2, 10.0)
cmd.publish(UInt8(data=9))                      # breaks cmd_range: not relayed; action f: 0
wait(lambda: warned("cmd_range") and 0 in out["relayed"], 10.0)
time.sleep(0.3)
level.publish(Float64(data=20.0))
level.publish(Float64(data=80.0))               # best effort, breaks level_max
wait(lambda: warned("level_max"), 10.0)

answer = client.call_async(SetBool.Request(data=False))
wait(answer.done, 10.0)
out["allowed"] = [answer.result().success, answer.result().message] if answer.done() else None
answer = client.call_async(SetBool.Request(data=True))   # breaks reset_no: refused
wait(answer.done, 10.0)
out["refused"] = [answer.result().success, answer.result().message] if answer.done() else None
wait(lambda: warned("reset_no"), 5.0)

ctrl.set_parameters([Parameter("gain", value=5.0)])      # breaks gain at the next poll
wait(lambda: warned("gain"), 10.0)

rogue = Node("rogue", namespace="/a")
executor.add_node(rogue)
rogue.create_publisher(UInt8, "/a/cmd", 10)               # breaks cmd_pubs: warn only
wait(lambda: warned("cmd_pubs"), 10.0)

clear = listener.create_publisher(String, "/m/clear_inv", 10)
time.sleep(0.5)
clear.publish(String(data="level_max"))
time.sleep(0.5)
before = len(warned("level_max"))
level.publish(Float64(data=90.0))
time.sleep(1.0)
out["level_after_clear"] = len(warned("level_max")) - before
with lock:
    print(json.dumps(out))
sys.stdout.flush()
# the driver's own teardown is not under test: rclpy's shutdown with the executor still
# spinning in its thread aborts now and then ("terminate called without an active exception")
os._exit(0)
"""


def demo_package(tmp_path: Path) -> Path:
    """The demo configuration's ROS 2 package, built and written under ``tmp_path``."""
    config = write_case(tmp_path, config_text(scope=SCOPE, monitor=MONITOR), demo_document())
    result = build_ros2(config)
    assert result.ok, [d.as_text() for d in result.diagnostics]
    return write_package(result.files, tmp_path / "out")


def start_monitor(ros2_python: str, package: Path, environment: dict[str, str]) -> Any:
    """The package's monitor node, its output piped."""
    return subprocess.Popen(
        [
            ros2_python,
            "-c",
            "from demo_monitor import main; main.monitor()",
            *("--ros-args", "-p", f"invariants:={package / 'config' / 'invariants.json'}"),
        ],
        env=environment,
        stdout=subprocess.PIPE,
        stderr=subprocess.STDOUT,
        text=True,
    )


def drive(
    ros2_python: str, driver: str, environment: dict[str, str], timeout: float
) -> subprocess.CompletedProcess[str]:
    """Run a driver script against the monitor ``demo_monitor``."""
    return subprocess.run(
        [ros2_python, "-c", driver.replace("MONITOR", repr("demo_monitor"))],
        env=environment,
        capture_output=True,
        text=True,
        check=False,
        timeout=timeout,
    )


def assert_monitored(stdout: str, log: str) -> None:
    """What ``DRIVER`` saw (the last line of its output) is what the monitor must do."""
    out = json.loads(stdout.strip().splitlines()[-1])
    context = json.dumps(out, indent=1) + "\n" + log
    assert out["ready"] and out["relay_publishers"], context
    assert out["level_best_effort"], context
    assert out["beats"] > 0, context
    warned = {w["invariant"] for w in out["warnings"]}
    assert {"cmd_range", "level_max", "reset_no", "gain", "cmd_pubs"} <= warned, context
    assert out["relayed"][:2] == [1, 2] and 9 not in out["relayed"], context
    assert 0 in out["relayed"], context  # action f published on the relay
    (cmd,) = [w for w in out["warnings"] if w["invariant"] == "cmd_range"]
    assert cmd["observed"] == 9.0 and cmd["actions"] == ["f"], context
    assert (cmd["alarm"], cmd["rule"]) == (True, "persist"), context  # no rule: each alarms
    for pubs in [w for w in out["warnings"] if w["invariant"] == "cmd_pubs"]:
        assert pubs["observed"] == ["/a/rogue"] and "no master" in pubs["note"], context
    assert out["allowed"] == [True, "done"], context
    assert out["refused"] == [False, ""], context  # the default response: refused
    assert out["served"] == [False], context  # the refused request never reached the server
    assert out["level_after_clear"] == 0, context
