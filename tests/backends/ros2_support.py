"""What the ROS 2 live tests share: the interpreter with rclpy, the environment of a test's
ROS 2 graph, processes whose output is read as it comes.

``IMROSC_ROS2_PYTHON`` names the interpreter (``make test`` builds a ROS 2 Jazzy virtualenv
with ``tools/ros2_venv.sh`` and names its python); without it, the test interpreter is used if
it has rclpy. Under ``IMROSC_REQUIRE_ROS2=1`` (``make test``, hence CI) a ROS 2 live test that
would be skipped for want of ROS 2 fails instead.
"""

from __future__ import annotations

import contextlib
import fcntl
import os
import random
import signal
import subprocess
import sys
import tempfile
import threading
import time
from collections.abc import Mapping, Sequence
from pathlib import Path
from types import SimpleNamespace
from typing import Any

import pytest

RCLPY_IMPORTS = "import rclpy, numpy, std_srvs.srv, rcl_interfaces.srv, service_msgs.msg"
LAUNCH_IMPORTS = "import launch_ros, ros2launch, colcon_core"
GRACE = 20
"""Seconds ``ros2 launch`` gives its processes between its SIGINT and a SIGTERM (launch's
``sigterm_timeout``, 5 by default). On a loaded machine a node's shutdown took longer than
5 s, and the SIGTERM then crashed rclpy's signal handler (exit code -11): the tests check
that Ctrl-C stops every node cleanly, not how fast."""
LAUNCH_GRACE = f"sigterm_timeout:={GRACE}"
"""The ``ros2 launch`` argument that gives its processes :data:`GRACE` seconds."""
STOP_TIMEOUT = GRACE + 30
"""Seconds a test waits for ``ros2 launch`` to end after its Ctrl-C before killing it: the
grace, launch's SIGKILL timeout (5 s) and a margin."""


def required() -> bool:
    """Whether a missing ROS 2 fails the ROS 2 live tests rather than skipping them."""
    return os.environ.get("IMROSC_REQUIRE_ROS2", "").lower() not in ("", "0", "false", "no")


def _probe(candidate: str, imports: str) -> bool:
    try:
        done = subprocess.run(
            [candidate, "-c", imports], capture_output=True, check=False, timeout=60
        )
    except (OSError, subprocess.TimeoutExpired):
        return False
    return done.returncode == 0


def _find_python() -> str | None:
    for candidate in (os.environ.get("IMROSC_ROS2_PYTHON"), sys.executable):
        if candidate and Path(candidate).exists() and _probe(candidate, RCLPY_IMPORTS):
            return candidate
    return None


ROS2_PYTHON = _find_python()
"""An interpreter with rclpy and the message packages the tests use, or ``None``."""


def require_ros2() -> str:
    """The interpreter with rclpy; skips the test without it (fails it when required)."""
    if ROS2_PYTHON is not None:
        return ROS2_PYTHON
    named = os.environ.get("IMROSC_ROS2_PYTHON")
    reason = (
        f"IMROSC_ROS2_PYTHON={named} cannot {RCLPY_IMPORTS!r}"
        if named
        else "needs rclpy (set IMROSC_ROS2_PYTHON; make test builds a ROS 2 virtualenv)"
    )
    if required():
        pytest.fail(f"ROS 2 live test cannot run under IMROSC_REQUIRE_ROS2: {reason}", False)
    pytest.skip(reason)


def require_launch() -> Path:
    """The bin folder of a ROS 2 virtualenv with colcon and ``ros2 launch`` (the one
    ``tools/ros2_venv.sh`` builds); skips without it (fails when required)."""
    python = require_ros2()
    bin_folder = Path(python).parent
    tools = [bin_folder / "ros2", bin_folder / "colcon"]
    if all(tool.exists() for tool in tools) and _probe(python, LAUNCH_IMPORTS):
        return bin_folder
    reason = f"{bin_folder} has no colcon or ros2 launch (tools/ros2_venv.sh installs them)"
    if required():
        pytest.fail(f"ROS 2 live test cannot run under IMROSC_REQUIRE_ROS2: {reason}", False)
    pytest.skip(reason)


DOMAINS = range(1, 200)
"""The DDS domains of the tests' graphs (0, ROS 2's default, is left to what runs by hand)."""
DOMAIN_LOCKS = Path(tempfile.gettempdir()) / "imrosc-ros2-domains"
_held: list[int] = []
"""The lock files' descriptors (not inherited by the processes the tests start)."""


def private_domain() -> int:
    """A DDS domain that no other process on this machine holds through this function: a
    random one whose lock file (under :data:`DOMAIN_LOCKS`) this process could lock, held
    until it ends (the system releases the lock then).

    Discovery stays on the machine, so two test runs at once (two checkouts, two CI jobs on
    one host) whose random domains meet see each other's nodes: a second publisher on a
    topic a monitor blocks breaks its alarm's episodes with good messages, and bad ones are
    relayed past the alarm. Without a usable lock folder: a random domain."""
    candidates = random.sample(DOMAINS, len(DOMAINS))
    try:
        DOMAIN_LOCKS.mkdir(exist_ok=True)
    except OSError:
        return candidates[0]
    for domain in candidates:
        try:
            handle = os.open(DOMAIN_LOCKS / f"{domain}.lock", os.O_CREAT | os.O_RDWR, 0o666)
        except OSError:
            continue
        try:
            fcntl.flock(handle, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError:  # another process's graph is on it
            os.close(handle)
            continue
        _held.append(handle)
        return domain
    return candidates[0]


def ros2_environment(folder: Path, **extra: str) -> dict[str, str]:
    """The environment of a test's own ROS 2 graph: a domain of its own on this machine
    (:func:`private_domain`), discovery on this machine only, logs under ``folder`` unless
    ``ROS_LOG_DIR`` is set already."""
    environment = {
        **os.environ,
        "ROS_DOMAIN_ID": str(private_domain()),
        "ROS_AUTOMATIC_DISCOVERY_RANGE": "LOCALHOST",
        "PYTHONUNBUFFERED": "1",
        **extra,
    }
    if not environment.get("ROS_LOG_DIR"):
        environment["ROS_LOG_DIR"] = str(folder / "ros_log")
    return environment


if signal.getsignal(signal.SIGINT) is signal.SIG_IGN:
    # a test run in the background of a non-interactive shell (`make test &`) ignores
    # SIGINT, and so would every process it starts: `ros2 launch`, which reacts to SIGINT
    # only where Python has a handler for it, would never stop on the tests' Ctrl-C (the
    # launch then killed after its timeout). Handled here, it is default again in children.
    signal.signal(signal.SIGINT, signal.default_int_handler)


class Reader:
    """A process started with its output (stdout and stderr together) read line by line as
    it comes, for waiting on what it prints."""

    def __init__(
        self,
        command: Sequence[str],
        env: Mapping[str, str],
        cwd: Path | None = None,
        stdin: bool = False,
    ) -> None:
        self.popen = subprocess.Popen(
            list(command),
            env=dict(env),
            cwd=cwd,
            stdin=subprocess.PIPE if stdin else subprocess.DEVNULL,
            stdout=subprocess.PIPE,
            stderr=subprocess.STDOUT,
            text=True,
            start_new_session=True,  # its own process group: a signal reaches its children
        )
        self.lines: list[str] = []
        self.ended = False
        self._reader = threading.Thread(target=self._read, daemon=True)
        self._reader.start()

    def _read(self) -> None:
        assert self.popen.stdout is not None
        for line in self.popen.stdout:
            self.lines.append(line.rstrip("\n"))
        self.ended = True

    @property
    def output(self) -> str:
        return "\n".join(self.lines)

    def wait_for(self, text: str, timeout: float = 30.0) -> str:
        """The first line (printed so far or from now on) that contains ``text``; raises
        AssertionError with the output after ``timeout`` seconds or when the output ends."""
        deadline = time.monotonic() + timeout
        while True:
            ended = self.ended
            found = next((line for line in list(self.lines) if text in line), None)
            if found is not None:
                return found
            if ended:
                raise AssertionError(f"the output ended before {text!r}:\n{self.output}")
            if time.monotonic() > deadline:
                raise AssertionError(f"timed out waiting for {text!r}:\n{self.output}")
            time.sleep(0.05)

    def send(self, line: str) -> None:
        assert self.popen.stdin is not None
        self.popen.stdin.write(line + "\n")
        self.popen.stdin.flush()

    def stop(
        self, signal_number: int = signal.SIGINT, timeout: float = 20.0, group: bool = False
    ) -> int:
        """Send ``signal_number`` to the process (``group``: to its process group, as Ctrl-C
        in a terminal does); kill the group after ``timeout`` seconds. The return code
        (negative: a signal ended it)."""
        if self.popen.poll() is None:
            with contextlib.suppress(ProcessLookupError):
                if group:
                    os.killpg(self.popen.pid, signal_number)
                else:
                    self.popen.send_signal(signal_number)
            try:
                self.popen.wait(timeout=timeout)
            except subprocess.TimeoutExpired:
                self.kill()
        self.read_to_the_end()
        return self.popen.returncode

    def read_to_the_end(self, timeout: float = 10.0) -> None:
        """Wait (at most ``timeout`` seconds) until what the ended process wrote is in
        :attr:`lines`: its last lines may still be in the pipe when it exits, on a loaded
        machine for a while (a child that keeps the pipe open past ``timeout`` is not waited
        for)."""
        self._reader.join(timeout)

    def kill(self) -> None:
        """Kill the process group (what is left of it) at once."""
        with contextlib.suppress(ProcessLookupError):
            os.killpg(self.popen.pid, signal.SIGKILL)
        self.popen.wait()
        self.read_to_the_end()

    def alive_in_group(self) -> list[int]:
        """The processes still in the process group (children a launch left behind)."""
        found = []
        for entry in Path("/proc").iterdir():
            if not entry.name.isdigit():
                continue
            try:
                fields = (entry / "stat").read_text().rsplit(")", 1)[1].split()
            except OSError:
                continue
            if int(fields[2]) == self.popen.pid and fields[0] != "Z":
                found.append(int(entry.name))
        return found


PARAMETER_TYPES = ((bool, 1, "bool_value"), (int, 2, "integer_value"), (float, 3, "double_value"))


def parameter_value(value: Any) -> SimpleNamespace:
    """An ``rcl_interfaces/ParameterValue`` as a ROS 2 parameter service answers it."""
    answer = SimpleNamespace(type=0)
    for kind, code, field in PARAMETER_TYPES:
        if isinstance(value, kind):
            answer.type = code
            setattr(answer, field, value)
            return answer
    if isinstance(value, str):
        answer.type, answer.string_value = 4, value
    elif isinstance(value, list) and all(isinstance(v, float) for v in value):
        answer.type, answer.double_array_value = 8, value
    return answer
