"""Lockstep for a rospy graph on simulated time: the simulator advances ``/clock`` only when
every node has reacted to the last step, so a run's outcome does not depend on how loaded
the machine is.

ROS 1 has no lockstep of its own (Gazebo's covers the systems inside its process, not the
nodes around it). This module gives every rospy process the node-side half, by patching
rospy when it is imported (``sitecustomize.py``), with no change to the nodes' code:

* **Counting** (distributed termination detection): each process counts the messages it
  wrote to each subscriber (``topic>subscriber``), those it received per publisher
  (``topic<publisher``), the service calls it made that were answered and those its
  handlers answered (summed over the services: a relay outside the lockstep serves one
  name and calls another; a call refused or failed is counted by neither side). When it is idle it
  publishes its counts and its time on ``/lockstep/report``. The simulator
  (:class:`Coordinator`) advances only when every process reports idle (at the current
  time, if it does not read the board) and every channel between them balances
  (sent = received): then no message is in flight and no callback runs anywhere (a
  process whose report is stale has received something after it, which its sender
  counted: the counts cannot balance). The release of a step
  (below) is not counted: the simulator waits for a report after it from each process
  whose timers it wakes (its last report said one was due).
* **Fewer reports**: a report is left out when a later one must reach the simulator before
  it can settle anyway: after a message of a batch rospy read at once but the last, while
  more data waits on a counted connection (its callback reports), and after a sensor
  message of the simulator stamped ahead of the process's clock (a step where the
  simulator does not wait: the next due step makes the process report). A report is
  written straight to the simulator's connection (a ``std_msgs/String`` is its length and
  its bytes), and the simulator's thread is woken by a report only when its wait may be
  over.
* **Idle**: no callback or service handler runs, and every thread that sleeps on ROS time
  (``rospy.sleep``, ``Rate``, ``Timer``) is back asleep with a deadline after the current
  time. Threads that wait on the wall clock (a heartbeat) are not tracked: what they
  publish is counted, which holds the step until their subscribers have it.
* **The release**: the simulator publishes its sensors' messages, then releases the
  step's timers (``/lockstep/go``, to the processes that reported a timer due: the others
  have nothing to release). A release gives how many messages the simulator sent that
  process so far per topic, and takes effect once the process took them in: a timer at t
  sees the simulator's messages of t. A thread sleeping on ROS time wakes once both the
  clock and the release passed its deadline (a new clock wakes it only then). While a
  process still takes its time from ``/clock`` (below), the simulator waits until every
  process has the step's ``/clock`` and messages before it releases (two phases).
* **The clock on a board**: the simulator writes the time of each step where it waits (a
  due step) to a file in shared memory (:class:`Board`) before it publishes anything then;
  a process sets its clock from it before it takes in any message (or service call), and
  from the release, which carries the step's time. So ``/clock`` need not go to every
  process at every due step (each would take it in and report): it goes only to the
  processes that do not read the board (outside the lockstep, or not yet: a process
  opens it at its first ``/clock``), and to one the simulator sent messages since its last
  due step but none at this one (nothing else would make it report them). No message a
  timer sends at time t reaches a process that lives at the time before: the board holds
  t while it is in flight.
* **Synchronous ticks**: a message (but the simulator's) that arrives while a timer of its
  subscriber is pending at the current time is handed to its callback only once that timer
  ran, so every timer at time t sees what was published before t and the simulator's
  messages of t, never what another node's timer published at t (which would depend on
  which process the scheduler ran first).
* Publishers write synchronously (no queue, nothing dropped), subscribers queue without
  bound and ask for ``TCP_NODELAY`` (Nagle's delayed small writes would stall every step).
* A subscriber connects to every publisher the master named to it, whatever order the
  master's reply and its updates arrive in (:func:`patch_publisher_updates`): rospy alone may
  never connect to one, and time would start without it.

A subscriber that closes its connection to a publisher (the monitor drops an unknown
publisher, a node leaves) reports the channel closed, and the simulator stops balancing it:
a message its publisher counted as sent may have been lost with the connection, and a closed
channel carries nothing more (a connection opened again later on the same channel is not
balanced either).

Messages of ``/rosout`` and the reports themselves are not counted; nor are channels to or
from processes without this module (``rosbag record``): they do not hold the clock. Two
things stay outside the lockstep: the order in which one subscriber gets messages that two
publishers sent in the same step (the stealing scenario's two sources of ``/a/car_pose``),
and what a thread that waits on something else than ROS time publishes (the monitor's
actions, taken by a worker thread after an alarm): the step that carries it may vary.
"""

from __future__ import annotations

import contextlib
import importlib.abc
import importlib.util
import json
import mmap
import os
import re
import select
import struct
import sys
import threading
import time
from collections.abc import Iterable
from typing import Any

REPORT_TOPIC = "/lockstep/report"
GO_TOPIC = "/lockstep/go"
UNLINKED = frozenset({REPORT_TOPIC, "/rosout", "/rosout_agg"})
"""Topics whose connections time need not wait for (the reports are latched)."""
UNCOUNTED = UNLINKED | {GO_TOPIC}
"""Not counted: the release is awaited through the reports of the processes it wakes."""
CLOCK = "/clock"


class Board:
    """The time of the simulator's last due step (ns), in a file in shared memory that the
    simulator writes (``create``) and its processes read: a process that takes in a message
    sets its clock from it, so ``/clock`` need not go to every process at every due step.

    The simulator writes it before it publishes anything at that step, and moves on only once
    every message sent meanwhile was taken in: a message from another process is read while
    the board holds the step it was sent at. A sequence number around the value (odd while it
    is written) keeps a reader from a half-written one (a sensor message of a step where the
    simulator does not wait is read while the simulator may be writing the next)."""

    SIZE = 16

    def __init__(self, path: str, create: bool = False) -> None:
        self.path = path
        flags = os.O_RDWR | (os.O_CREAT | os.O_TRUNC if create else 0)
        fd = os.open(path, flags, 0o600)
        try:
            if create:
                os.ftruncate(fd, self.SIZE)
            self.map = mmap.mmap(fd, self.SIZE)
        finally:
            os.close(fd)
        self.sequence = 0

    def write(self, value: int) -> None:
        """(The simulator) the time of the due step it begins (ns)."""
        self.sequence += 1
        struct.pack_into("<q", self.map, 0, self.sequence)
        struct.pack_into("<q", self.map, 8, value)
        self.sequence += 1
        struct.pack_into("<q", self.map, 0, self.sequence)

    def read(self) -> int:
        while True:
            before = struct.unpack_from("<q", self.map, 0)[0]
            value: int = struct.unpack_from("<q", self.map, 8)[0]
            if before % 2 == 0 and struct.unpack_from("<q", self.map, 0)[0] == before:
                return value

    def close(self, unlink: bool = False) -> None:
        with contextlib.suppress(Exception):
            self.map.close()
        if unlink:
            with contextlib.suppress(OSError):
                os.unlink(self.path)


def master_uri() -> str:
    import rosgraph  # type: ignore[import-not-found]

    return str(rosgraph.get_master_uri())


def board_path(master_uri: str) -> str:
    """The board of the simulator started beside this process (the same parent, the same
    master)."""
    folder = "/dev/shm" if os.access("/dev/shm", os.W_OK) else "/tmp"
    return os.path.join(
        folder, f"rospy_lockstep_{re.sub(r'[^0-9A-Za-z]+', '_', master_uri)}_{os.getppid()}"
    )


def _publish_each(publisher: Any, message_to: Any) -> None:
    """Publish on each of ``publisher``'s connections what ``message_to(subscriber name)``
    gives (``None``: nothing to that subscriber)."""
    impl = publisher.impl
    for connection in list(impl.connections):
        message = message_to(connection.endpoint_id)
        if message is None:
            continue
        impl.acquire()
        try:
            impl.publish(message, connection_override=connection)
        finally:
            impl.release()


class Process:
    """This process's half of the lockstep: its counts, its activity, its reports."""

    def __init__(self, rospy: Any) -> None:
        self.rospy = rospy
        self.cond = threading.Condition()
        self.sent: dict[str, int] = {}
        self.received: dict[str, int] = {}
        self.calls: dict[str, int] = {}
        self.served: dict[str, int] = {}
        self.closed: set[str] = set()
        """``topic<publisher`` of the connections this process's subscribers closed."""
        self.busy = 0
        """Callbacks and service handlers running."""
        self.simulator = ""
        """The node that publishes ``/clock``."""
        self.holding = 0
        """Callbacks waiting for this process's pending timers (``begin``)."""
        self.sleepers: dict[int, int | None] = {}
        """Threads asleep on ROS time and their deadline (ns; None: until time starts)."""
        self.awake: set[int] = set()
        """Threads that slept on ROS time and are out of that sleep now."""
        self.released = 0
        """The time (ns) up to which timers may run (``/lockstep/go``)."""
        self.pending: tuple[int, dict[str, int]] | None = None
        """A release that waits for the simulator's messages sent before it: its time and,
        per ``topic<simulator``, how many (:meth:`release`)."""
        self.done: dict[str, int] = {}
        """Per ``topic<publisher``, the messages whose callback ended."""
        self.ready = False
        """The node's set-up is done (it spins, or a thread sleeps on ROS time)."""
        self.publisher: Any = None
        self.sequence = 0
        self.version = 0
        """Bumped on every change of the counts or the activity."""
        self.links_version = 0
        """Bumped when a publisher of this process gains a connection."""
        self.last: Any = None
        self.last_links = -1
        self.report_lock = threading.Lock()
        self.string: Any = None
        self.sockets: set[Any] = set()
        """The sockets of the connections that brought this process counted messages."""
        self.listeners: list[Any] = []
        """Called (no arguments) on every change: the coordinator in the simulator."""
        self.board: Board | None = None
        """The simulator's :class:`Board`, once this process had a ``/clock`` from it."""
        self.set_time: Any = None
        """rospy's ``_set_rostime`` as patched (:func:`install`)."""

    def now(self) -> int:
        return int(self.rospy.rostime.get_rostime().to_nsec())

    def advance(self, ns: int) -> None:
        """Set this process's clock to ``ns`` unless it is there or later already."""
        rostime = self.rospy.rostime
        current = rostime._rostime_current
        if current is None or current.to_nsec() < ns:
            self.set_time(rostime.Time(ns // 1_000_000_000, ns % 1_000_000_000))

    def catch_up(self) -> None:
        """Before a message of the graph is taken in: this process's clock at the
        simulator's last due step (the board), which it may not have had (``/clock`` goes
        only where it is needed)."""
        if self.board is not None:
            self.advance(self.board.read())

    def clocked(self) -> None:
        """A ``/clock`` came: read the board from now on (the simulator created it before)."""
        if self.board is None:
            with contextlib.suppress(OSError, ValueError):
                self.board = Board(board_path(master_uri()))

    # ----- activity (called with self.cond held)
    def timers_pending(self, until: int, now: int | None = None) -> bool:
        """A thread sleeping on ROS time is due at or before ``until`` (ns), or awake
        (``now``: the current time, when known)."""
        if self.awake:  # but threads that ended meanwhile
            self.awake &= {t.ident for t in threading.enumerate()}
            if self.awake:
                return True
        started = (self.now() if now is None else now) > 0
        for deadline in self.sleepers.values():
            if (deadline is None and started) or (deadline is not None and deadline <= until):
                return True
        return False

    def idle(self, now: int) -> bool:
        """No callback runs, no timer released to run, and no held message about to be
        handed over (one held for a timer still waiting for its release) at ``now`` (ns)."""
        if self.busy or self.timers_pending(min(now, self.released), now):
            return False
        return self.holding == 0 or self.timers_pending(now, now)

    def changed(self) -> None:
        self.version += 1
        self.cond.notify_all()
        for listener in self.listeners:
            listener()

    # ----- hooks
    def begin(self, hold: bool, counts: dict[str, int] | None = None, key: str = "") -> None:
        """A callback starts, its message counted as received at once; with ``hold``, it
        waits until no timer of this process is pending at the current time."""
        with self.cond:
            if counts is not None:
                counts[key] = counts.get(key, 0) + 1
            held = hold and self.timers_pending(self.now())
            if held:
                self.holding += 1
                self.changed()
            else:
                self.busy += 1
        if not held:
            return
        self.report()  # idle while the timer waits for its release: the clock may settle
        with self.cond:
            while self.timers_pending(self.now()) and not self.rospy.is_shutdown():
                self.cond.wait(0.2)
            self.holding -= 1
            self.busy += 1

    def end(
        self,
        counts: dict[str, int] | None = None,
        key: str = "",
        ahead: int | None = None,
        quiet: bool = False,
        done: str | None = None,
    ) -> None:
        """A callback ended (``done``: of a message on ``topic<publisher``, which a release
        may wait for). Its report is left out when a later one is sure to
        come before the simulator can settle: a message from the simulator stamped ``ahead``
        (ns) of this process's time (a sensor message of a step where the simulator does not
        wait: the next due step makes this process report), more data waiting on a counted
        connection (the callback that takes it in reports), or ``quiet``: the next message
        of the same read follows."""
        waiting = False
        with self.cond:
            self.busy -= 1
            if counts is not None:
                counts[key] = counts.get(key, 0) + 1
            if done is not None:
                self.done[done] = self.done.get(done, 0) + 1
                waiting = self.pending is not None
            self.changed()
            silent = quiet or (ahead is not None and ahead > self.now())
        if waiting:
            cond = self.rospy.rostime.get_rostime_cond()
            with cond, self.cond:
                if self.take_release():
                    cond.notify_all()
        if not silent and not self.more_coming():
            self.report()

    def more_coming(self) -> bool:
        """Data waits to be read on a connection of this process's counted subscribers."""
        sockets = [s for s in list(self.sockets) if s.fileno() >= 0]
        if not sockets:
            return False
        try:
            ready, _, _ = select.select(sockets, [], [], 0)
        except (OSError, ValueError):
            return False
        return bool(ready)

    def count(self, counts: dict[str, int], keys: Iterable[str]) -> None:
        with self.cond:
            for key in keys:
                counts[key] = counts.get(key, 0) + 1
            self.changed()
        self.report()

    def enter_sleep(self, deadline: int | None) -> None:
        ident = threading.get_ident()
        with self.cond:
            self.awake.discard(ident)
            self.sleepers[ident] = deadline
            self.ready = True
            self.changed()
        self.report()

    def leave_sleep(self) -> None:
        ident = threading.get_ident()
        with self.cond:
            self.sleepers.pop(ident, None)
            self.awake.add(ident)

    def spinning(self) -> None:
        with self.cond:
            self.ready = True
            self.changed()
        self.report()

    # ----- reports
    def links(self) -> list[str]:
        """``topic>subscriber`` of every connection of this process's publishers."""
        manager = self.rospy.impl.registration.get_topic_manager()
        found = []
        for topic, impl in list(getattr(manager, "pubs", {}).items()):
            if topic not in UNLINKED:
                found.extend(f"{topic}>{c.endpoint_id}" for c in list(impl.connections))
        return sorted(found)

    def report(self, bye: bool = False) -> None:
        """Publish this process's state if it is idle (or leaving) and changed since the
        last report (its publishers' connections only when they changed)."""
        if self.publisher is None:
            return
        with self.report_lock:
            with self.cond:
                now = self.now()
                if not bye and not self.idle(now):
                    return
                key = (now, self.ready, self.version, self.links_version, bye)
                if key == self.last:
                    return
                self.last = key
                self.sequence += 1
                state: dict[str, Any] = {
                    "node": self.rospy.get_caller_id(),
                    "seq": self.sequence,
                    "pid": os.getpid(),
                    "time": now,
                    "sim": not self.rospy.rostime.is_wallclock(),
                    "ready": self.ready,
                    "bye": bye,
                    "released": self.released,
                    "next": min((d for d in self.sleepers.values() if d is not None), default=None),
                    "waiting": any(d is None for d in self.sleepers.values()),
                    "sent": self.sent,
                    "received": self.received,
                    "calls": self.calls,
                    "served": self.served,
                    "closed": sorted(self.closed),
                    "board": self.board is not None,
                }
                if self.links_version != self.last_links:
                    self.last_links = self.links_version
                    state["links"] = self.links()
                text = json.dumps(state, separators=(",", ":"))
            self.send(text)

    def send(self, text: str) -> None:
        """Write a report to the simulator's connection(s) as ``Publisher.publish`` would,
        without its generic path (the message built, serialized through a buffer): a
        ``std_msgs/String`` is its length and its bytes, after the message's length. Kept
        as the latched message for a subscriber that connects later."""
        payload = text.encode("utf-8")
        data = struct.pack("<II", len(payload) + 4, len(payload)) + payload
        impl = self.publisher.impl
        if impl is None or impl.closed:
            return
        impl.acquire()
        try:
            impl.latch = self.string(text)
            for connection in list(impl.connections):
                try:
                    connection.write_data(data)
                except Exception:  # a connection that closed: rospy drops it too
                    with contextlib.suppress(Exception):
                        impl.remove_connection(connection)
        finally:
            impl.release()

    def wake_all(self) -> None:
        """Wake every thread that waits on ROS time or on this process's condition."""
        cond = self.rospy.rostime.get_rostime_cond()
        with cond:
            cond.notify_all()
        with self.cond:
            self.cond.notify_all()

    def release(self, message: Any) -> None:
        """``/lockstep/go``: this process's clock at its time (which a process that reads
        the board may not have had), and timers up to that time may run once this process
        took in the simulator's messages sent before it (it gives their count per topic):
        the step's sensor messages, which the simulator need not wait for before it
        releases (:meth:`Coordinator.step`)."""
        data = json.loads(message.data)
        step = int(data["t"])
        cond = self.rospy.rostime.get_rostime_cond()
        with cond:
            with self.cond:
                self.advance(step)
                self.pending = (step, data.get("expect") or {})
                self.take_release()
            cond.notify_all()  # no report of its own: a woken timer's sleep makes one

    def take_release(self) -> bool:
        """The pending release takes effect if the messages it waits for are in. Called
        with ROS time's condition and this process's held."""
        if self.pending is None:
            return False
        step, expect = self.pending
        if any(self.done.get(key, 0) < count for key, count in expect.items()):
            return False
        self.pending = None
        self.released = max(self.released, step)
        self.cond.notify_all()
        return True

    def start(self) -> None:
        """After ``init_node``: the report topic, and a last report at shutdown."""
        from std_msgs.msg import String  # type: ignore[import-not-found]

        self.rospy.Subscriber(GO_TOPIC, String, self.release)

        self.string = String
        # latched: the simulator, connecting later, still hears the last report
        self.publisher = self.rospy.Publisher(REPORT_TOPIC, String, queue_size=None, latch=True)
        self.rospy.on_shutdown(lambda: self.report(bye=True))
        # once shut down, the threads asleep on ROS time or held see it at once (they would
        # otherwise look again only after their wait's timeout: a trial's eleven processes,
        # stopped one after the other, took that long each)
        self.rospy.core.add_shutdown_hook(lambda _reason: self.wake_all())
        self.report()


def stamp_of(message: Any) -> int | None:
    """The header stamp of a message (ns), None without one."""
    stamp = getattr(getattr(message, "header", None), "stamp", None)
    return None if stamp is None else int(stamp.to_nsec())


_INSTALLED: list[Process] = []
"""This process's lockstep, once rospy was patched."""


def process() -> Process | None:
    """This process's lockstep, when rospy was patched."""
    return _INSTALLED[0] if _INSTALLED else None


def install(rospy: Any) -> Process:
    """Patch an imported rospy (once)."""
    if _INSTALLED:
        return _INSTALLED[0]
    import genpy  # type: ignore[import-not-found]
    from rospy import rostime, timer, topics  # type: ignore[import-not-found]
    from rospy.impl import simtime, tcpros_service  # type: ignore[import-not-found]

    state = Process(rospy)
    _INSTALLED.append(state)

    def sleep(duration: Any) -> None:
        if rostime.is_wallclock():
            return original_sleep(duration)
        if not isinstance(duration, genpy.Duration):
            duration = genpy.Duration.from_sec(duration)
        cond = rostime.get_rostime_cond()
        zero = genpy.Time(0)
        initial = rostime.get_rostime()
        try:
            if initial == zero:
                state.enter_sleep(None)
                with cond:
                    while rostime.get_rostime() == zero and not rospy.is_shutdown():
                        cond.wait(0.3)
                initial = rostime.get_rostime()
            deadline = initial + duration
            state.enter_sleep(deadline.to_nsec())
            with cond:  # the check under the lock: no notification lost
                while not rospy.is_shutdown() and (
                    initial <= rostime.get_rostime() < deadline
                    or (rostime.get_rostime() >= initial and state.released < deadline.to_nsec())
                ):
                    cond.wait(0.5)
        finally:
            state.leave_sleep()
        if rostime.get_rostime() < initial:
            back = (initial - rostime.get_rostime()).to_sec()
            raise rospy.exceptions.ROSTimeMovedBackwardsException(back)
        if rospy.is_shutdown():
            raise rospy.exceptions.ROSInterruptException("ROS shutdown request")
        return None

    original_sleep = timer.sleep
    timer.sleep = sleep
    rospy.sleep = sleep

    def set_rostime(t: Any) -> None:
        """rospy's ``_set_rostime`` (``/clock``), waking the threads asleep on ROS time only
        when one of them is due (or waits for time to start, or time went back): the others
        would only look at the clock and sleep again, at every step."""
        if isinstance(t, genpy.Time):
            t = rostime.Time(t.secs, t.nsecs)
        elif not isinstance(t, rostime.Time):
            raise ValueError(f"must be Time instance: {t.__class__}")
        old = rostime._rostime_current
        rostime._rostime_current = t
        ns = t.to_nsec()
        with state.cond:
            due = old is None or t < old or state.awake
            due = due or any(d is None or d <= ns for d in state.sleepers.values())
        if due:
            cond = rostime.get_rostime_cond()
            with cond:
                cond.notify_all()

    rostime._set_rostime = set_rostime
    simtime._set_rostime = set_rostime
    state.set_time = set_rostime

    original_init = rospy.init_node

    def init_node(*args: Any, **kwargs: Any) -> Any:
        result = original_init(*args, **kwargs)
        state.start()
        return result

    rospy.init_node = init_node

    original_spin = rospy.spin

    def spin() -> Any:
        state.spinning()
        return original_spin()

    rospy.spin = spin

    # publishers: synchronous, counted per subscriber
    topics._PublisherImpl.set_queue_size = lambda impl, size: None
    original_publish = topics._PublisherImpl.publish

    def publish(impl: Any, message: Any, connection_override: Any = None) -> Any:
        topic = impl.resolved_name
        if topic in UNCOUNTED or impl.closed:
            return original_publish(impl, message, connection_override)
        targets = [connection_override] if connection_override else list(impl.connections)
        if targets:
            state.count(state.sent, [f"{topic}>{c.endpoint_id}" for c in targets])
        return original_publish(impl, message, connection_override)

    topics._PublisherImpl.publish = publish
    original_add_connection = topics._PublisherImpl.add_connection

    def add_connection(impl: Any, connection: Any) -> Any:
        added = original_add_connection(impl, connection)
        with state.cond:
            state.links_version += 1
        state.report()  # a new link: the simulator's start waits for them
        return added

    topics._PublisherImpl.add_connection = add_connection

    # subscribers: unbounded queue, TCP_NODELAY, counted per publisher, held while a timer is due
    topics._SubscriberImpl.set_queue_size = lambda impl, size: setattr(impl, "queue_size", None)
    original_subscriber = topics.Subscriber.__init__

    def subscriber(self: Any, *args: Any, **kwargs: Any) -> None:
        kwargs["tcp_nodelay"] = True
        original_subscriber(self, *args, **kwargs)

    topics.Subscriber.__init__ = subscriber
    original_receive = topics._SubscriberImpl.receive_callback

    def receive_callback(impl: Any, msgs: Any, connection: Any) -> None:
        topic = impl.resolved_name
        if topic in UNCOUNTED:
            return original_receive(impl, msgs, connection)
        source = connection.callerid_pub
        clock = topic == CLOCK
        if clock:
            state.simulator = source
            state.clocked()
        key = f"{topic}<{source}"
        # the simulator's messages (the clock, the release, sensors) are the step's inputs,
        # all delivered before the release: never held
        hold = source != state.simulator
        sock = getattr(connection, "socket", None)
        if sock is not None:
            state.sockets.add(sock)
        last = len(msgs) - 1
        for k, msg in enumerate(msgs):  # one by one: each message held and counted on its own
            if not clock:
                state.catch_up()
            state.begin(hold, state.received, key)
            try:
                original_receive(impl, [msg], connection)
            finally:
                # the simulator's sensor messages are stamped with their step
                ahead = stamp_of(msg) if not hold and not clock else None
                state.end(ahead=ahead, quiet=k < last, done=key)
        return None

    topics._SubscriberImpl.receive_callback = receive_callback
    original_remove = topics._SubscriberImpl.remove_connection

    def remove_connection(impl: Any, connection: Any) -> Any:
        # a closed connection carries nothing more; what was in flight on it is lost, so
        # the channel no longer balances: report it closed (not the simulator's own)
        topic, source = impl.resolved_name, getattr(connection, "callerid_pub", None)
        if topic not in UNCOUNTED and source:
            with state.cond:
                state.closed.add(f"{topic}<{source}")
                state.changed()
        removed = original_remove(impl, connection)
        state.report()
        return removed

    topics._SubscriberImpl.remove_connection = remove_connection

    # services: calls counted per service name, made and served
    original_call = tcpros_service.ServiceProxy.call

    def call(proxy: Any, *args: Any, **kwargs: Any) -> Any:
        answer = original_call(proxy, *args, **kwargs)
        state.count(state.calls, [proxy.resolved_name])  # answered: a handler ran to its end
        return answer

    tcpros_service.ServiceProxy.call = call
    original_handle = tcpros_service.ServiceImpl._handle_request
    handled = threading.local()

    def handle_request(service: Any, transport: Any, request: Any) -> None:
        if not getattr(service, "lockstep_counted", False):
            inner = service.handler

            def counted(request: Any) -> Any:
                answer = inner(request)
                handled.ok = True
                return answer

            service.handler = counted
            service.lockstep_counted = True
        handled.ok = False
        state.catch_up()
        state.begin(False)
        try:
            original_handle(service, transport, request)
        finally:  # a call the handler refused (raised) is counted by neither side
            if handled.ok:
                state.end(state.served, service.resolved_name)
            else:
                state.end()

    tcpros_service.ServiceImpl._handle_request = handle_request
    patch_publisher_updates()
    return state


def patch_publisher_updates() -> None:
    """Keep rospy from losing a publisher a subscriber must connect to.

    rospy queues the publisher lists it hears for a topic (the master's reply to its
    ``registerSubscriber``, the master's ``publisherUpdate`` calls) and its registration
    thread connects only to the last one queued, dropping the others. The reply to a
    subscription, taken before a publisher registered, can be queued after the master's
    update that names that publisher (both race on their way in): the publisher is then never
    connected to (a subscriber of ``/a/cmd_attitude`` that never hears the UAV's commands,
    and the simulator's start waiting 60 s for that connection). Here a list queued for a
    topic also holds the publishers of the lists still queued for it: connecting to a
    publisher that has left meanwhile fails at once (connection refused). The connections to
    one publisher on one topic are made one at a time, so that two updates naming it do not
    both connect (the second, a duplicate, is reset by the publisher)."""
    from rospy.impl import registration  # type: ignore[import-not-found]

    manager = registration.RegManager

    def publisher_update(self: Any, resolved_name: str, uris: list[str]) -> None:
        with self.cond:
            queued = [u for topic, listed in self.updates if topic == resolved_name for u in listed]
            self.updates.append((resolved_name, list(dict.fromkeys([*queued, *uris]))))
            self.cond.notify_all()

    manager.publisher_update = publisher_update
    original_connect = manager._connect_topic_thread
    guard = threading.Lock()
    locks: dict[tuple[str, str], threading.Lock] = {}

    def connect_topic_thread(self: Any, topic: str, uri: str) -> None:
        with guard:
            lock = locks.setdefault((topic, uri), threading.Lock())
        with lock:
            original_connect(self, topic, uri)

    manager._connect_topic_thread = connect_topic_thread


class _Hook(importlib.abc.MetaPathFinder):
    """Patches rospy right after its import."""

    def find_spec(self, name: str, path: Any, target: Any = None) -> Any:
        if name != "rospy":
            return None
        sys.meta_path.remove(self)
        spec = importlib.util.find_spec("rospy")
        if spec is None or spec.loader is None:
            return spec
        loader = spec.loader
        execute = loader.exec_module

        def exec_module(module: Any) -> None:
            execute(module)
            install(module)

        loader.exec_module = exec_module  # type: ignore[method-assign]
        return spec


def patch_on_import() -> None:
    """Patch rospy when (if ever) this process imports it."""
    if "rospy" in sys.modules:
        install(sys.modules["rospy"])
    else:
        sys.meta_path.insert(0, _Hook())


class Coordinator:
    """The simulator's half: waits until the graph has reacted to the current step.

    Participants are the processes that report; :meth:`start` also waits for the nodes the
    same ``roslaunch`` started (its other Python children) to be ready and connected. The
    channels' balance is kept up to date report by report (a step brings a few dozen).
    """

    def __init__(self, state: Process, clock: Any = None) -> None:
        from rosgraph_msgs.msg import Clock  # type: ignore[import-not-found]
        from std_msgs.msg import String  # type: ignore[import-not-found]

        self.clock = Clock
        self.clock_publisher = clock
        """``/clock`` (:meth:`tick` publishes it where it is needed)."""
        self.board = Board(board_path(master_uri()), create=True)
        state.rospy.on_shutdown(lambda: self.board.close(unlink=True))
        self.before: dict[str, int] = {}
        """The simulator's sent counts (``topic>to``) before the current step's messages."""
        self.at_due: dict[str, int] = {}
        """... after the last due step's."""
        self.string = String
        self.go = state.rospy.Publisher(GO_TOPIC, String, queue_size=None)
        self.state = state
        self.name = state.rospy.get_caller_id()
        self.inbox: list[dict[str, Any]] = []
        self.reports: dict[str, dict[str, Any]] = {}
        """The latest report of each participant but the simulator (``links`` kept)."""
        self.sent: dict[tuple[str, str, str], int] = {}
        self.received: dict[tuple[str, str, str], int] = {}
        self.services: dict[str, dict[str, tuple[int, int]]] = {}
        """Per node, per service: (calls answered, calls served). Summed over the services:
        a relay outside the lockstep (``imrosc record``'s) serves one name and calls
        another."""
        self.unbalanced: set[tuple[str, str, str]] = set()
        self.channels: dict[tuple[str, str, str], tuple[str, str, str]] = {}
        """The channel of each key of a node's counts (``topic>to``, ``topic<from``)."""
        self.closed: set[tuple[str, str, str]] = set()
        """Channels whose subscriber closed the connection: no longer balanced."""
        self.own_version = -1
        self.awaiting: tuple[int, bool, set[str]] | None = None
        """What :meth:`settle` waits for (time, after the release, the processes released)
        while it waits."""
        self.stalls = 0
        state.simulator = self.name
        state.publisher = None  # nobody needs the simulator's own reports
        state.listeners.append(self.wake)
        state.rospy.Subscriber(REPORT_TOPIC, String, self.on_report)

    def wake(self) -> None:
        with self.state.cond:
            self.state.cond.notify_all()

    def on_report(self, message: Any) -> None:
        report = json.loads(message.data)
        if report["node"] == self.name:
            return
        with self.state.cond:
            self.inbox.append(report)
            waiting = self.awaiting
            # the simulator's thread is woken only when its wait may be over: the graph
            # settled, or (after the release) a process with a timer due to release
            if waiting is not None and (
                self.settled(waiting[0], waiting[1])
                or (waiting[1] and self.due_now(waiting[0]) - waiting[2])
            ):
                self.state.cond.notify_all()

    # ----- the balance (called with the condition held)
    def participants(self) -> set[str]:
        return {self.name, *self.reports}

    def check(self, channel: tuple[str, str, str], members: set[str]) -> None:
        if (
            channel[1] in members
            and channel[2] in members
            and channel not in self.closed
            and self.sent.get(channel, 0) != self.received.get(channel, 0)
        ):
            self.unbalanced.add(channel)
        else:
            self.unbalanced.discard(channel)

    def apply(self, node: str, report: dict[str, Any]) -> None:
        """Take a node's counts in place of its last ones."""
        touched: list[tuple[str, str, str]] = []
        self._take(node, ">", report["sent"], self.sent, touched)
        self._take(node, "<", report["received"], self.received, touched)
        for key in report.get("closed", ()):
            topic, _, source = key.rpartition("<")
            channel = (topic, source, node)
            if channel not in self.closed:
                self.closed.add(channel)
                touched.append(channel)
        calls, served = report["calls"], report["served"]
        if calls or served or node in self.services:
            self.services[node] = {
                s: (calls.get(s, 0), served.get(s, 0)) for s in {*calls, *served}
            }
        if touched:
            members = self.participants()
            for channel in touched:
                self.check(channel, members)

    def _take(
        self,
        node: str,
        way: str,
        counts: dict[str, int],
        table: dict[tuple[str, str, str], int],
        touched: list[tuple[str, str, str]],
    ) -> None:
        """Take a node's sent (``way`` ``>``, keys ``topic>to``) or received (``<``, keys
        ``topic<source``) counts into ``table``, keyed by channel (topic, source, to); the
        channels whose count changed go to ``touched``."""
        channels = self.channels
        for key, n in counts.items():
            channel = channels.get((node, way, key))
            if channel is None:
                topic, _, other = key.rpartition(way)
                channel = (topic, node, other) if way == ">" else (topic, other, node)
                channels[(node, way, key)] = channel
            if table.get(channel) != n:
                table[channel] = n
                touched.append(channel)

    def recheck(self) -> None:
        members = self.participants()
        self.unbalanced.clear()
        for channel in {*self.sent, *self.received}:
            self.check(channel, members)

    def take_reports(self) -> None:
        joined = False
        for report in self.inbox:
            name = report["node"]
            if report["bye"]:
                if self.reports.pop(name, None) is not None:
                    self.services.pop(name, None)
                    joined = True
                continue
            last = self.reports.get(name)
            if last is not None and report["seq"] <= last["seq"]:
                continue
            if "links" not in report:
                report["links"] = last["links"] if last is not None else []
            joined = joined or last is None
            self.reports[name] = report
            self.apply(name, report)
        self.inbox.clear()
        if self.state.version != self.own_version:
            self.own_version = self.state.version
            own = self.state
            self.apply(
                self.name,
                {
                    "sent": own.sent,
                    "received": own.received,
                    "calls": own.calls,
                    "served": own.served,
                    "closed": sorted(own.closed),
                },
            )
        if joined:
            self.recheck()

    def settled(self, now: int, released: bool) -> bool:
        """Whether :meth:`unsettled` would say nothing (quicker). Called with the condition
        held."""
        self.take_reports()
        if self.state.busy or self.unbalanced:
            return False
        for report in self.reports.values():
            if report["sim"] and report["time"] < now and not report.get("board"):
                return False
            if released and report["released"] < now and (report["next"] or now + 1) <= now:
                return False
        made = sum(m for per_node in self.services.values() for m, _ in per_node.values())
        done = sum(d for per_node in self.services.values() for _, d in per_node.values())
        return made == done

    def unsettled(self, now: int, released: bool = False) -> list[str]:
        """Why the graph has not settled at ``now`` (ns), before or after the step's
        release; empty when it has. Called with the condition held."""
        self.take_reports()
        why = []
        if self.state.busy:
            why.append("the simulator's callbacks run")
        for name, report in self.reports.items():
            if report["sim"] and report["time"] < now and not report.get("board"):
                why.append(f"{name} is at {report['time'] / 1e9:.2f} s")
            elif released and report["released"] < now and (report["next"] or now + 1) <= now:
                why.append(f"{name}'s timers have not run")
        if why:
            return why
        for topic, source, to in sorted(self.unbalanced)[:4]:
            sent, got = (
                self.sent.get((topic, source, to), 0),
                self.received.get((topic, source, to), 0),
            )
            why.append(f"{topic} {source} -> {to}: sent {sent}, received {got}")
        made = sum(m for per_node in self.services.values() for m, _ in per_node.values())
        done = sum(d for per_node in self.services.values() for _, d in per_node.values())
        if made != done:
            why.append(f"services: {made} calls answered, {done} served")
        return why

    def due(self, stamp: Any) -> bool:
        """Whether a process has a timer due at ``stamp`` (a ``rospy.Time``), or may have:
        before every process has reported a deadline. Between two due steps nothing in the
        graph runs but the callbacks that take in the simulator's sensor messages, so the
        simulator need not publish ``/clock`` nor wait there (:meth:`step` waits at the next
        due step until those messages are in)."""
        now = int(stamp.to_nsec())
        with self.state.cond:
            self.take_reports()
            if self.state.busy or not self.reports:
                return True
            for report in self.reports.values():
                if report.get("waiting", True):
                    return True  # a sleep that began before time started
                deadline = report.get("next")
                if deadline is not None and deadline <= now:
                    return True
        return False

    def tick(self, stamp: Any) -> bool:
        """The step at ``stamp`` (a ``rospy.Time``) begins, before the simulator publishes its
        messages; whether it is due (:meth:`due`). A due step's time goes on the board and
        ``/clock`` to the processes that do not read the board (those outside the lockstep,
        a recorder, among them); the others take their time from the board when a message
        comes, and from the release when a timer is due."""
        with self.state.cond:
            self.before = dict(self.state.sent)
        if not self.due(stamp):
            return False
        now = int(stamp.to_nsec())
        self.board.write(now)
        self.state.advance(now)
        with self.state.cond:
            self.take_reports()
            reading = {name for name, report in self.reports.items() if report.get("board")}
        if self.clock_publisher is not None:
            self.publish_clock(stamp, lambda name: name not in reading)
        return True

    def publish_clock(self, stamp: Any, to: Any) -> None:
        """``/clock`` at ``stamp`` to the subscribers (but the simulator) ``to(name)`` says."""
        message = self.clock(clock=stamp)
        _publish_each(
            self.clock_publisher,
            lambda name: message if name != self.name and to(name) else None,
        )

    def unreported(self) -> set[str]:
        """The processes the simulator sent messages to since its last due step but none
        at this one: nothing makes them report what they took in (a sensor message of a step
        that is not due leaves its report out)."""
        since, now = set(), set()
        with self.state.cond:
            sent = dict(self.state.sent)
        for key, count in sent.items():
            name = key.rpartition(">")[2]
            if count > self.at_due.get(key, 0):
                since.add(name)
            if count > self.before.get(key, 0):
                now.add(name)
        return since - now

    def step(self, stamp: Any) -> None:
        """The due step at ``stamp`` (a ``rospy.Time``; :meth:`tick`), once its sensor
        messages are published: wait until every process has them (``/clock`` to a process
        that would not report without: :meth:`unreported`), release the step's timers in the
        processes that have one due, wait until the graph has reacted."""
        now = int(stamp.to_nsec())
        if self.clock_publisher is not None:
            poke = self.unreported()
            if poke:
                self.publish_clock(stamp, poke.__contains__)
            with self.state.cond:
                self.at_due = dict(self.state.sent)
        with self.state.cond:
            self.take_reports()
            direct = bool(self.reports) and all(r.get("board") for r in self.reports.values())
        if not direct:  # a process that takes its time from /clock must have it first
            self.settle(now)
        self.settle(now, stamp)

    def due_now(self, now: int) -> set[str]:
        """The processes with a timer due at ``now`` (ns) or that may have one (a sleep that
        began before time started): those the step's release goes to. Called with the
        condition held, the graph settled at ``now``."""
        due = {
            name
            for name, report in self.reports.items()
            if report.get("waiting", True) or (report["next"] is not None and report["next"] <= now)
        }
        if self.state.sleepers:
            due.add(self.name)
        return due

    def release(self, stamp: Any, names: set[str]) -> None:
        """``/lockstep/go`` at ``stamp`` to the subscribers ``names`` only: a process with
        no timer due has nothing to release (its next due step releases it up to then).
        Each release gives how many messages the simulator sent that process so far, per
        topic: its timers wait until it took them in."""
        now = int(stamp.to_nsec())
        with self.state.cond:
            sent = dict(self.state.sent)

        def message_to(name: str) -> Any:
            if name not in names:
                return None
            expect = {}
            for key, count in sent.items():
                topic, _, to = key.rpartition(">")
                if to == name:
                    expect[f"{topic}<{self.name}"] = count
            return self.string(json.dumps({"t": now, "expect": expect}))

        _publish_each(self.go, message_to)

    def settle(self, now: int, stamp: Any = None, timeout: float = 30.0) -> bool:
        """Wait until the graph has reacted to time ``now`` (ns); with ``stamp`` (the step's
        time), after releasing the timers due then (to each process once, as soon as it
        reports one due: a timer that began after the release sees it too). False (and a
        warning) when it did not within ``timeout`` wall seconds: the step goes on (counted
        in :attr:`stalls`)."""
        released = stamp is not None
        sent: set[str] = set()
        deadline = time.monotonic() + timeout
        while True:
            with self.state.cond:
                # settled() is unsettled()'s answer without its reasons, which only the
                # warning needs
                if self.settled(now, released) or self.state.rospy.is_shutdown():
                    return True
                wake = self.due_now(now) - sent if released else set()
                if not wake:
                    left = deadline - time.monotonic()
                    if left <= 0:
                        why = self.unsettled(now, released)
                        self.stalls += 1
                        self.forget_the_dead()
                        self.state.rospy.logwarn(
                            "lockstep: not settled at %.2f s: %s", now / 1e9, why[:4]
                        )
                        return False
                    self.awaiting = (now, released, sent)
                    try:
                        self.state.cond.wait(min(left, 1.0))
                    finally:
                        self.awaiting = None
                    continue
            sent |= wake
            self.release(stamp, wake)

    def forget_the_dead(self) -> None:
        for name, report in list(self.reports.items()):
            try:
                os.kill(int(report["pid"]), 0)
            except OSError:
                self.reports.pop(name, None)
                self.services.pop(name, None)
        self.recheck()

    def start(self, timeout: float = 60.0) -> bool:
        """Before time starts: wait until the Python processes the same ``roslaunch``
        started have all reported ready, and every publisher among the participants is
        connected to every subscriber the master knows. False after ``timeout``."""
        master = self.state.rospy.get_master()
        deadline = time.monotonic() + timeout
        why = ""
        while time.monotonic() < deadline and not self.state.rospy.is_shutdown():
            with self.state.cond:
                self.take_reports()
                reports = {name: dict(report) for name, report in self.reports.items()}
            pids = {int(r["pid"]) for r in reports.values() if r["ready"]}
            missing = siblings() - pids - {os.getpid()}
            why = f"processes {sorted(missing)} not ready" if missing else ""
            why = why or self.connected(master, reports)
            if not why:
                return True
            time.sleep(0.05)
        self.state.rospy.logwarn("lockstep: time starts although %s", why)
        return False

    def connected(self, master: Any, reports: dict[str, dict[str, Any]]) -> str:
        """Why not every publisher is connected to its subscribers yet ("" when it is)."""
        code, _, system = master.getSystemState()
        if code != 1:
            return "the master did not answer"
        everyone = {name: set(r["links"]) for name, r in reports.items()}
        everyone[self.name] = set(self.state.links())
        subscribers = {topic: set(nodes) for topic, nodes in system[1]}
        for topic, publishers in system[0]:
            if topic in UNLINKED:
                continue
            for publisher in publishers:
                if publisher not in everyone:
                    continue
                for subscriber in subscribers.get(topic, ()):
                    if (
                        subscriber in everyone
                        and f"{topic}>{subscriber}" not in everyone[publisher]
                    ):
                        return f"{publisher} is not connected to {subscriber} on {topic}"
        return ""


def siblings() -> set[int]:
    """The other Python processes of this process's parent when it is ``roslaunch``."""
    parent = os.getppid()
    try:
        with open(f"/proc/{parent}/cmdline", "rb") as handle:
            if b"roslaunch" not in handle.read():
                return set()
    except OSError:
        return set()
    found = set()
    for entry in os.listdir("/proc"):
        if not entry.isdigit():
            continue
        try:
            with open(f"/proc/{entry}/stat", encoding="utf-8") as handle:
                fields = handle.read().rsplit(")", 1)[1].split()
            if int(fields[1]) != parent:
                continue
            with open(f"/proc/{entry}/cmdline", "rb") as handle:
                command = handle.read().split(b"\0")
        except (OSError, IndexError, ValueError):
            continue
        if command and b"python" in os.path.basename(command[0]):
            found.add(int(entry))
    return found
