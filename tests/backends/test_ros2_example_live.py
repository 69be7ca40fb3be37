"""The landing example on ROS 2, the way its README says to run it: ``imrosc build
examples/uav_landing.xml --backend ros2 --graph examples/uav_landing.graph.yaml -o ws/src``,
``colcon build``, ``ros2 launch uav_landing_monitor system_monitored.launch.xml``: the
example's ROS 2 launch file (``<monitor launch_ros2="launch/landing.launch.xml">``) rewritten,
which starts the landing system with the subscribers of the blocked topics remapped to the
monitor's relays, and the monitor.

``examples/landing_system`` is a ROS 1 package (rospy, genpy services), so the test installs a
stand-in ``landing_system`` beside the workspace: an ament index entry and one rclpy script
per executable the launch file names, each playing its node of the example's graph (the topics
and types of ``uav_landing.graph.yaml``; ``/vicon`` publishes ``/clock``, since the launch file
sets ``use_sim_time``). ``/a/car_ctrl`` commands the state its test driver asks for on
``/standin/command``; it, ``/a/ctrl_state_machine`` and ``/a/pid_ctrl`` print what they hear.

The invariants are the example's inferred from two simulated runs, kept to those of the state
command alone (``cmd_subject_ctrl_state.data <= 6``): the stand-ins do not fly, so the
invariants over poses would break all the time. The example's alarm rule applies (three
violating commands in a row or 0.3 s of them, in ROS time). The driver checks that good
commands and every platform position are relayed, that a bad command (200) is blocked once
the alarm is raised, warned on ``/m/broken_inv`` and answered by action ``f`` (``{data: 3}``
to the state machine), and that good commands flow again; the state machine's output shows
the same through the remap, and the waypoints reach the position loop straight (they are not
blocked). SIGINT then stops ``ros2 launch`` and every node cleanly.
"""

from __future__ import annotations

import json
import os
import re
import shutil
import signal
import subprocess
from dataclasses import dataclass
from pathlib import Path

import pytest
from click.testing import CliRunner

from imrosc.cli import main
from tests.backends.example_ros2_support import CONFIG, GRAPH, PACKAGE
from tests.backends.ros2_support import (
    LAUNCH_GRACE,
    STOP_TIMEOUT,
    Reader,
    require_launch,
    ros2_environment,
)

pytestmark = pytest.mark.live

KEPT = "cmd_subject_ctrl_state."
"""The prefix of the variables of the invariants the test keeps."""
EXECUTABLES = (
    "sim.py",
    "car.py",
    "uav.py",
    "robot_monitor.py",
    "ctrl_state_machine.py",
    "car_ctrl.py",
    "pid_ctrl.py",
    "listener.py",
    "thief.py",
)
"""What ``examples/launch/landing.launch.xml`` starts from package ``landing_system``."""

STANDIN = r'''
"""A stand-in for a node of the landing system (ROS 2): it publishes the node's topics of
uav_landing.graph.yaml at a few hertz of wall time and says what it hears on stderr (which
ros2 launch shows)."""
import sys, time
import rclpy
from rclpy.clock import Clock as Timing, ClockType
from rclpy.executors import ExternalShutdownException
from rclpy.node import Node
from rosgraph_msgs.msg import Clock
from geometry_msgs.msg import PoseStamped, TransformStamped
from sensor_msgs.msg import BatteryState
from std_msgs.msg import UInt8

rclpy.init(args=sys.argv)
node = Node("standin")
name = node.get_fully_qualified_name()
steady = Timing(clock_type=ClockType.STEADY_TIME)
command = [3]
state = [3]


def say(text):
    print(text, file=sys.stderr, flush=True)


def every(period, publish):
    # a timer on the steady clock, spun with the node: no thread of its own that could
    # outlive rclpy's shutdown (/vicon publishes the /clock every other node's ROS time is)
    node.create_timer(period, publish, clock=steady)


def pose(topic, kind=PoseStamped):
    publisher = node.create_publisher(kind, topic, 10)
    def publish():
        message = kind()
        message.header.frame_id = "world"
        message.header.stamp = node.get_clock().now().to_msg()
        publisher.publish(message)
    return publish


def listen(topic):
    # says when the first message of a topic (after its remap) comes
    heard = []
    def hear(message):
        if not heard:
            say(f"STANDIN {name} heard {subscription.topic_name}")
        heard.append(message)
    subscription = node.create_subscription(PoseStamped, topic, hear, 10)


if name == "/vicon":
    clock = node.create_publisher(Clock, "/clock", 10)
    start = time.monotonic()
    speed = 4.0
    def tick():
        seconds = (time.monotonic() - start) * speed
        message = Clock()
        message.clock.sec = int(seconds)
        message.clock.nanosec = int((seconds % 1) * 1e9)
        clock.publish(message)
    every(0.01, tick)
    every(0.05, pose("/vicon/car", TransformStamped))
elif name == "/a/car":
    every(0.05, pose("/a/car_pose"))
elif name == "/a/uav":
    every(0.05, pose("/a/subject_pose"))
elif name == "/a/robot_monitor":
    status = node.create_publisher(BatteryState, "/a/subject_status", 10)
    every(0.1, lambda: status.publish(BatteryState(voltage=12.0)))
elif name == "/a/ctrl_state_machine":
    states = node.create_publisher(UInt8, "/a/subject_ctrl_state", 10)
    def heard(message):
        state[0] = message.data
        say(f"STANDIN {name} heard {subscription.topic_name} {message.data}")
    subscription = node.create_subscription(UInt8, "/a/cmd_subject_ctrl_state", heard, 10)
    every(0.1, lambda: states.publish(UInt8(data=state[0])))
elif name == "/a/car_ctrl":
    commands = node.create_publisher(UInt8, "/a/cmd_subject_ctrl_state", 10)
    def asked(message):
        command[0] = message.data
        say(f"STANDIN {name} commands {message.data}")
    node.create_subscription(UInt8, "/standin/command", asked, 10)
    every(0.1, lambda: commands.publish(UInt8(data=command[0])))
    every(0.05, pose("/a/task_waypose"))
    listen("/a/car_pose")
elif name == "/a/pid_ctrl":
    listen("/a/task_waypose")
    node.create_subscription(PoseStamped, "/a/subject_pose", lambda m: None, 10)
    node.create_subscription(UInt8, "/a/subject_ctrl_state", lambda m: None, 10)
else:  # the listeners of the state
    node.create_subscription(UInt8, "/a/subject_ctrl_state", lambda m: None, 10)
say(f"STANDIN {name} up")


def spin():
    try:
        rclpy.spin(node)
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    except Exception:  # rclpy may raise from a take or publish the SIGINT shutdown interrupted
        # (on a loaded machine it failed a moment before the context said it was shut down:
        # give the shutdown a few seconds to show before calling the error the stand-in's)
        deadline = time.monotonic() + 5.0
        while rclpy.ok() and time.monotonic() < deadline:
            time.sleep(0.05)
        if rclpy.ok():
            raise
    finally:
        node.destroy_node()
        rclpy.try_shutdown()


try:
    spin()
except KeyboardInterrupt:
    # rclpy's handler shuts the context down from its own thread and passes the SIGINT on to
    # Python's: the KeyboardInterrupt may come after spin() ended on the shutdown, while the
    # stand-in tells a failed take from it or destroys the node; it is the same Ctrl-C
    pass
'''

DRIVER = r"""
import json, os, threading, time
MONITOR, INPUTS = json.loads(os.environ["IMROSC_TEST_POINT"])
import rclpy
from rclpy.executors import MultiThreadedExecutor
from rclpy.node import Node
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy
from geometry_msgs.msg import PoseStamped
from std_msgs.msg import String, UInt8

rclpy.init()
node = Node("driver")
executor = MultiThreadedExecutor(num_threads=2)
executor.add_node(node)
threading.Thread(target=executor.spin, daemon=True).start()
out = {"relayed": [], "relayed_info": [], "poses": 0, "warnings": []}
phase = ["good"]

def relayed(message, info):
    # the writer's sequence number and source time: who sent what, should it go wrong
    out["relayed"].append([phase[0], message.data])
    out["relayed_info"].append(
        [info.get("publication_sequence_number"), info.get("source_timestamp"), time.time()]
    )

def car_pose(message):
    out["poses"] += 1

node.create_subscription(UInt8, "/m/a/cmd_subject_ctrl_state", relayed, 100)
node.create_subscription(PoseStamped, "/m/a/car_pose", car_pose, 100)
node.create_subscription(String, "/m/broken_inv", lambda m: out["warnings"].append(m.data), 100)
latched = QoSProfile(
    depth=1, reliability=ReliabilityPolicy.RELIABLE, durability=DurabilityPolicy.TRANSIENT_LOCAL
)
ask = node.create_publisher(UInt8, "/standin/command", latched)

def wait(what, timeout):
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        if what():
            return True
        time.sleep(0.05)
    return False

def count(which, value):
    return sum(1 for p, v in out["relayed"] if p == which and v == value)

out["relaying"] = wait(lambda: count("good", 3) >= 5 and out["poses"] >= 5, 60.0)
wait(lambda: ask.get_subscription_count() > 0, 30.0)

def hears(topic):
    return any(
        i.node_name == MONITOR for i in node.get_subscriptions_info_by_topic(topic)
    ) and node.count_publishers(topic) > 0

# the monitor relays a command unchecked until it holds a value of every input of point a
# (a loaded run discovered a stand-in late and relayed 17 bad commands that way): the bad
# phase begins once it subscribes to all of them, and a second of their messages later
out["inputs"] = wait(lambda: all(hears(t) for t in INPUTS), 60.0)
time.sleep(1.0)
phase[0] = "bad"
ask.publish(UInt8(data=200))
wait(lambda: len(out["warnings"]) >= 3, 20.0)
time.sleep(2.0)  # about 20 bad commands
publishers = node.get_publishers_info_by_topic("/m/a/cmd_subject_ctrl_state")
out["relay_publishers"] = sorted(
    (i.node_namespace.rstrip("/") + "/" + i.node_name) for i in publishers
)
out["relay_writers"] = [
    [i.node_namespace, i.node_name, bytes(i.endpoint_gid).hex(), str(i.qos_profile.durability)]
    for i in publishers
]
# who commands: a second publisher of the command (another graph on this DDS domain) would
# break the monitor's episode of bad commands with good ones, and bad ones would pass
out["command_publishers"] = sorted(
    (i.node_namespace.rstrip("/") + "/" + i.node_name)
    for i in node.get_publishers_info_by_topic("/a/cmd_subject_ctrl_state")
)
phase[0] = "recovered"
ask.publish(UInt8(data=3))
out["recovered"] = wait(lambda: count("recovered", 3) >= 5, 20.0)
print(json.dumps(out), flush=True)
os._exit(0)
"""


@dataclass
class Example:
    """A colcon workspace with the example's monitor package built and installed, the
    stand-in system's prefix, and the ROS 2 virtualenv."""

    root: Path
    standins: Path
    venv_bin: Path

    def environment(self, folder: Path) -> dict[str, str]:
        prefixes = os.pathsep.join((str(self.standins), str(self.venv_bin.parent)))
        return ros2_environment(
            folder,
            AMENT_PREFIX_PATH=prefixes,
            PATH=f"{self.venv_bin}{os.pathsep}{os.environ.get('PATH', '')}",
        )

    def inputs(self, point: str) -> list[str]:
        """The topics besides its trigger whose latest values a sample of ``point`` holds,
        from the invariants file the monitor package installed."""
        path = self.root / "src" / PACKAGE / "config" / "invariants.json"
        document = json.loads(path.read_text(encoding="utf-8"))
        return list(document["points"][point]["inputs"])

    def start(self, command: str, environment: dict[str, str]) -> Reader:
        return Reader(
            ["bash", "-c", f". install/setup.sh && exec {command}"], environment, cwd=self.root
        )


def standin_prefix(prefix: Path, python: Path) -> Path:
    """An install prefix holding package ``landing_system``: its ament index entry and, in
    ``lib/landing_system``, every executable of the launch file as the stand-in script."""
    index = prefix / "share" / "ament_index" / "resource_index" / "packages"
    index.mkdir(parents=True)
    (index / "landing_system").write_text("")
    (prefix / "share" / "landing_system").mkdir(parents=True)
    lib = prefix / "lib" / "landing_system"
    lib.mkdir(parents=True)
    for name in EXECUTABLES:
        script = lib / name
        script.write_text(f"#!{python}\n{STANDIN}", encoding="utf-8")
        script.chmod(0o755)
    return prefix


def keep_command_invariants(path: Path) -> int:
    """Keep in the invariants file at ``path`` the invariants of point ``a`` over the state
    command alone; how many."""
    document = json.loads(path.read_text(encoding="utf-8"))
    document["invariants"] = [
        invariant
        for invariant in document["invariants"]
        if invariant["point"] == "a"
        and invariant["variables"]
        and all(v.startswith(KEPT) for v in invariant["variables"])
    ]
    path.write_text(json.dumps(document), encoding="utf-8")
    return len(document["invariants"])


@pytest.fixture(scope="module")
def example(
    landing_example: Path,
    tmp_path_factory: pytest.TempPathFactory,
) -> Example:
    """The README's commands: ``imrosc build`` the example with ``--backend ros2``, then
    ``colcon build`` in the workspace."""
    venv_bin = require_launch()
    folder = tmp_path_factory.mktemp("ros2_example")
    source = folder / "example"
    shutil.copytree(landing_example, source, ignore=shutil.ignore_patterns("bags"))
    assert keep_command_invariants(source / "landing.inv") >= 1
    built = Example(
        folder / "ws", standin_prefix(folder / "standins", venv_bin / "python"), venv_bin
    )
    result = CliRunner().invoke(
        main,
        [
            *("build", str(source / CONFIG), "--backend", "ros2"),
            *("--graph", str(source / GRAPH), "-o", str(built.root / "src")),
        ],
    )
    assert result.exit_code == 0, result.output
    colcon = subprocess.run(
        [str(venv_bin / "colcon"), "build", "--base-paths", "src"],
        cwd=built.root,
        env=built.environment(folder),
        capture_output=True,
        text=True,
        check=False,
        timeout=180,
    )
    assert colcon.returncode == 0, colcon.stdout + colcon.stderr
    share = built.root / "install" / PACKAGE / "share" / PACKAGE / "launch"
    assert (share / "system_monitored.launch.xml").exists(), colcon.stdout
    return built


def test_the_example_runs_on_ros2_launch_with_the_blocked_topics_through_the_monitor(
    example: Example, tmp_path: Path
) -> None:
    environment = example.environment(tmp_path)
    launch = example.start(
        f"ros2 launch {PACKAGE} system_monitored.launch.xml {LAUNCH_GRACE}", environment
    )
    try:
        launch.wait_for(f"[{PACKAGE}]: imrosc monitor /{PACKAGE}: checking", 90)
        for node in ("/vicon", "/a/car_ctrl", "/a/ctrl_state_machine", "/a/pid_ctrl"):
            launch.wait_for(f"STANDIN {node} up", 60)
        driver = subprocess.run(
            [str(example.venv_bin / "python"), "-c", DRIVER],
            env={**environment, "IMROSC_TEST_POINT": json.dumps([PACKAGE, example.inputs("a")])},
            capture_output=True,
            text=True,
            check=False,
            timeout=240,
        )
        assert driver.returncode == 0, driver.stdout + driver.stderr + launch.output
        launch.wait_for("STANDIN /a/car_ctrl heard /m/a/car_pose", 10)
        # the waypoints go straight to the position loop (not blocked)
        launch.wait_for("STANDIN /a/pid_ctrl heard /a/task_waypose", 10)
        code = launch.stop(
            signal.SIGINT, timeout=STOP_TIMEOUT
        )  # Ctrl-C: ros2 launch stops its nodes
        left = launch.alive_in_group()
    finally:
        launch.kill()
    out = json.loads(driver.stdout.strip().splitlines()[-1])
    warnings = [json.loads(text) for text in out["warnings"]]
    # how each process ended, and any traceback: the middle of a long context may be cut
    endings = [
        line
        for line in launch.output.splitlines()
        if "process has" in line or "Traceback" in line or "Error" in line
    ]
    summary = "relayed: {}; reports (time, alarm, rule): {}\n{}".format(
        out["relayed"],
        [(w["time"], w["alarm"], w.get("rule")) for w in warnings],
        "\n".join(endings),
    )
    context = f"{summary}\n{json.dumps(out)}\n{launch.output}\n{summary}"
    assert out["relaying"] and out["recovered"], context  # good commands and positions relayed
    assert out["inputs"], context  # the monitor subscribed to every input of point a
    # only the monitor publishes on the relay (its relay and action f's publisher), and only
    # the stand-in car_ctrl on the command topic
    assert set(out["relay_publishers"]) == {f"/{PACKAGE}"}, context
    assert out["command_publishers"] == ["/a/car_ctrl"], context
    bad = [value for phase, value in out["relayed"] if phase == "bad"]
    # the first bad commands are relayed until the alarm (three in a row or 0.3 s of ROS
    # time), then every one is blocked; about 20 were sent
    assert bad.count(200) <= 2, context
    if 200 in bad:
        assert 3 in bad[bad.index(200) :], context  # action f: {data: 3} to the state machine
    assert {w["text"] for w in warnings} == {"cmd_subject_ctrl_state.data <= 6"}, context
    alarmed = [w for w in warnings if w["alarm"]]
    assert alarmed and alarmed[0]["actions"] == ["f"], context

    # the remapped state machine heard the monitor's relay: the same blocking, seen by it
    heard = re.findall(r"STANDIN /a/ctrl_state_machine heard (\S+) (\d+)", launch.output)
    assert {topic for topic, _ in heard} == {"/m/a/cmd_subject_ctrl_state"}, context
    assert [int(value) for _, value in heard].count(200) <= 2, context
    assert "imrosc: blocked a message on /a/cmd_subject_ctrl_state" in launch.output, context
    commanded = re.findall(r"STANDIN /a/car_ctrl commands 200", launch.output)
    assert commanded, context  # the stand-in did send bad commands
    assert code == 0, context
    for executable in ("sim.py", "car_ctrl.py", "ctrl_state_machine.py", PACKAGE):
        assert re.search(
            rf"\[{re.escape(executable)}-\d+\]: process has finished cleanly", launch.output
        ), context
    assert not left, f"left running after ros2 launch stopped: {left}\n{context}"
