"""The bag tap: an rclpy node that hands every message of the recording to imrosc.

``python -m imrosc.onboard.record_ros2.tap SPEC`` (``SPEC``: JSON with ``node``, the tap's hidden
node name; ``fd``, the pipe to write frames to; ``period``; ``settle``, seconds to wait at
most for discovery before describing the graph; ``expect``, the topics the scope names).
Under the ROS 2 Python, started by ``imrosc record``.

1. It subscribes at once to the three record topics (``std_msgs/msg/String``, reliable and
   transient local, as the recorder offers them), so that it hears the recorder's first
   snapshots.
2. Once discovery settled (the scope's named topics have publishers and the graph is
   complete and steady; at most ``settle`` seconds) it sends the graph it sees (``graph``:
   an architecture record, for the scope's relative inputs) and waits for a line on standard
   input: ``{"topics": [...], "all": false}``, the topics to record. It sends the graph again
   whenever it changes, and imrosc sends another line when that changes the topics (a
   relative point's inputs known late).
3. Every ``period`` seconds it reads the graph and subscribes to each of those topics that
   has appeared, with a serialized (``raw``) subscription of the type the graph gives and a
   QoS that hears every publisher (best effort when one publisher is, transient local when
   all are; changed when the publishers change). Each new subscription is announced
   (``topic``: id, name, type, the ``.msg`` definitions of the type and of every type it
   uses, the publishers' QoS) before its first message.
4. Every message is sent as it arrives: CDR bytes and receive time.

SIGINT or SIGTERM ends it: it sends its counts (``stats``) and closes the pipe; imrosc then
closes the bag. Python 3.8 syntax.
"""

from __future__ import annotations

import contextlib
import json
import os
import sys
import threading
import time
from typing import IO, Any, Dict, List, Optional, Set

from .. import records
from ..monitor_ros2 import logic as graph
from ..monitor_ros2 import plumbing
from . import logic as recorder_logic
from . import node as recorder
from . import wire

try:  # only a ROS 2 system has these
    import rclpy  # type: ignore[import-not-found, unused-ignore]
    from rclpy.executors import (  # type: ignore[import-not-found, unused-ignore]
        SingleThreadedExecutor,
    )
    from rclpy.node import Node  # type: ignore[import-not-found, unused-ignore]
    from std_msgs.msg import String  # type: ignore[import-not-found, unused-ignore]
except ImportError:  # pragma: no cover - exercised on ROS 2 systems only
    rclpy = None

LEAST, STEADY = 1.5, 1.0
"""Discovery: seconds before the graph is described at the soonest, and without change."""
DRAIN = 0.3
"""Seconds the tap goes on taking what DDS has received after SIGINT or SIGTERM."""
RECORD_DEPTH = 100
DATA_DEPTH = 1000
"""Depth of the data subscriptions: the tap only copies bytes, it rarely falls behind."""


def share_folders() -> List[str]:
    """Where the ``.msg`` files are: ``share`` of every ament prefix and of this Python."""
    prefixes = [p for p in os.environ.get("AMENT_PREFIX_PATH", "").split(os.pathsep) if p]
    prefixes.append(sys.prefix)
    folders: List[str] = []
    for prefix in prefixes:
        folder = os.path.join(prefix, "share")
        if folder not in folders and os.path.isdir(folder):
            folders.append(folder)
    return folders


def find_definition(type_name: str, folders: List[str]) -> Optional[str]:
    """The text of ``<share>/<pkg>/msg/<Name>.msg`` for ``pkg/msg/Name``, or ``None``."""
    package, _, name = type_name.partition("/msg/")
    if not package or not name:
        return None
    for folder in folders:
        path = os.path.join(folder, package, "msg", name + ".msg")
        try:
            with open(path, encoding="utf-8") as stream:
                return stream.read()
        except OSError:
            continue
    return None


class Tap:
    """The node's state: the subscriptions, the pipe, the counts."""

    def __init__(self, node: Any, spec: Dict[str, Any], out: IO[bytes]) -> None:
        self.node = node
        self.log = node.get_logger()
        self.out = out
        self.lock = threading.Lock()
        self.period = float(spec.get("period", 0.5))
        self.folders = share_folders()
        self.wanted: Optional[Set[str]] = None
        """The topics to record, once imrosc said (``None`` before)."""
        self.everything = False
        self.connections: Dict[str, int] = {}
        self.subscriptions: Dict[str, Any] = {}
        self.qos: Dict[str, graph.Qos] = {}
        self.types: Dict[str, str] = {}
        self.counts: Dict[str, int] = {}
        self.told: Set[str] = set()
        self.closed = False
        self.described = ""
        """The last graph sent."""
        for topic in records.RECORD_TOPICS:
            qos = graph.Qos(graph.RELIABLE, graph.TRANSIENT_LOCAL)
            self.subscribe(topic, records.RECORD_TYPE, String, qos, [qos])

    # -- the pipe ------------------------------------------------------------------------------

    def send(self, data: bytes) -> None:
        with self.lock:
            if self.closed:
                return
            try:
                self.out.write(data)
                self.out.flush()
            except (OSError, ValueError):  # imrosc is gone: nothing more can be kept
                self.closed = True

    def tell(self, kind: str, **fields: Any) -> None:
        self.send(wire.event(dict(fields, event=kind)))

    def warn_once(self, key: str, text: str) -> None:
        if key not in self.told:
            self.told.add(key)
            self.tell("warning", message=text)

    # -- subscriptions -------------------------------------------------------------------------

    def subscribe(
        self,
        topic: str,
        type_name: str,
        message_class: Any,
        qos: graph.Qos,
        offered: List[Optional[graph.Qos]],
    ) -> None:
        """Subscribe to ``topic`` (announcing it first if it is new)."""
        if topic not in self.connections:
            defs, missing = wire.definitions(
                type_name, lambda name: find_definition(name, self.folders)
            )
            ident = len(self.connections) + 1
            self.connections[topic] = ident
            self.types[topic] = type_name
            self.counts[topic] = 0
            self.tell(
                "topic",
                id=ident,
                topic=topic,
                type=type_name,
                definitions=defs,
                missing=missing,
                qos=[list(q) for q in offered if q is not None],
                hashes=self.type_hashes(topic),
            )
        else:
            self.node.destroy_subscription(self.subscriptions.pop(topic))
        ident = self.connections[topic]

        def on_message(data: bytes) -> None:
            self.counts[topic] += 1
            self.send(wire.message(ident, time.time_ns(), data))

        self.subscriptions[topic] = self.node.create_subscription(
            message_class, topic, on_message, plumbing.profile(qos, DATA_DEPTH), raw=True
        )
        self.qos[topic] = qos

    def type_hashes(self, topic: str) -> List[str]:
        """The type hashes (``RIHS01_...``) the publishers of ``topic`` announce (Iron and
        later)."""
        try:
            infos = self.node.get_publishers_info_by_topic(topic)
        except Exception:
            return []
        found = {str(getattr(info, "topic_type_hash", "")) for info in infos}
        return sorted(h for h in found if h.startswith("RIHS01_"))

    def wants(self, topic: str) -> bool:
        if topic in records.RECORD_TOPICS:
            return False
        if self.everything:
            return not recorder_logic.is_hidden(topic) and records.is_global_name(topic)
        return self.wanted is not None and topic in self.wanted

    def poll(self) -> None:
        """Describe the graph when it changed; subscribe to the wanted topics that have
        appeared; follow their publishers' QoS."""
        view = plumbing.read_graph(self.node)
        if view.complete:
            self.describe(view)
        if self.wanted is None and not self.everything:
            return
        mine = [graph.node_name(self.node.get_namespace(), self.node.get_name())]
        for topic, kinds in sorted(view.types.items()):
            if not self.wants(topic) or not kinds:
                continue
            type_name = self.types.get(topic, kinds[0])
            if len(kinds) > 1:
                self.warn_once(
                    "types " + topic,
                    f"{topic} has several types ({', '.join(kinds)}): recording {type_name}",
                )
            offered = graph.publisher_qos(view, topic, mine)
            wanted = graph.qos_update(self.qos.get(topic), offered, type_name)
            if wanted is None:
                continue
            message_class = plumbing.message_class(type_name)
            if message_class is None:
                self.warn_once(
                    "class " + topic,
                    f"{topic}: its type {type_name} cannot be imported here; not recorded",
                )
                continue
            self.subscribe(topic, type_name, message_class, wanted, offered)

    def describe(self, view: graph.GraphView) -> None:
        """Send the graph (an architecture record, the tap left out) if it changed."""
        topics, services = recorder_logic.arch_of(view)
        text = records.arch_text(topics, services)
        if text != self.described:
            self.described = text
            self.tell("graph", arch=text)

    def choose(self, answer: Dict[str, Any]) -> None:
        """Take imrosc's choice of topics (``topics``, ``all``)."""
        self.everything = bool(answer.get("all"))
        self.wanted = set(answer.get("topics") or [])

    def close(self) -> None:
        self.tell("stats", received=dict(self.counts))
        with self.lock:
            self.closed = True
            with contextlib.suppress(OSError):
                self.out.close()


def settle(node: Any, executor: Any, seconds: float, expected: List[str]) -> None:
    """Spin while discovery goes on: at least :data:`LEAST` seconds, then until every
    ``expected`` topic has a publisher and the graph is complete and unchanged for
    :data:`STEADY` seconds; at most ``seconds``."""
    start = time.monotonic()
    last = None
    since = start
    while True:
        executor.spin_once(timeout_sec=0.1)
        now = time.monotonic()
        view = plumbing.read_graph(node)
        seen = (sorted(view.topics.items()), sorted(view.services.items()))
        published = all(view.topics.get(t, ((), ()))[0] for t in expected)
        if seen != last or not view.complete or not published:
            last, since = seen, now
        if now - start >= seconds or (now - start >= LEAST and now - since >= STEADY):
            return


def listen(tap: Tap, stream: IO[str], first: threading.Event) -> None:
    """imrosc's choices, one JSON line each (the first before recording starts, then one
    whenever the graph changes what the scope names); ``first`` is set after the first
    (or when imrosc closed the stream)."""
    for line in stream:
        try:
            answer = json.loads(line)
        except ValueError:
            continue
        if isinstance(answer, dict):
            tap.choose(answer)
            first.set()
    first.set()


def main(argv: Optional[List[str]] = None) -> None:
    """Run the tap until SIGINT or SIGTERM."""
    args = sys.argv[1:] if argv is None else argv
    spec = json.loads(args[0])
    if rclpy is None:
        sys.exit("imrosc bag tap: rclpy is not importable; run it under the ROS 2 Python")
    out = os.fdopen(int(spec["fd"]), "wb")
    recorder.init(["--ros-args", "--disable-rosout-logs"])
    node = Node(spec["node"], start_parameter_services=False)
    tap = Tap(node, spec, out)
    executor = SingleThreadedExecutor()
    executor.add_node(node)
    try:
        settle(node, executor, float(spec.get("settle", 5.0)), list(spec.get("expect", [])))
        tap.describe(plumbing.read_graph(node))
        chosen = threading.Event()
        threading.Thread(target=listen, args=(tap, sys.stdin, chosen), daemon=True).start()
        while not chosen.wait(0.1):
            executor.spin_once(timeout_sec=0.0)
        tap.poll()
        tap.tell("ready")
        node.create_timer(tap.period, plumbing.guarded(tap.log, "poll", tap.poll))
        recorder.spin(executor)
        end = time.monotonic() + DRAIN
        while time.monotonic() < end and rclpy.ok():
            executor.spin_once(timeout_sec=0.05)
    except plumbing.SPIN_ENDED:
        pass
    finally:
        tap.close()
        executor.shutdown()
        node.destroy_node()
        if rclpy.ok():
            rclpy.shutdown()


if __name__ == "__main__":
    main()
