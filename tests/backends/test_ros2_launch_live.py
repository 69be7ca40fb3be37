"""A generated ROS 2 monitor package the way a ROS 2 user runs it: ``imrosc build --backend
ros2`` into a workspace, ``colcon build`` into an install space, ``ros2 launch <pkg>
<pkg>.launch.xml`` after sourcing ``install/setup.sh``, Ctrl-C.

Needs the ROS 2 virtualenv ``tools/ros2_venv.sh`` builds (``make test`` does): rclpy, colcon
and the vendored launch system and ``ros2`` command; colcon runs from it, so the installed
scripts run under its python. ``AMENT_PREFIX_PATH`` lists the virtualenv (where the message
packages and ``ros2cli`` put their ament index) before ``setup.sh`` adds the install space.

The package is the one of ``ros2_live_support.py``'s system, started with ``fail_open:=true``
(the watchdog runs beside the monitor and stays idle while it beats), and the same driver
plays the system: blocking, the publishing action, QoS matching against a best-effort
publisher, a parameter, the relayed service (allowed and refused), an unknown publisher,
``/m/clear_inv`` and the heartbeat. Then the monitor is killed: the watchdog fails open and
relays the blocked topic and service unchecked. Then SIGINT to ``ros2 launch``: it stops
the watchdog, which finishes cleanly, and exits 0 with nothing left behind.

``ros2 run <pkg> <pkg>_recorder`` starts the installed recorder the same way: it publishes
the graph and the scope's parameters, and Ctrl-C stops it cleanly.
"""

from __future__ import annotations

import json
import os
import re
import signal
import subprocess
from dataclasses import dataclass
from pathlib import Path

import pytest
from click.testing import CliRunner

from imrosc import records
from imrosc.cli import main
from tests.backends.monitor_support import config_text, write_case
from tests.backends.ros2_live_support import DRIVER, MONITOR, SCOPE, assert_monitored, demo_document
from tests.backends.ros2_support import (
    LAUNCH_GRACE,
    STOP_TIMEOUT,
    Reader,
    require_launch,
    ros2_environment,
)

pytestmark = pytest.mark.live

PACKAGE = "demo_monitor"

FAILED_OPEN = r"""
import json, os, threading, time
import rclpy
from rclpy.executors import MultiThreadedExecutor
from rclpy.node import Node
from std_msgs.msg import UInt8
from std_srvs.srv import SetBool

rclpy.init()
executor = MultiThreadedExecutor(num_threads=4)
node = Node("system", namespace="/a")
executor.add_node(node)
threading.Thread(target=executor.spin, daemon=True).start()
out = {"relayed": [], "served": []}

def serve(request, response):
    out["served"].append(bool(request.data))
    response.success = True
    return response

def wait(what, timeout=30.0):
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        if what():
            return True
        time.sleep(0.05)
    return False

cmd = node.create_publisher(UInt8, "/a/cmd", 10)
node.create_service(SetBool, "/a/reset", serve)
node.create_subscription(UInt8, "/m/a/cmd", lambda m: out["relayed"].append(m.data), 10)
client = node.create_client(SetBool, "/m/a/reset")
out["relaying"] = wait(lambda: node.count_publishers("/m/a/cmd") > 0 and client.service_is_ready())
time.sleep(0.5)
cmd.publish(UInt8(data=9))  # unchecked: the monitor is dead
wait(lambda: 9 in out["relayed"], 10.0)
answer = client.call_async(SetBool.Request(data=True))
wait(answer.done, 10.0)
out["answer"] = answer.result().success if answer.done() else None
print(json.dumps(out), flush=True)
os._exit(0)
"""


@dataclass
class Workspace:
    """A colcon workspace with the package built and installed, and the ROS 2 virtualenv."""

    root: Path
    venv_bin: Path

    def environment(self, folder: Path) -> dict[str, str]:
        """A test's ROS 2 environment with the virtualenv on ``PATH`` and in
        ``AMENT_PREFIX_PATH`` (``install/setup.sh`` adds the install space)."""
        return ros2_environment(
            folder,
            AMENT_PREFIX_PATH=str(self.venv_bin.parent),
            PATH=f"{self.venv_bin}{os.pathsep}{os.environ.get('PATH', '')}",
        )

    def start(self, command: str, environment: dict[str, str]) -> Reader:
        """Run ``command`` (``ros2 ...``) in the workspace after ``. install/setup.sh``."""
        return Reader(
            ["bash", "-c", f". install/setup.sh && exec {command}"], environment, cwd=self.root
        )


@pytest.fixture(scope="module")
def workspace(tmp_path_factory: pytest.TempPathFactory) -> Workspace:
    """``imrosc build --backend ros2 -o ws/src``, then ``colcon build`` in ``ws``."""
    venv_bin = require_launch()
    folder = tmp_path_factory.mktemp("ros2_launch")
    config = write_case(folder, config_text(scope=SCOPE, monitor=MONITOR), demo_document())
    built = Workspace(folder / "ws", venv_bin)
    result = CliRunner().invoke(
        main, ["build", str(config), "--backend", "ros2", "-o", str(built.root / "src")]
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
    share = built.root / "install" / PACKAGE / "share" / PACKAGE
    assert (share / "launch" / f"{PACKAGE}.launch.xml").exists(), colcon.stdout
    return built


def test_the_package_built_with_colcon_runs_under_ros2_launch_and_stops_on_sigint(
    workspace: Workspace, tmp_path: Path
) -> None:
    venv_bin = workspace.venv_bin
    environment = workspace.environment(tmp_path)
    launch = workspace.start(
        f"ros2 launch {PACKAGE} {PACKAGE}.launch.xml fail_open:=true {LAUNCH_GRACE}", environment
    )
    try:
        launch.wait_for(f"[{PACKAGE}]: imrosc monitor /{PACKAGE}: checking", 60)
        driver = subprocess.run(
            [str(venv_bin / "python"), "-c", DRIVER.replace("MONITOR", repr(PACKAGE))],
            env=environment,
            capture_output=True,
            text=True,
            check=False,
            timeout=240,
        )
        assert driver.returncode == 0, driver.stdout + driver.stderr + launch.output
        assert_monitored(driver.stdout, launch.output)

        started = launch.wait_for(f"[{PACKAGE}-1]: process started with pid")
        pid = re.search(r"pid \[(\d+)\]", started)
        assert pid is not None, started
        os.kill(int(pid.group(1)), signal.SIGKILL)  # the monitor dies
        launch.wait_for("the monitor is silent; failing open", 30)
        system = subprocess.run(
            [str(venv_bin / "python"), "-c", FAILED_OPEN],
            env=environment,
            capture_output=True,
            text=True,
            check=False,
            timeout=120,
        )
        assert system.returncode == 0, system.stdout + system.stderr + launch.output
        out = json.loads(system.stdout.strip().splitlines()[-1])
        context = json.dumps(out) + "\n" + launch.output
        assert out["relaying"] and 9 in out["relayed"], context  # relayed unchecked
        assert out["answer"] is True and out["served"] == [True], context

        code = launch.stop(
            signal.SIGINT, timeout=STOP_TIMEOUT
        )  # Ctrl-C: ros2 launch stops its nodes
        left = launch.alive_in_group()
    finally:
        launch.kill()
    assert code == 0, launch.output
    for node in (PACKAGE, f"{PACKAGE}_watchdog"):
        assert f"[{node}-" in launch.output, launch.output  # started by the launch file
    assert f"[{PACKAGE}_watchdog-2]: process has finished cleanly" in launch.output, launch.output
    assert not left, f"left running after ros2 launch stopped: {left}\n{launch.output}"


RECORDS = r"""
import json, os, threading, time
import rclpy
from rclpy.executors import MultiThreadedExecutor
from rclpy.node import Node
from rclpy.parameter import Parameter
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy
from std_msgs.msg import String, UInt8

rclpy.init()
executor = MultiThreadedExecutor(num_threads=4)
ctrl = Node("ctrl", namespace="/a", parameter_overrides=[Parameter("gain", value=1.5)])
ctrl.declare_parameter("gain", 1.5)
ctrl.create_publisher(UInt8, "/a/cmd", 10)
listener = Node("listener")
seen = {"/imrosc/arch": [], "/imrosc/params": []}
qos = QoSProfile(
    depth=100, reliability=ReliabilityPolicy.RELIABLE, durability=DurabilityPolicy.TRANSIENT_LOCAL
)
for topic in seen:
    listener.create_subscription(String, topic, lambda m, t=topic: seen[t].append(m.data), qos)
for node in (ctrl, listener):
    executor.add_node(node)
threading.Thread(target=executor.spin, daemon=True).start()
end = time.monotonic() + 30
while time.monotonic() < end:
    if any("/a/cmd" in a for a in seen["/imrosc/arch"]) and any(
        "gain" in p for p in seen["/imrosc/params"]
    ):
        break
    time.sleep(0.1)
print(json.dumps(seen), flush=True)
os._exit(0)
"""


def test_ros2_run_starts_the_installed_recorder_which_stops_on_sigint(
    workspace: Workspace, tmp_path: Path
) -> None:
    """``ros2 run <pkg> <pkg>_recorder`` from the install space: it publishes the graph and
    the scope's parameters, and Ctrl-C (SIGINT to the process group, as a terminal sends it)
    stops it cleanly."""
    environment = workspace.environment(tmp_path)
    recorder = workspace.start(f"ros2 run {PACKAGE} {PACKAGE}_recorder", environment)
    try:
        system = subprocess.run(
            [str(workspace.venv_bin / "python"), "-c", RECORDS],
            env=environment,
            capture_output=True,
            text=True,
            check=False,
            timeout=120,
        )
        # Ctrl-C: ros2 run leaves the signal to its child, which the terminal signals too
        code = recorder.stop(signal.SIGINT, timeout=30, group=True)
        left = recorder.alive_in_group()
    finally:
        recorder.kill()
    assert system.returncode == 0, system.stdout + system.stderr + recorder.output
    seen = json.loads(system.stdout.strip().splitlines()[-1])
    context = json.dumps(seen) + "\n" + recorder.output
    archs = [records.decode_arch(text) for text in seen["/imrosc/arch"]]
    assert any("/a/ctrl" in a.topics["/a/cmd"].pubs for a in archs if "/a/cmd" in a.topics), context
    params = [records.decode_params(text) for text in seen["/imrosc/params"]]
    assert params and params[-1].params.get("/a/ctrl/gain") == 1.5, context
    assert code == 0, context
    assert not left, f"left running after ros2 run stopped: {left}\n{context}"
