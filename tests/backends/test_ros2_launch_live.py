"""A generated ROS 2 monitor package the way a ROS 2 user runs it: ``imrosc build --backend
ros2`` into a workspace, ``colcon build`` into an install space, ``ros2 launch <pkg>
<pkg>.launch.xml`` after sourcing ``install/setup.sh``, Ctrl-C.

Needs the ROS 2 virtualenv ``tools/ros2_venv.sh`` builds (``make test`` does): rclpy, colcon
and the vendored launch system and ``ros2`` command; colcon runs from it, so the installed
scripts run under its python. ``AMENT_PREFIX_PATH`` lists the virtualenv (where the message
packages and ``ros2cli`` put their ament index) before ``setup.sh`` adds the install space.

The package is the one of ``test_ros2_live.py``'s system, started with ``fail_open:=true``
(the watchdog runs beside the monitor and stays idle while it beats), and the same driver
plays the system: blocking, the publishing action, QoS matching against a best-effort
publisher, a parameter, the relayed service (allowed and refused), an unknown publisher,
``/m/clear_inv`` and the heartbeat. Then the monitor is killed: the watchdog fails open and
relays the blocked topic and service unchecked. Then SIGINT to ``ros2 launch``: it stops
the watchdog, which finishes cleanly, and exits 0 with nothing left behind.
"""

from __future__ import annotations

import json
import os
import re
import signal
import subprocess
from pathlib import Path

import pytest
from click.testing import CliRunner

from imrosc.cli import main
from tests.backends.ros2_support import Reader, require_launch, ros2_environment
from tests.backends.test_monitor_spec import config_text, write_case
from tests.backends.test_ros2_live import DRIVER, MONITOR, SCOPE, assert_monitored, demo_document

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


def test_the_package_built_with_colcon_runs_under_ros2_launch_and_stops_on_sigint(
    tmp_path: Path,
) -> None:
    venv_bin = require_launch()
    config = write_case(tmp_path, config_text(scope=SCOPE, monitor=MONITOR), demo_document())
    workspace = tmp_path / "ws"
    built = CliRunner().invoke(
        main, ["build", str(config), "--backend", "ros2", "-o", str(workspace / "src")]
    )
    assert built.exit_code == 0, built.output
    environment = ros2_environment(
        tmp_path,
        AMENT_PREFIX_PATH=str(venv_bin.parent),
        PATH=f"{venv_bin}{os.pathsep}{os.environ.get('PATH', '')}",
    )
    colcon = subprocess.run(
        [str(venv_bin / "colcon"), "build", "--base-paths", "src"],
        cwd=workspace,
        env=environment,
        capture_output=True,
        text=True,
        check=False,
        timeout=180,
    )
    assert colcon.returncode == 0, colcon.stdout + colcon.stderr
    share = workspace / "install" / PACKAGE / "share" / PACKAGE
    assert (share / "launch" / f"{PACKAGE}.launch.xml").exists(), colcon.stdout

    launch = Reader(
        [
            "bash",
            "-c",
            f". install/setup.sh && exec ros2 launch {PACKAGE} {PACKAGE}.launch.xml"
            " fail_open:=true",
        ],
        environment,
        cwd=workspace,
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

        code = launch.stop(signal.SIGINT, timeout=30)  # Ctrl-C: ros2 launch stops its nodes
        left = launch.alive_in_group()
    finally:
        launch.kill()
    assert code == 0, launch.output
    for node in (PACKAGE, f"{PACKAGE}_watchdog"):
        assert f"[{node}-" in launch.output, launch.output  # started by the launch file
    assert f"[{PACKAGE}_watchdog-2]: process has finished cleanly" in launch.output, launch.output
    assert not left, f"left running after ros2 launch stopped: {left}\n{launch.output}"
