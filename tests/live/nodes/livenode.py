"""What the rospy nodes of the live test system share.

These nodes run under Debian's ``/usr/bin/python3`` (where rospy lives), never under the
interpreter that runs pytest; mypy sees rospy as missing, hence the ``type: ignore``s.

Faults are injected two ways:

* on the command line, for recordings: ``--fault KIND --fault-at SECONDS [--fault-count N]``
  (seconds after the node's first message);
* on demand, through the node's private parameter ``~fault`` (e.g. ``/a/car/fault``), polled
  every cycle: ``out_of_range:N`` makes the next N messages bad, then the node deletes the
  parameter (a test sees it consumed); ``silent`` stops publishing while the parameter holds
  it; deleting it (or ``""``) restores the nominal behaviour.
"""

from __future__ import annotations

import argparse
import json
import os
import signal
import socket
import threading
import time
from collections.abc import Sequence
from typing import IO, Any

import rospy  # type: ignore[import-not-found]

FAULT_KINDS = ("none", "out_of_range", "silent")


def init_node(name: str, **options: Any) -> None:
    """``rospy.init_node`` with a shutdown that cannot deadlock on a signal.

    rospy's own handler shuts the node down inside the signal handler, on the main thread: a
    signal that lands while that thread publishes (holding the publisher's lock) waits on that
    lock forever, and SIGTERM then finds a shutdown "in progress". Here the handler only starts
    the shutdown on a thread of its own (not a daemon: the interpreter waits for it, so the node
    unregisters from the master before it exits); the main loop sees ``rospy.is_shutdown()``.
    """
    rospy.init_node(name, disable_signals=True, **options)

    def shut_down(signum: int, _frame: Any) -> None:
        threading.Thread(target=rospy.signal_shutdown, args=(f"signal-{signum}",)).start()

    for signum in (signal.SIGINT, signal.SIGTERM):
        signal.signal(signum, shut_down)


def parse(description: str, add: Any = None, argv: Sequence[str] | None = None) -> Any:
    """The node's options (ROS remappings such as ``__name:=`` are left to rospy)."""
    parser = argparse.ArgumentParser(description=description)
    parser.add_argument("--fault", choices=FAULT_KINDS, default="none")
    parser.add_argument("--fault-at", type=float, default=1.0, help="seconds after start")
    parser.add_argument("--fault-count", type=int, default=1, help="bad messages (out_of_range)")
    if add is not None:
        add(parser)
    args = rospy.myargv(argv=argv)[1:] if argv is None else list(argv)
    return parser.parse_args(args)


class Faults:
    """Decides, once per message, whether this message is nominal, bad or not sent."""

    def __init__(self, options: Any) -> None:
        self.kind: str = options.fault
        self.at: float = options.fault_at
        self.left: int = options.fault_count if options.fault == "out_of_range" else 0
        self.started: float | None = None
        self.pending_bad = 0

    def next(self) -> str:
        """``nominal``, ``bad`` or ``silent`` for the message about to be sent."""
        now = time.monotonic()
        if self.started is None:
            self.started = now
        state = self._param()
        if state == "silent":
            return "silent"
        if self.pending_bad > 0:
            self.pending_bad -= 1
            return "bad"
        if self.kind != "none" and now - self.started >= self.at:
            if self.kind == "silent":
                return "silent"
            if self.left > 0:
                self.left -= 1
                return "bad"
        return "nominal"

    def _param(self) -> str:
        value = str(rospy.get_param("~fault", "") or "")
        if value.startswith("out_of_range"):
            _, _, count = value.partition(":")
            self.pending_bad += int(count or 1)
            rospy.delete_param("~fault")
            return "nominal"
        return value


def to_plain(value: Any) -> Any:
    """A rospy message as JSON-ready data (times as float seconds, bytes as integers)."""
    if hasattr(value, "to_sec"):
        return value.to_sec()
    if hasattr(value, "_slot_types"):
        return {name: to_plain(getattr(value, name)) for name in value.__slots__}
    if isinstance(value, (bytes, bytearray)):
        return list(value)
    if isinstance(value, (list, tuple)):
        return [to_plain(item) for item in value]
    return value


def open_log(path: str) -> IO[str]:
    """A JSON-lines file, line-buffered so a test reads every line as it is written."""
    return open(path, "a", buffering=1, encoding="utf-8")


def write_line(log: IO[str], record: dict[str, Any]) -> None:
    """One JSON line."""
    log.write(json.dumps(record, allow_nan=False, default=str) + "\n")


class Connections(rospy.SubscribeListener):  # type: ignore[misc]
    """Notes each subscriber connected to the node's publishers in
    ``$IMROSC_LIVE_CONNECTIONS/<node>.txt`` (the harness's folder; nothing without it), a line
    ``"<topic> <subscriber> <0|1>"`` each, 1 when the connection has TCP_NODELAY (which the
    subscriber asks for in its connection header)."""

    def __init__(self) -> None:
        self.found: set[str] = set()
        self.lock = threading.Lock()

    def peer_subscribe(self, topic_name: str, topic_publish: Any, peer_publish: Any) -> None:
        del topic_publish, peer_publish
        publisher = rospy.topics.get_topic_manager().get_publisher_impl(topic_name)
        with self.lock:
            for connection in publisher.connections if publisher is not None else ():
                flag = connection.socket.getsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY)
                self.found.add(f"{topic_name} {connection.endpoint_id} {int(bool(flag))}")
            folder = os.environ.get("IMROSC_LIVE_CONNECTIONS")
            if folder:
                name = rospy.get_name().strip("/").replace("/", "-")
                path = os.path.join(folder, name + ".txt")
                with open(path + ".new", "w", encoding="utf-8") as out:
                    out.write("".join(line + "\n" for line in sorted(self.found)))
                os.replace(path + ".new", path)
