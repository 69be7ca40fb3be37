"""A real ROS 1 graph for the live tests (and ``bench/monitor_latency.py``).

:class:`Ros` starts Debian's ``roscore`` on a free port of 127.0.0.1 with ``ROS_HOME`` and
``ROS_LOG_DIR`` in a temporary folder, waits for the master (its XML-RPC
``getSystemState``), and starts rospy node scripts under ``/usr/bin/python3`` (rospy is not
importable by the interpreter that runs pytest), ``roslaunch`` files and ``rosbag record``,
all with the same environment. Every process it starts runs in its own session and carries a
token in its environment; :meth:`Ros.shutdown` interrupts them (roslaunch and roscore take
their children down), then kills by pid whatever still carries the token (a node roslaunch
started in a session of its own included), so nothing outlives the test module.

The node scripts of ``tests/live/nodes`` are copied into a ROS package, ``imrosc_live``, on
the ``ROS_PACKAGE_PATH`` of the graph, so launch files can start them.
"""

from __future__ import annotations

import contextlib
import functools
import http.client
import json
import os
import shutil
import signal
import socket
import subprocess
import time
import uuid
import xmlrpc.client
from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, TypeVar

from imrosc.bags import open_bag

HERE = Path(__file__).resolve().parent
NODES = HERE / "nodes"
SYSTEM_LAUNCH = "landing.launch"
"""The launch file of the test system, in the ``imrosc_live`` package."""
CONFIG = HERE / "landing_live.xml"
"""The configuration of the test system (its ``<detect>`` reads ``bags/nominal``)."""
SYSTEM_TOPICS = ("/a/car_pose", "/a/cmd_subject_ctrl_state", "/a/subject_ctrl_state")
ROSCORE = Path("/usr/bin/roscore")
ROSLAUNCH = Path("/usr/bin/roslaunch")
ROSBAG = Path("/usr/bin/rosbag")
ROS_PYTHON = Path("/usr/bin/python3")
PACKAGE = "imrosc_live"
TOKEN_VARIABLE = "IMROSC_LIVE_TOKEN"
CONNECTIONS_VARIABLE = "IMROSC_LIVE_CONNECTIONS"
"""The folder the test system's publishers write their subscribers' connections to."""
CALLER_ID = "/imrosc_live_test"
ROS_MODULES = (
    "rospy",
    "rosbag",
    "roslaunch",
    "numpy",
    "std_msgs.msg",
    "geometry_msgs.msg",
    "sensor_msgs.msg",
)
DEBIAN_PACKAGES = (
    "ros-core python3-rospy python3-std-msgs python3-geometry-msgs python3-sensor-msgs "
    "python3-std-srvs python3-rosbag python3-numpy python3-yaml"
)

T = TypeVar("T")


class RosError(Exception):
    """The master refused a call, or a ROS process did not do what was expected."""


@functools.cache
def ros_missing() -> str | None:
    """Why the live tests cannot run here (None: they can)."""
    for tool in (ROSCORE, ROSLAUNCH, ROSBAG, ROS_PYTHON):
        if not tool.exists():
            return f"{tool} is missing (install Debian's {DEBIAN_PACKAGES}; `make test` does)"
    try:
        done = subprocess.run(
            [str(ROS_PYTHON), "-c", "import " + ", ".join(ROS_MODULES)],
            env=_clean_environment(),
            capture_output=True,
            text=True,
            timeout=60,
            check=False,
        )
    except (OSError, subprocess.TimeoutExpired) as error:
        return f"{ROS_PYTHON} cannot run: {error}"
    if done.returncode:
        last = (done.stderr.strip().splitlines() or ["?"])[-1]
        return f"{ROS_PYTHON} cannot import rospy and the message packages: {last}"
    return None


@functools.cache
def ros_python_version_of(module: str) -> str | None:
    """The version of ``module`` as Debian's python imports it (``None``: it cannot; the
    monitor's optional numba, for one)."""
    if not ROS_PYTHON.exists():
        return None
    try:
        done = subprocess.run(
            [str(ROS_PYTHON), "-c", f"import {module}; print({module}.__version__)"],
            env=_clean_environment(),
            capture_output=True,
            text=True,
            timeout=120,
            check=False,
        )
    except (OSError, subprocess.TimeoutExpired):
        return None
    return done.stdout.strip() if done.returncode == 0 else None


def _clean_environment() -> dict[str, str]:
    """This process's environment without what would mislead Debian's Python or ROS."""
    dropped = ("ROS_", "PYTHON", "VIRTUAL_ENV", "PYENV", "CONDA", TOKEN_VARIABLE)
    env = {k: v for k, v in os.environ.items() if not k.startswith(dropped)}
    env["PATH"] = "/usr/bin:/bin:" + env.get("PATH", "")
    env["PYTHONDONTWRITEBYTECODE"] = "1"
    env["PYTHONUNBUFFERED"] = "1"
    return env


def free_port() -> int:
    """A TCP port of 127.0.0.1 that nothing listens on now."""
    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as probe:
        probe.bind(("127.0.0.1", 0))
        port: int = probe.getsockname()[1]
        return port


def token_pids(token: str) -> list[int]:
    """Processes whose environment carries ``token`` (those a :class:`Ros` started)."""
    marker = f"{TOKEN_VARIABLE}={token}".encode()
    found = []
    for entry in Path("/proc").iterdir():
        if not entry.name.isdigit():
            continue
        try:
            environ = (entry / "environ").read_bytes()
        except OSError:
            continue
        if marker in environ.split(b"\0"):
            found.append(int(entry.name))
    return found


def _group_alive(group: int) -> bool:
    """Whether a process group has a member that is not a zombie."""
    for entry in Path("/proc").iterdir():
        if not entry.name.isdigit():
            continue
        try:
            fields = (entry / "stat").read_text().rsplit(")", 1)[1].split()
        except (OSError, IndexError):
            continue
        if int(fields[2]) == group and fields[0] != "Z":
            return True
    return False


def wait_until(
    predicate: Callable[[], T | None],
    what: str,
    timeout: float = 20.0,
    watch: Iterable[Proc] = (),
    interval: float = 0.05,
) -> T:
    """Poll ``predicate`` until it returns something true, and return that.

    Raises AssertionError after ``timeout`` seconds, or at once when a watched process has
    exited (with the end of its log).
    """
    deadline = time.monotonic() + timeout
    watched = list(watch)
    while True:
        value = predicate()
        if value:
            return value
        for proc in watched:
            if proc.popen.poll() is not None:
                raise AssertionError(
                    f"{proc.name} exited ({proc.popen.returncode}) while waiting for {what}:\n"
                    f"{proc.tail()}"
                )
        if time.monotonic() >= deadline:
            raise AssertionError(f"timed out after {timeout:g} s waiting for {what}")
        time.sleep(interval)


@dataclass
class Proc:
    """A process of the graph: its name (for messages), the process, its output file."""

    name: str
    popen: subprocess.Popen[bytes]
    log: Path

    @property
    def alive(self) -> bool:
        return self.popen.poll() is None

    def tail(self, lines: int = 30) -> str:
        """The end of what the process printed."""
        try:
            text = self.log.read_text(encoding="utf-8", errors="replace")
        except OSError:
            return ""
        return "\n".join(text.splitlines()[-lines:])


@dataclass
class Listener:
    """A ``listener.py`` node: every message of its topics, as JSON lines in a file."""

    proc: Proc
    path: Path
    topics: tuple[str, ...]

    def messages(self, topic: str | None = None) -> list[dict[str, Any]]:
        """Every message written so far (a half-written last line is left out)."""
        try:
            text = self.path.read_text(encoding="utf-8")
        except FileNotFoundError:
            return []
        found = []
        for line in text.splitlines():
            try:
                record = json.loads(line)
            except json.JSONDecodeError:
                continue
            if topic is None or record["topic"] == topic:
                found.append(record)
        return found

    def wait(
        self,
        predicate: Callable[[list[dict[str, Any]]], bool],
        what: str,
        timeout: float = 20.0,
        topic: str | None = None,
    ) -> list[dict[str, Any]]:
        """Wait until ``predicate`` holds for the messages so far; return them."""
        found: list[dict[str, Any]] = []

        def check() -> bool:
            nonlocal found
            found = self.messages(topic)
            return predicate(found)

        wait_until(check, what, timeout, (self.proc,))
        return found

    def wait_count(
        self, count: int, topic: str | None = None, timeout: float = 20.0
    ) -> list[dict[str, Any]]:
        """Wait for at least ``count`` messages (of ``topic``)."""
        what = f"{count} message(s) on {topic or ', '.join(self.topics)}"
        return self.wait(lambda found: len(found) >= count, what, timeout, topic)


@dataclass
class Recording:
    """A running ``rosbag record``."""

    proc: Proc
    bag: Path
    split: bool

    def _pattern(self) -> str:
        return f"{self.bag.stem}_*.bag" if self.split else self.bag.name

    def active(self) -> list[Path]:
        """The bags still being written."""
        return sorted(self.bag.parent.glob(self._pattern() + ".active"))

    def bags(self) -> list[Path]:
        """The closed bags."""
        return sorted(self.bag.parent.glob(self._pattern()))


@dataclass
class SystemState:
    """The master's ``getSystemState``: topic or service -> node names."""

    publishers: dict[str, set[str]] = field(default_factory=dict)
    subscribers: dict[str, set[str]] = field(default_factory=dict)
    services: dict[str, set[str]] = field(default_factory=dict)


class _Transport(xmlrpc.client.Transport):
    """XML-RPC over HTTP with a timeout: a hung master fails a test instead of hanging it."""

    def __init__(self, timeout: float) -> None:
        super().__init__()
        self._timeout = timeout

    def make_connection(self, host: Any) -> http.client.HTTPConnection:
        connection = super().make_connection(host)
        connection.timeout = self._timeout
        return connection


def build_package(root: Path) -> Path:
    """``root/imrosc_live``: the node scripts and launch files as a ROS package."""
    package = root / PACKAGE
    if package.exists():
        shutil.rmtree(package)
    package.mkdir(parents=True)
    for source in sorted(NODES.iterdir()):
        if source.suffix in (".py", ".launch"):
            target = package / source.name
            shutil.copyfile(source, target)
            target.chmod(0o755 if source.suffix == ".py" else 0o644)
    (package / "package.xml").write_text(
        '<?xml version="1.0"?>\n<package format="2">\n'
        f"  <name>{PACKAGE}</name>\n  <version>0.0.0</version>\n"
        "  <description>The live test system of imrosc.</description>\n"
        '  <maintainer email="imrosc@localhost">imrosc</maintainer>\n'
        "  <license>Apache-2.0</license>\n"
        "  <buildtool_depend>catkin</buildtool_depend>\n</package>\n",
        encoding="utf-8",
    )
    return package


class Ros:
    """A roscore on a free port and the processes started against it."""

    def __init__(self, home: Path) -> None:
        home.mkdir(parents=True, exist_ok=True)
        self.home = home
        self.port = free_port()
        self.uri = f"http://127.0.0.1:{self.port}"
        self.token = uuid.uuid4().hex
        self.package = build_package(home / "packages")
        self.connections_dir = home / "connections"
        """Where the test system's publishers note their subscribers (``nodes/livenode.py``)."""
        self.connections_dir.mkdir(exist_ok=True)
        self.env = _clean_environment()
        self.env.update(
            {
                "ROS_MASTER_URI": self.uri,
                "ROS_HOSTNAME": "127.0.0.1",
                "ROS_HOME": str(home / "ros_home"),
                "ROS_LOG_DIR": str(home / "ros_log"),
                "ROS_PACKAGE_PATH": str(self.package.parent),
                "ROSCONSOLE_STDOUT_LINE_BUFFERED": "1",
                TOKEN_VARIABLE: self.token,
                CONNECTIONS_VARIABLE: str(self.connections_dir),
            }
        )
        self.processes: list[Proc] = []
        self.core: Proc | None = None
        self._count = 0

    # -- processes ---------------------------------------------------------------------------

    def start(self, timeout: float = 30.0) -> Ros:
        """Start roscore and wait until its master answers; returns self."""
        self.core = self.spawn("roscore", [str(ROSCORE), "-p", str(self.port)])
        wait_until(self._master_up, f"the master at {self.uri}", timeout, (self.core,))
        self.wait_publisher("/rosout_agg", "/rosout", timeout, (self.core,))  # roscore is up
        return self

    def spawn(self, name: str, command: Sequence[str], cwd: Path | None = None) -> Proc:
        """Start a process with the graph's environment, in a session of its own."""
        self._count += 1
        log = self.home / "logs" / f"{self._count:02d}-{name.strip('/').replace('/', '_')}.log"
        log.parent.mkdir(exist_ok=True)
        with log.open("wb") as out:
            popen = subprocess.Popen(
                list(command),
                env=self.env,
                cwd=cwd or self.home,
                stdin=subprocess.DEVNULL,
                stdout=out,
                stderr=subprocess.STDOUT,
                start_new_session=True,
            )
        proc = Proc(name, popen, log)
        self.processes.append(proc)
        return proc

    def node(
        self,
        script: str,
        *args: str,
        name: str | None = None,
        namespace: str | None = None,
        remap: Mapping[str, str] | None = None,
        params: Mapping[str, Any] | None = None,
    ) -> Proc:
        """Start a node script of ``tests/live/nodes`` under ``/usr/bin/python3``.

        ``name`` and ``namespace`` become ``__name:=`` and ``__ns:=``, ``remap`` plain
        remappings, ``params`` private parameters (``_key:=value``).
        """
        command = [str(ROS_PYTHON), str(self.package / script), *args]
        if name:
            command.append(f"__name:={name}")
        if namespace:
            command.append(f"__ns:={namespace}")
        command += [f"{source}:={target}" for source, target in (remap or {}).items()]
        command += [f"_{key}:={value}" for key, value in (params or {}).items()]
        label = f"{namespace or ''}/{name or Path(script).stem}"
        return self.spawn(label, command)

    def launch(self, file: Path | str, **args: str) -> Proc:
        """Run ``roslaunch`` on a file (a path, or a name in the ``imrosc_live`` package)."""
        path = Path(file) if os.sep in str(file) else self.package / str(file)
        command = [str(ROSLAUNCH), "--skip-log-check", str(path)]
        command += [f"{key}:={value}" for key, value in args.items()]
        return self.spawn(f"roslaunch-{path.stem}", command)

    def add_package_path(self, path: Path) -> None:
        """Put a folder of ROS packages first on the ``ROS_PACKAGE_PATH`` of later processes."""
        self.env["ROS_PACKAGE_PATH"] = f"{path}{os.pathsep}{self.env['ROS_PACKAGE_PATH']}"

    def listen(self, *topics: str, timeout: float = 20.0) -> Listener:
        """Start a ``listener.py`` on ``topics`` and wait until the master lists it."""
        self._count += 1
        name = f"listener_{self._count}"
        path = self.home / f"{name}.jsonl"
        proc = self.node("listener.py", "--out", str(path), *topics, name=name)
        for topic in topics:
            self.wait_subscriber(topic, "/" + name, timeout, (proc,))
        return Listener(proc, path, topics)

    def start_recording(
        self, bag: Path, topics: Sequence[str], split: float | None = None
    ) -> Recording:
        """Start ``rosbag record -O bag topics`` and wait until it records.

        ``split``: seconds per bag (``--split --duration``); the bags are then
        ``<stem>_0.bag``, ``<stem>_1.bag``, ... beside ``bag``.
        """
        command = [str(ROSBAG), "record", "-O", str(bag)]
        if split is not None:
            command += ["--split", f"--duration={split}"]
        proc = self.spawn(f"rosbag-record-{bag.stem}", [*command, *topics])
        recording = Recording(proc, bag, split is not None)

        def subscribed() -> bool:
            state = self.system_state()
            return all(
                any(node.startswith("/record_") for node in state.subscribers.get(topic, ()))
                for topic in topics
            )

        wait_until(subscribed, f"rosbag record to subscribe to {', '.join(topics)}", 30, (proc,))
        wait_until(recording.active, f"rosbag record to open {bag}", 10, (proc,))
        return recording

    def finish_recording(self, recording: Recording) -> list[Path]:
        """Stop a recording (as Ctrl-C does) and wait until its bags are closed."""
        self.stop(recording.proc)
        # the recorder renames a bag from .active when it closes it
        what = f"rosbag record to close {recording.bag}"
        wait_until(lambda: not recording.active() and recording.bags(), what, 15)
        return recording.bags()

    def record(
        self,
        bag: Path,
        topics: Sequence[str],
        seconds: float,
        during: Callable[[], None] | None = None,
    ) -> Path:
        """``rosbag record`` of ``topics`` into ``bag`` for ``seconds`` (from when it has
        subscribed); ``during`` runs once recording has started. Returns the bag."""
        recording = self.start_recording(bag, topics)
        started = time.monotonic()
        if during is not None:
            during()
        time.sleep(max(0.0, seconds - (time.monotonic() - started)))
        self.finish_recording(recording)
        return bag

    def stop(self, *procs: Proc, timeout: float = 15.0) -> None:
        """Interrupt the processes' sessions (SIGINT, as Ctrl-C; all at once, as each takes a
        while to shut down), then terminate, then kill, until every member of each session
        is gone."""
        steps = ((signal.SIGINT, timeout), (signal.SIGTERM, 3.0), (signal.SIGKILL, 3.0))
        left = [p for p in procs if _group_alive(p.popen.pid)]
        for sig, grace in steps:
            for proc in left:
                with contextlib.suppress(ProcessLookupError, PermissionError):
                    os.killpg(proc.popen.pid, sig)
            deadline = time.monotonic() + grace
            for proc in left:
                with contextlib.suppress(subprocess.TimeoutExpired):
                    proc.popen.wait(max(0.0, deadline - time.monotonic()))
            while time.monotonic() < deadline and any(_group_alive(p.popen.pid) for p in left):
                time.sleep(0.02)
            left = [p for p in left if _group_alive(p.popen.pid)]
            if not left:
                break
        for proc in procs:
            proc.popen.poll()
            if proc in self.processes:
                self.processes.remove(proc)

    def shutdown(self) -> list[int]:
        """Stop every process, roscore last, then kill what still carries the token.

        Returns the pids that had to be killed that way (a clean shutdown leaves none).
        """
        self.stop(*[p for p in reversed(self.processes) if p is not self.core])
        if self.core is not None:
            self.stop(self.core)
        strays = token_pids(self.token)
        for pid in strays:
            with contextlib.suppress(ProcessLookupError):
                os.kill(pid, signal.SIGKILL)
        if strays:
            wait_until(lambda: not token_pids(self.token), "stray processes to die", 10)
        return strays

    # -- the master --------------------------------------------------------------------------

    def master(self, timeout: float = 10.0) -> xmlrpc.client.ServerProxy:
        """An XML-RPC proxy of the master."""
        return xmlrpc.client.ServerProxy(self.uri, transport=_Transport(timeout))

    def call(self, method: str, *args: Any) -> Any:
        """Call the master API; a failure code raises :class:`RosError`."""
        code, message, value = getattr(self.master(), method)(CALLER_ID, *args)
        if code != 1:
            raise RosError(f"{method}{args}: {message}")
        return value

    def _master_up(self) -> bool:
        try:
            self.call("getSystemState")
        except (OSError, xmlrpc.client.Error, RosError):
            return False
        return True

    def system_state(self) -> SystemState:
        """Who publishes, subscribes and serves what, now."""
        pubs, subs, srvs = self.call("getSystemState")
        return SystemState(
            {topic: set(nodes) for topic, nodes in pubs},
            {topic: set(nodes) for topic, nodes in subs},
            {service: set(nodes) for service, nodes in srvs},
        )

    def publishers(self, topic: str) -> set[str]:
        return self.system_state().publishers.get(topic, set())

    def subscribers(self, topic: str) -> set[str]:
        return self.system_state().subscribers.get(topic, set())

    def wait_publisher(
        self, topic: str, node: str | None = None, timeout: float = 20.0, watch: Iterable[Proc] = ()
    ) -> set[str]:
        """Wait until ``topic`` has a publisher (``node``, when given); return them."""
        what = f"{node or 'a publisher'} on {topic}"
        return wait_until(lambda: self._having(self.publishers(topic), node), what, timeout, watch)

    def wait_subscriber(
        self, topic: str, node: str | None = None, timeout: float = 20.0, watch: Iterable[Proc] = ()
    ) -> set[str]:
        """Wait until ``topic`` has a subscriber (``node``, when given); return them."""
        what = f"{node or 'a subscriber'} of {topic}"
        return wait_until(lambda: self._having(self.subscribers(topic), node), what, timeout, watch)

    @staticmethod
    def _having(nodes: set[str], node: str | None) -> set[str]:
        return nodes if (node in nodes if node else nodes) else set()

    def connections(self, node: str) -> list[str]:
        """What ``node`` (of the test system) notes of its subscribers: ``"<topic>
        <subscriber> <0|1>"``, 1 for a connection with TCP_NODELAY (``nodes/livenode.py``)."""
        path = self.connections_dir / (node.strip("/").replace("/", "-") + ".txt")
        return path.read_text(encoding="utf-8").splitlines() if path.exists() else []

    def get_param(self, name: str) -> Any:
        return self.call("getParam", name)

    def set_param(self, name: str, value: Any) -> None:
        self.call("setParam", name, value)

    def has_param(self, name: str) -> bool:
        return bool(self.call("hasParam", name))

    def delete_param(self, name: str) -> None:
        with contextlib.suppress(RosError):
            self.call("deleteParam", name)

    # -- the test system ---------------------------------------------------------------------

    def start_system(
        self, launch: Path | str = SYSTEM_LAUNCH, log: Path | None = None, **args: str
    ) -> Proc:
        """Launch the test system (car, controller, state machine) and wait until it runs.

        ``log``: the file the state machine writes the commands it receives to.
        """
        proc = self.launch(launch, log=str(log or ""), **args)
        watch = (proc,)
        self.wait_publisher("/a/car_pose", "/a/car", 30, watch)
        self.wait_publisher("/a/cmd_subject_ctrl_state", "/a/car_ctrl", 30, watch)
        self.wait_publisher("/a/subject_ctrl_state", "/a/ctrl_state_machine", 30, watch)
        return proc

    def inject(self, node: str, fault: str) -> None:
        """Set a node's ``~fault`` parameter (see ``nodes/livenode.py``)."""
        self.set_param(f"{node}/fault", fault)


def live_config(folder: Path) -> Path:
    """A copy of the test system's configuration (and the launch file it names) in
    ``folder``; its ``<detect>`` bags go to ``folder/bags/nominal``."""
    (folder / "nodes").mkdir(parents=True, exist_ok=True)
    (folder / "bags" / "nominal").mkdir(parents=True, exist_ok=True)
    shutil.copyfile(NODES / SYSTEM_LAUNCH, folder / "nodes" / SYSTEM_LAUNCH)
    return Path(shutil.copy(CONFIG, folder / CONFIG.name))


def record_nominal(ros: Ros, folder: Path, seconds: float = 4.0) -> list[Path]:
    """Record the running test system into ``folder``: one bag of ``seconds`` and, at the
    same time, the same split into bags of 0.5 s.

    The long bag gives the time windows (frequency, variance, rate need a full window of
    1 s); the short ones give the architecture invariants enough runs: a bag recorded by
    ``rosbag record`` tells its publishers (``callerid``) once, and an invariant needs seven
    observations at the default confidence.
    """
    whole = ros.start_recording(folder / "nominal.bag", SYSTEM_TOPICS)
    split = ros.start_recording(folder / "split.bag", SYSTEM_TOPICS, split=0.5)
    time.sleep(seconds)
    bags = ros.finish_recording(whole) + ros.finish_recording(split)
    kept = []
    for bag in bags:
        # stopped just after a split, rosbag record leaves a last bag with nothing in it:
        # inference skips it, but it would tell replay that nobody published
        with open_bag(bag) as reader:
            empty = reader.message_count == 0
        if empty:
            bag.unlink()
        else:
            kept.append(bag)
    return kept
