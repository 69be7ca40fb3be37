"""One recording: ``rosbag record`` and the recording node, started and stopped in order.

Start: ``rosbag record`` first (as the node ``/imrosc_rosbag_<pid>``), and once the master
lists its subscriptions, the recording node (``/imrosc_recorder_<pid>``,
:mod:`imrosc.onboard.record_ros1.node` under the ROS Python, with only ``imrosc`` on its
module path: :func:`link_package`). The node publishes nothing before rosbag is connected
to its three record topics, then publishes the first snapshots, starts its relays and says
``ready``: from then on nothing it records can be lost.

Stop (Ctrl-C, SIGTERM, the duration, or a process that died): the node first (its relays are
withdrawn, calls in flight answered and recorded, every record published), then, after a
short grace so that rosbag has stored the last records, ``rosbag record`` with SIGINT, which
closes and indexes the bag (``<name>.bag.active`` becomes ``<name>.bag``). Both run in
sessions of their own, so a Ctrl-C in the terminal reaches imrosc only and the order holds;
if imrosc itself dies they get SIGINT from the kernel (``PR_SET_PDEATHSIG``).

Their output goes to ``<output>/.imrosc/`` (a hidden folder: bag discovery skips it).

What a recording holds and does alike on ROS 1 and ROS 2 (its events, its start-up wait and
its loop) is :class:`Session`, which :class:`Recording` and ROS 2's
:class:`~imrosc.record.session_ros2.TapRecording` extend.
"""

from __future__ import annotations

import contextlib
import json
import os
import queue
import signal
import subprocess
import threading
import time
from abc import ABC, abstractmethod
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import IO, Any

from imrosc import records
from imrosc.bags import BagError, open_bag
from imrosc.record.master import MasterError, system_state
from imrosc.record.scope import Scope

__all__ = [
    "LOG_FOLDER",
    "RECORDER",
    "ROS_PYTHON",
    "Outcome",
    "RecordError",
    "Recording",
    "Session",
    "Settings",
    "find_rosbag_record",
]

PACKAGE = Path(__file__).resolve().parent.parent
"""The ``imrosc`` package folder (linked into the recorders' module path)."""
RECORDER = "imrosc.onboard.record_ros1.node"
"""The ROS 1 recording node, run with ``python -m`` under the ROS Python."""
ROS_PYTHON = "/usr/bin/python3"
LOG_FOLDER = ".imrosc"
STOP_GRACE = 0.5
"""Seconds between the recording node's exit and SIGINT to rosbag: rosbag stores the last
records it was sent (they are on its socket already)."""
_PROBE = (
    "import rospy, std_msgs.msg, roslib.packages as p\n"
    "found = p.find_node('rosbag', 'record')\n"
    "print(found[0] if found else '')\n"
)


def read_events(
    stream: IO[bytes], log: Path, put: Callable[[dict[str, Any]], None], source: str = ""
) -> None:
    """A recorder node's standard output, on either middleware: its events (one JSON object
    a line, with ``event``) to ``put``, tagged ``from`` ``source`` when one is given; its other
    lines to the ``log`` file."""
    with log.open("ab") as written:
        for line in stream:
            try:
                event = json.loads(line)
            except ValueError:
                event = None
            if isinstance(event, dict) and "event" in event:
                if source:
                    event["from"] = source
                put(event)
            else:
                written.write(line)


class RecordError(Exception):
    """Recording cannot start or did not end well; the message is one line."""


@dataclass(frozen=True)
class Settings:
    """How to record (the options of ``imrosc record``)."""

    output: Path
    name: str
    period: float = 1.0
    all_topics: bool = False
    all_params: bool = False
    python: str = ROS_PYTHON
    prefix: str = "/rec"
    ready_timeout: float = 30.0

    @property
    def bag(self) -> Path:
        return self.output / f"{self.name}.bag"

    @property
    def logs(self) -> Path:
        return self.output / LOG_FOLDER


@dataclass
class Outcome:
    """What a finished recording holds."""

    bag: Path
    seconds: float = 0.0
    messages: dict[str, int] = field(default_factory=dict)
    published: dict[str, int] = field(default_factory=dict)
    calls: dict[str, int] = field(default_factory=dict)
    relayed: set[str] = field(default_factory=set)


def child_environment(environment: Mapping[str, str], uri: str) -> dict[str, str]:
    """The environment of rosbag and the node: ours, with the master, without a namespace
    (the node names must be the ones imrosc chose) or a foreign Python home.

    >>> env = child_environment({"ROS_NAMESPACE": "/a", "PATH": "/bin"}, "http://h:1")
    >>> sorted(env.items())
    [('PATH', '/bin'), ('PYTHONUNBUFFERED', '1'), ('ROS_MASTER_URI', 'http://h:1')]
    """
    env = {k: v for k, v in environment.items() if k not in ("ROS_NAMESPACE", "PYTHONHOME")}
    env["ROS_MASTER_URI"] = uri
    env["PYTHONUNBUFFERED"] = "1"
    return env


def probe(python: str, env: Mapping[str, str], code: str, what: str, module: str) -> str:
    """What ``code`` prints when ``python`` (``what``: "the ROS Python") runs it, or
    :class:`RecordError` in one line: it cannot be run, or it cannot import ``module``."""
    try:
        done = subprocess.run(
            [python, "-c", code],
            env=dict(env),
            capture_output=True,
            text=True,
            timeout=60,
            check=False,
        )
    except (OSError, subprocess.TimeoutExpired) as error:
        raise RecordError(f"cannot run {what} {python}: {error}") from None
    if done.returncode != 0:
        last = (done.stderr.strip().splitlines() or ["it failed"])[-1]
        raise RecordError(f"{what} {python} cannot import {module}: {last}")
    return done.stdout


def with_module_path(environment: Mapping[str, str], folder: Path) -> dict[str, str]:
    """``environment`` with ``folder`` first on the Python path.

    >>> with_module_path({"PYTHONPATH": "/r", "A": "1"}, Path("/l"))
    {'PYTHONPATH': '/l:/r', 'A': '1'}
    """
    env = dict(environment)
    paths = [str(folder), *(p for p in env.get("PYTHONPATH", "").split(os.pathsep) if p)]
    env["PYTHONPATH"] = os.pathsep.join(paths)
    return env


def link_package(folder: Path) -> Path:
    """``folder/imrosc`` pointing at the ``imrosc`` package; ``folder`` is returned."""
    folder.mkdir(parents=True, exist_ok=True)
    link = folder / "imrosc"
    if link.is_symlink():
        if link.resolve() == PACKAGE:
            return folder
        link.unlink()  # imrosc's own link, to another checkout
    link.symlink_to(PACKAGE, target_is_directory=True)
    return folder


def find_rosbag_record(python: str, env: Mapping[str, str]) -> str:
    """The ``rosbag record`` program, as the ROS Python finds it (which also proves that
    rospy is importable there)."""
    found = probe(python, env, _PROBE, "the ROS Python", "rospy").strip()
    if not found:
        raise RecordError(f"the ROS Python {python} finds no 'rosbag record' (rosbag missing?)")
    return found


def _parent_death_signal() -> Callable[[], None] | None:
    """What makes a child get SIGINT from the kernel when imrosc dies (Linux's
    ``PR_SET_PDEATHSIG``), so that rosbag still closes the bag; None where there is none.

    Everything is looked up here, before the fork: the child only calls into libc.
    """
    try:
        import ctypes

        prctl = ctypes.CDLL(None, use_errno=True).prctl
    except (OSError, AttributeError):
        return None
    request, number = 1, int(signal.SIGINT)  # PR_SET_PDEATHSIG

    def ask() -> None:  # pragma: no cover - runs in the child, between fork and exec
        prctl(request, number)

    return ask


def _tail(path: Path) -> str:
    try:
        lines = path.read_text(encoding="utf-8", errors="replace").strip().splitlines()
    except OSError:
        return ""
    return lines[-1].strip() if lines else ""


class _Child:
    """A process of the recording, in a session of its own, with a log file."""

    def __init__(
        self,
        name: str,
        command: list[str],
        env: Mapping[str, str],
        log: Path,
        stdout: int | IO[bytes] | None = None,
        stdin: int = subprocess.DEVNULL,
        pass_fds: tuple[int, ...] = (),
    ) -> None:
        self.name = name
        self.log = log
        with log.open("wb") as out:
            self.popen = subprocess.Popen(
                command,
                env=dict(env),
                stdin=stdin,
                stdout=out if stdout is None else stdout,
                stderr=out,
                start_new_session=True,
                pass_fds=pass_fds,
                preexec_fn=_parent_death_signal(),  # noqa: PLW1509 - only a libc call
            )

    @property
    def alive(self) -> bool:
        return self.popen.poll() is None

    def interrupt(self, timeout: float) -> bool:
        """SIGINT (what Ctrl-C sends) and wait; SIGKILL after ``timeout``. True if clean."""
        if not self.alive:
            return True
        with contextlib.suppress(ProcessLookupError):
            self.popen.send_signal(signal.SIGINT)
        try:
            self.popen.wait(timeout)
            return True
        except subprocess.TimeoutExpired:
            self.popen.kill()
            self.popen.wait()
            return False

    def died(self) -> str:
        """``rosbag record exited with status 1: its last line`` (or ``was killed``)."""
        status = self.popen.returncode
        how = f"was killed (signal {-status})" if status < 0 else f"exited with status {status}"
        last = _tail(self.log)
        return f"{self.name} {how}" + (f": {last}" if last else "")


class Session(ABC):
    """What a recording holds and does alike on either middleware: the scope, the
    environment of its children, the recorder node, the events its children say (queued by
    their readers' threads, handled by :meth:`pump` on the caller's thread), the failure one
    of them reported, the outcome, and the loops of its start and of recording, which pump
    the events and check the children ten or twenty times a second.

    Each middleware handles an event (:meth:`handle`) and checks its children
    (:meth:`check_children`)."""

    def __init__(
        self,
        scope: Scope,
        env: Mapping[str, str],
        bag: Path,
        start_timeout: float,
        *,
        say: Callable[[str], None],
        warn: Callable[[str], None],
    ) -> None:
        self.scope = scope
        self.env = dict(env)
        self.start_timeout = start_timeout
        """Seconds the start waits at most for each of its steps."""
        self.say = say
        self.warn = warn
        self.node: _Child | None = None
        self.events: queue.Queue[dict[str, Any]] = queue.Queue()
        self.failure: str | None = None
        self.outcome = Outcome(bag)
        self.started = 0.0

    @abstractmethod
    def handle(self, event: dict[str, Any]) -> None:
        """Handle one event a child said."""

    @abstractmethod
    def check_children(self) -> None:
        """:class:`RecordError` when a child stopped or reported a failure."""

    def pump(self) -> None:
        """Handle what the children said since the last call."""
        while True:
            try:
                event = self.events.get_nowait()
            except queue.Empty:
                return
            self.handle(event)

    def wait(self, done: Callable[[], bool], stop: threading.Event, what: str) -> bool:
        """Pump and check the children, twenty times a second, until ``done()`` (True),
        ``stop`` is set (False) or :attr:`start_timeout` seconds have passed
        (:class:`RecordError` naming ``what``)."""
        deadline = time.monotonic() + self.start_timeout
        while not stop.is_set():
            self.pump()
            self.check_children()
            if done():
                return True
            if time.monotonic() > deadline:
                raise RecordError(f"timed out waiting for {what}")
            stop.wait(0.05)
        return False

    def run(self, stop: threading.Event, duration: float | None) -> None:
        """Record until ``stop`` is set or ``duration`` seconds have passed: pump and check
        the children ten times a second."""
        end = None if duration is None else self.started + duration
        while not stop.is_set():
            self.pump()
            self.check_children()
            now = time.monotonic()
            if end is not None and now >= end:
                return
            stop.wait(0.1 if end is None else min(0.1, max(0.0, end - now)))


class Recording(Session):
    """Starts, watches and stops one ROS 1 recording; :meth:`finish` must always be called."""

    def __init__(
        self,
        scope: Scope,
        settings: Settings,
        env: Mapping[str, str],
        uri: str,
        *,
        say: Callable[[str], None],
        warn: Callable[[str], None],
    ) -> None:
        super().__init__(
            scope, env, settings.bag, settings.ready_timeout + 10.0, say=say, warn=warn
        )
        self.settings = settings
        self.uri = uri
        tag = os.getpid()
        self.rosbag_name = f"/imrosc_rosbag_{tag}"
        self.node_name = f"/imrosc_recorder_{tag}"
        self.rosbag: _Child | None = None
        self.reader: threading.Thread | None = None
        self.ready = False

    # -- start ----------------------------------------------------------------------------

    def start(self, record_program: str, stop: threading.Event) -> bool:
        """Start rosbag and the node; False if ``stop`` was set before they were ready."""
        settings = self.settings
        settings.logs.mkdir(parents=True, exist_ok=True)
        topics = ["-a"] if settings.all_topics else [*self.scope.topics, *records.RECORD_TOPICS]
        command = [
            record_program,
            "-O",
            str(settings.bag),
            f"__name:={self.rosbag_name.lstrip('/')}",
            *topics,
        ]
        self.rosbag = _Child("rosbag record", command, self.env, settings.logs / "rosbag.log")
        wanted = () if settings.all_topics else (*self.scope.topics, *records.RECORD_TOPICS)
        if not self.wait(lambda: self._subscribed(wanted), stop, "rosbag record to subscribe"):
            return False
        spec = {
            "node": self.node_name,
            "rosbag": self.rosbag_name,
            "services": list(self.scope.services),
            "params": None if settings.all_params else list(self.scope.params),
            "period": settings.period,
            "prefix": settings.prefix,
            "ready_timeout": settings.ready_timeout,
        }
        command = [settings.python, "-m", RECORDER, json.dumps(spec)]
        env = with_module_path(self.env, link_package(settings.logs / "path"))
        self.node = _Child(
            "the recording node",
            command,
            env,
            settings.logs / "recorder.log",
            stdout=subprocess.PIPE,
        )
        assert self.node.popen.stdout is not None
        events = (self.node.popen.stdout, settings.logs / "recorder.events", self.events.put)
        self.reader = threading.Thread(target=read_events, args=events, daemon=True)
        self.reader.start()
        if not self.wait(lambda: self.ready, stop, "the recording node"):
            return False
        self.started = time.monotonic()
        return True

    def _subscribed(self, topics: tuple[str, ...]) -> bool:
        """Whether rosbag subscribes to every topic (with ``-a`` there is nothing to wait
        for here: the node waits until rosbag is connected to the record topics)."""
        if not topics:
            return True
        try:
            state = system_state(self.uri)
        except MasterError as error:
            raise RecordError(str(error)) from None
        return all(self.rosbag_name in state.subscribers.get(topic, ()) for topic in topics)

    # -- while recording --------------------------------------------------------------------

    def handle(self, event: dict[str, Any]) -> None:
        """Handle one event the node said."""
        kind = event.get("event")
        if kind == "ready":
            self.ready = True
        elif kind == "warning":
            self.warn(str(event.get("message", "")))
        elif kind == "error":
            self.failure = str(event.get("message", ""))
        elif kind == "relay":
            service = str(event.get("service", ""))
            self.outcome.relayed.add(service)
            raw = " (raw: its type cannot be imported)" if event.get("raw") else ""
            self.say(f"relaying {service} ({event.get('type')}) to {event.get('target')}{raw}")
        elif kind == "unrelay":
            self.say(f"{event.get('service')}: its server is gone; relay withdrawn")
        elif kind == "stats":
            self.outcome.published = dict(event.get("published") or {})
            self.outcome.calls = dict(event.get("calls") or {})

    def check_children(self) -> None:
        for child in (self.rosbag, self.node):
            if child is not None and not child.alive:
                if child is self.node and self.failure:
                    raise RecordError(f"the recording node stopped: {self.failure}")
                raise RecordError(child.died())

    # -- stop -----------------------------------------------------------------------------

    def finish(self) -> Outcome:
        """Stop the node, then rosbag; check and count the bag."""
        ended = time.monotonic()
        if self.node is not None:
            if not self.node.interrupt(15.0):
                self.warn("the recording node did not stop in time and was killed")
            if self.reader is not None:
                self.reader.join(5.0)
            self.pump()
            time.sleep(STOP_GRACE)
        if self.rosbag is not None and not self.rosbag.interrupt(30.0):
            self.warn("rosbag record did not stop in time and was killed")
        self.outcome.seconds = max(0.0, ended - self.started) if self.started else 0.0
        bag = self.settings.bag
        active = bag.with_name(bag.name + ".active")
        if active.exists():
            raise RecordError(
                f"rosbag did not close {active}; 'rosbag reindex {active}' may repair it"
            )
        if self.rosbag is None or not bag.exists():
            raise RecordError(f"no bag was written ({self.rosbag.died() if self.rosbag else ''})")
        try:
            with open_bag(bag) as reader:
                counts: dict[str, int] = {}
                for connection in reader.connections:
                    counts[connection.topic] = counts.get(connection.topic, 0) + connection.msgcount
        except BagError as error:
            raise RecordError(f"{bag}: {error.message}") from None
        self.outcome.messages = counts
        return self.outcome
