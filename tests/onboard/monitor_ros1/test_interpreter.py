"""A generated ROS 1 script started by a Python without rospy (a virtualenv's) runs under the
system's Python instead, or says in one line what to do
(imrosc/onboard/monitor_ros1/interpreter.py)."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

import imrosc.onboard.monitor_ros1 as adapter
from imrosc.onboard.monitor_ros1 import interpreter

SYSTEM = "/usr/bin/python3"


def _script(folder: Path) -> Path:
    """A script laid out as a package's: its folder on sys.path holds ``imrosc_monitor``."""
    package = folder / "imrosc_monitor"
    package.mkdir()
    source = Path(adapter.__file__).parent
    for name in ("__init__.py", "interpreter.py"):
        (package / name).write_text((source / name).read_text())
    script = folder / "node"
    script.write_text(
        "import os, sys\n"
        "sys.path.insert(0, os.path.dirname(os.path.realpath(__file__)))\n"
        "from imrosc_monitor import interpreter\n"
        "interpreter.ensure_rospy(sys.argv)\n"
        "import rospy\n"
        "print(sys.executable, sys.argv[1:])\n"
    )
    return script


def _without_rospy() -> bool:
    done = subprocess.run([sys.executable, "-c", "import rospy"], capture_output=True, check=False)
    return done.returncode != 0


needs = pytest.mark.skipif(
    not (_without_rospy() and interpreter.has_rospy(SYSTEM)),
    reason="needs a test Python without rospy and a system Python with it",
)


@needs
def test_a_python_without_rospy_hands_the_script_to_the_systems(tmp_path: Path) -> None:
    env = {k: v for k, v in os.environ.items() if k != interpreter.AGAIN}
    done = subprocess.run(
        [sys.executable, str(_script(tmp_path)), "__name:=m", "_period:=0.5"],
        capture_output=True,
        text=True,
        env=env,
        check=False,
    )
    assert done.returncode == 0, done.stderr
    assert done.stdout.strip() == f"{SYSTEM} ['__name:=m', '_period:=0.5']"


@needs
def test_when_no_python_has_rospy_one_line_says_what_to_do(tmp_path: Path) -> None:
    script = _script(tmp_path)
    env = {**os.environ, interpreter.AGAIN: "1"}  # as if the system's had failed too
    done = subprocess.run(
        [sys.executable, str(script)], capture_output=True, text=True, env=env, check=False
    )
    assert done.returncode == 1 and done.stdout == ""
    (line,) = done.stderr.splitlines()
    assert line.startswith(f"{script}: rospy cannot be imported by {sys.executable}")
    assert f"/usr/bin/python3 {script}" in line


def test_the_current_python_is_never_a_candidate() -> None:
    assert interpreter.candidates(sys.executable, [sys.executable]) == []
    assert interpreter.candidates(sys.executable, ["/nonexistent/python3"]) == []
