"""One ROS 2 recording: the bag tap and the recorder node, started and stopped in order, and
the MCAP bag imrosc writes from what the tap sends.

Start: the bag tap first (``/_imrosc_bag_<pid>``, hidden; :mod:`imrosc.onboard.record_ros2.tap`
under the ROS 2 Python). It subscribes to the record topics, describes the graph once
discovery settled, and imrosc answers with the topics of the scope (computed with that
graph: relative inputs); the tap describes the graph again when it changes, and imrosc
answers again when that changes the scope's topics. Once it says ``ready``, the recorder node
(``/imrosc_recorder_<pid>``, :mod:`imrosc.onboard.record_ros2`), which waits until the tap
subscribes to its record topics before it publishes its first snapshots, and says
``ready``.

While recording, a thread reads the tap's frames (:mod:`imrosc.onboard.record_ros2.wire`) and
writes each message into the bag at once (:class:`imrosc.record.mcap.BagSink`).

Stop (Ctrl-C, SIGTERM, the duration, or a process that died): the recorder first (the calls
still waiting are published), then, after a short grace so that the tap has received them,
the tap with SIGINT: it closes the pipe, the thread writes what is left, and imrosc closes
the bag (MCAP summary and ``metadata.yaml``). Everything the tap received is in the bag.
Both processes run in sessions of their own (a Ctrl-C in the terminal reaches imrosc only)
and get SIGINT from the kernel if imrosc dies.

Their output goes to ``<output>/.imrosc/``, with the folder that puts imrosc's ROS 2
modules on the ROS 2 Python's path (a link to the ``imrosc`` package, nothing else).
"""

from __future__ import annotations

import contextlib
import importlib.util
import json
import os
import subprocess
import sys
import threading
import time
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import IO, Any

from rosbags.rosbag2 import WriterError

from imrosc.onboard.record_ros2 import wire
from imrosc.record.mcap import BagSink, SinkError
from imrosc.record.scope import Scope
from imrosc.record.session import (
    STOP_GRACE,
    Outcome,
    RecordError,
    Session,
    _Child,
    link_package,
    probe,
    read_events,
    with_module_path,
)

__all__ = [
    "PYTHON_VARIABLE",
    "Settings2",
    "TapRecording",
    "choose_python",
    "ros2_environment",
]

PYTHON_VARIABLE = "IMROSC_ROS2_PYTHON"
_PROBE = "import rclpy, std_msgs.msg\n"
TAP = "imrosc.onboard.record_ros2.tap"
RECORDER = "imrosc.onboard.record_ros2"
"""The recorder node as ``imrosc record`` runs it (its ``__main__``)."""


@dataclass(frozen=True)
class Settings2:
    """How to record on ROS 2 (the options of ``imrosc record``)."""

    output: Path
    name: str
    period: float = 1.0
    all_topics: bool = False
    python: str = sys.executable
    settle: float = 5.0
    """Seconds the tap waits at most for discovery before it describes the graph."""
    ready_timeout: float = 30.0

    @property
    def bag(self) -> Path:
        """The bag: a ROS 2 bag folder."""
        return self.output / self.name

    @property
    def logs(self) -> Path:
        return self.output / ".imrosc"


def choose_python(given: str | None, environment: Mapping[str, str]) -> str:
    """The ROS 2 Python: ``--python``, else ``$IMROSC_ROS2_PYTHON``, else this interpreter
    if it has rclpy; :class:`RecordError` saying what to set otherwise.

    >>> choose_python("/opt/py", {}), choose_python(None, {"IMROSC_ROS2_PYTHON": "/x/py"})
    ('/opt/py', '/x/py')
    """
    if given:
        return given
    named = environment.get(PYTHON_VARIABLE)
    if named:
        return named
    if importlib.util.find_spec("rclpy") is not None:
        return sys.executable
    raise RecordError(
        f"no Python with rclpy: set {PYTHON_VARIABLE} (or --python) to the ROS 2 "
        f"interpreter, e.g. /usr/bin/python3 after sourcing /opt/ros/jazzy/setup.bash"
    )


def check_python(python: str, env: Mapping[str, str]) -> None:
    """:class:`RecordError` unless ``python`` runs and imports rclpy and std_msgs."""
    probe(python, env, _PROBE, "the ROS 2 Python", "rclpy")


def ros2_environment(environment: Mapping[str, str], path_folder: Path) -> dict[str, str]:
    """The children's environment: ours, without a namespace or a foreign Python home, with
    ``path_folder`` (where ``imrosc`` is linked) first on the Python path.

    >>> env = ros2_environment({"ROS_NAMESPACE": "/a", "PYTHONPATH": "/r"}, Path("/l"))
    >>> sorted(env.items())
    [('PYTHONPATH', '/l:/r'), ('PYTHONUNBUFFERED', '1')]
    """
    kept = {k: v for k, v in environment.items() if k not in ("ROS_NAMESPACE", "PYTHONHOME")}
    env = with_module_path(kept, path_folder)
    env["PYTHONUNBUFFERED"] = "1"
    return env


class TapRecording(Session):
    """Starts, watches and stops one ROS 2 recording; :meth:`finish` must always be
    called. ``choose`` gets the graph the tap saw (an architecture record) and returns the
    topics to record."""

    def __init__(
        self,
        scope: Scope,
        settings: Settings2,
        env: Mapping[str, str],
        choose: Callable[[str], tuple[str, ...]],
        *,
        say: Callable[[str], None],
        warn: Callable[[str], None],
    ) -> None:
        timeout = settings.ready_timeout + settings.settle
        super().__init__(scope, env, settings.bag, timeout, say=say, warn=warn)
        self.settings = settings
        self.choose = choose
        tag = os.getpid()
        self.tap_name = f"_imrosc_bag_{tag}"
        self.node_name = f"imrosc_recorder_{tag}"
        self.tap: _Child | None = None
        self.sink: BagSink | None = None
        self.threads: list[threading.Thread] = []
        self.state: dict[str, Any] = {}
        self.topics: tuple[str, ...] | None = None
        """The topics the tap was told to record (``None`` before the first graph)."""
        self.received: dict[str, int] = {}
        """What the tap received, by topic (its last words)."""

    # -- start ----------------------------------------------------------------------------

    def start(self, stop: threading.Event) -> bool:
        """Start the tap and the recorder; False if ``stop`` was set before they were ready."""
        settings = self.settings
        try:
            settings.logs.mkdir(parents=True, exist_ok=True)
            env = ros2_environment(self.env, link_package(settings.logs / "path"))
            self.sink = BagSink(settings.bag)
        except (OSError, WriterError) as error:
            reason = error.strerror if isinstance(error, OSError) and error.strerror else error
            raise RecordError(f"{settings.output}: cannot write the bag: {reason}") from None
        read_end, write_end = os.pipe()
        spec = {
            "node": self.tap_name,
            "fd": write_end,
            "period": min(settings.period, 0.5),
            "settle": settings.settle,
            "expect": list(self.scope.topics),
        }
        try:
            self.tap = _Child(
                "the bag tap",
                [settings.python, "-m", TAP, json.dumps(spec)],
                env,
                settings.logs / "tap.log",
                stdin=subprocess.PIPE,
                pass_fds=(write_end,),
            )
        finally:
            os.close(write_end)
        self._thread(self._read_frames, os.fdopen(read_end, "rb"))
        if not self.wait(lambda: "graph" in self.state, stop, "the bag tap to see the graph"):
            return False
        self._choose(str(self.state["graph"]))
        if not self.wait(lambda: "tap ready" in self.state, stop, "the bag tap"):
            return False
        recorder = {
            "format": "imrosc-recorder",
            "version": 1,
            "node": self.node_name,
            "services": list(self.scope.services),
            "params": list(self.scope.params),
            "period": settings.period,
            "events": True,
            "wait": 10.0,
        }
        self.node = _Child(
            "the recorder node",
            [settings.python, "-m", RECORDER, json.dumps(recorder)],
            env,
            settings.logs / "recorder.log",
            stdout=subprocess.PIPE,
        )
        assert self.node.popen.stdout is not None
        self._thread(self._read_lines, self.node.popen.stdout)
        if not self.wait(lambda: "recorder ready" in self.state, stop, "the recorder node"):
            return False
        self.started = time.monotonic()
        return True

    def _thread(self, target: Callable[[IO[bytes]], None], stream: IO[bytes]) -> None:
        thread = threading.Thread(target=target, args=(stream,), daemon=True)
        thread.start()
        self.threads.append(thread)

    def _choose(self, arch: str) -> None:
        """Tell the tap the scope's topics in the graph ``arch`` (again when they change)."""
        topics = tuple(sorted(self.choose(arch)))
        if topics == self.topics:
            return
        if self.topics is not None and set(topics) - set(self.topics):
            self.say(f"the graph names more of the scope: recording {', '.join(topics)}")
        self.topics = topics
        assert self.tap is not None and self.tap.popen.stdin is not None
        answer = {"topics": list(topics), "all": self.settings.all_topics}
        with contextlib.suppress(OSError, ValueError):  # a tap that died is found elsewhere
            self.tap.popen.stdin.write(json.dumps(answer).encode() + b"\n")
            self.tap.popen.stdin.flush()

    # -- the children's output --------------------------------------------------------------

    def _read_frames(self, stream: IO[bytes]) -> None:
        """The tap's frames: topics are added and messages written here, events queued."""
        with stream:
            for kind, body in wire.read_frames(stream):
                if kind == wire.MESSAGE:
                    self._write(*wire.parse_message(body))
                    continue
                try:
                    event = json.loads(body)
                except ValueError:
                    continue
                if not isinstance(event, dict):
                    continue
                if event.get("event") == "topic":
                    self._add_topic(event)
                else:
                    event["from"] = "tap"
                    self.events.put(event)

    def _add_topic(self, event: Mapping[str, Any]) -> None:
        assert self.sink is not None
        try:
            self.sink.add_topic(event)
        except SinkError as error:
            self.events.put({"event": "warning", "message": f"{event.get('topic')}: {error}"})
        except Exception as error:  # the bag cannot be written: stop recording
            self.events.put({"event": "error", "message": f"{self.settings.bag}: {error}"})

    def _write(self, ident: int, stamp: int, data: bytes) -> None:
        assert self.sink is not None
        if "write failed" in self.state:
            return
        try:
            self.sink.write(ident, stamp, data)
        except Exception as error:  # a full disk: keep what is written, stop recording
            self.state["write failed"] = True
            self.events.put({"event": "error", "message": f"{self.settings.bag}: {error}"})

    def _read_lines(self, stream: IO[bytes]) -> None:
        """The recorder's standard output: its events, one JSON object a line."""
        with stream:
            log = self.settings.logs / "recorder.events"
            read_events(stream, log, self.events.put, "recorder")

    def handle(self, event: dict[str, Any]) -> None:
        """Handle one event the tap or the recorder said (``from`` names which)."""
        kind = str(event.get("event"))
        source = str(event.get("from", ""))
        if kind == "graph":
            self.state["graph"] = str(event.get("arch", ""))
            if self.topics is not None:
                self._choose(self.state["graph"])
        elif kind == "ready":
            self.state[f"{source} ready"] = True
        elif kind == "warning":
            self.warn(str(event.get("message", "")))
        elif kind == "error":
            self.failure = self.failure or str(event.get("message", ""))
        elif kind == "stats" and source == "recorder":
            self.outcome.published = dict(event.get("published") or {})
            self.outcome.calls = dict(event.get("calls") or {})
        elif kind == "stats" and source == "tap":
            self.received = {str(k): int(v) for k, v in dict(event["received"]).items()}

    def check_children(self) -> None:
        if self.failure:
            raise RecordError(self.failure)
        for child in (self.tap, self.node):
            if child is not None and not child.alive:
                raise RecordError(child.died())

    # -- stop -----------------------------------------------------------------------------

    def finish(self) -> Outcome:
        """Stop the recorder, then the tap; write what is left and close the bag."""
        ended = time.monotonic()
        if self.node is not None:
            if not self.node.interrupt(15.0):
                self.warn("the recorder node did not stop in time and was killed")
            time.sleep(STOP_GRACE)
        if self.tap is not None:
            if self.tap.popen.stdin is not None:
                with contextlib.suppress(OSError):
                    self.tap.popen.stdin.close()  # it may still wait for the scope
            if not self.tap.interrupt(30.0):
                self.warn("the bag tap did not stop in time and was killed")
        for thread in self.threads:
            thread.join(30.0)
        self.pump()
        self.outcome.seconds = max(0.0, ended - self.started) if self.started else 0.0
        if self.sink is None:
            raise RecordError("no bag was written")
        try:
            self.outcome.messages = self.sink.close()
        except Exception as error:
            raise RecordError(f"{self.settings.bag}: cannot close the bag: {error}") from None
        for topic, received in sorted(self.received.items()):
            stored = self.outcome.messages.get(topic, 0)
            if stored < received:
                self.warn(
                    f"{received - stored} of {received} messages on {topic} are not in the bag"
                )
        return self.outcome
