"""The demo's printed ROS 1 command works as printed (issue 18, item 8): run by a shell whose
``python3`` is a Python without rospy (the README's virtualenv), it starts the monitor node,
which registers with the master and publishes its violations topic."""

from __future__ import annotations

import sys
from pathlib import Path

import pytest
from click.testing import CliRunner

from imrosc.cli import main
from tests.live.harness import Ros

pytestmark = pytest.mark.live


def test_the_demos_ros1_command_starts_the_monitor_from_a_virtualenv(
    ros: Ros, tmp_path: Path
) -> None:
    done = CliRunner().invoke(main, ["demo", "-o", str(tmp_path / "demo"), "--runs", "2", "-q"])
    assert done.exit_code == 0, done.output
    (printed,) = [line for line in done.stdout.splitlines() if line.strip().startswith("ROS 1: ")]
    command = printed.strip().removeprefix("ROS 1: ")
    assert command.startswith("ROS_PACKAGE_PATH=") and " roslaunch " in command
    venv = tmp_path / "venv" / "bin"  # python3 first on PATH, without rospy
    venv.mkdir(parents=True)
    (venv / "python3").symlink_to(sys.executable)
    saved = dict(ros.env)
    ros.env["PATH"] = f"{venv}:{saved['PATH']}"
    try:
        shell = ros.spawn("demo-command", ["/bin/bash", "-c", command])
    finally:
        ros.env.clear()
        ros.env.update(saved)
    ros.wait_publisher("/m/broken_inv", "/landing_sim_monitor", 90, (shell,))
    assert shell.alive, shell.tail()
    ros.stop(shell)
