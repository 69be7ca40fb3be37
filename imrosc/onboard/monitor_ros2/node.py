"""The monitor node for ROS 2 (rclpy): thin plumbing around the runtime engine.

A generated monitor package's entry point runs :func:`main` with its runtime engine class
and its generated flatteners. The node

* subscribes to every topic of the invariants file with the QoS its publishers offer
  (``get_publishers_info_by_topic``: best effort as soon as one publisher is, transient
  local when all are; a ``sensor_msgs`` topic starts as ``qos_profile_sensor_data`` until a
  publisher shows), flattens each message and feeds it to the engine; a blocked topic's
  message is republished on ``/m/<topic>``, with the source's QoS, unless one of its
  violations belongs to an alarm (the rewritten launch file remaps the topic's subscribers
  there). A blocked topic is subscribed raw: its values are read from the CDR bytes
  (``cdr.py``) and the relay publishes the same bytes, so a relayed message is neither
  decoded into a Python object nor encoded again;
* serves ``/m/<service>`` for every watched or blocked service once the graph tells the
  service's type, forwards each call to the real service and feeds the call to the engine;
  for a blocked service a request that breaks an invariant of the request in alarm is not
  forwarded and a response that breaks one in alarm is withheld. ROS 2 services have no
  error reply (rclpy sends whatever the callback returns), so the client gets the type's
  default response (every field zero, false or empty) instead;
* every ``period`` seconds (ROS time) advances the engine's clock, reads the graph
  (``get_topic_names_and_types``, ``get_publishers_info_by_topic``,
  ``get_subscriptions_info_by_topic``, ``get_service_names_and_types_by_node``) into
  ``engine.graph`` and the parameters the invariants read (``rcl_interfaces/GetParameters``
  on ``/<node>/get_parameters``) into ``engine.params`` (each only when it changed), adapts
  the QoS of its subscriptions and relays to publishers that appeared, and sets up what
  could not be set up yet (a topic or service whose type only the graph knows);
* runs the engine under the invariants file's alarm rule, overridden by the ``<monitor>``'s
  ``alarm_*`` attributes (``spec.json``'s ``alarms``), and after each call takes the alarms
  raised and the violations that belong to an alarm;
* publishes every violation as JSON on ``/m/broken_inv`` (with ``alarm``: whether it belongs
  to an alarm, and ``rule``: the rule of the alarm it raised), takes on each newly raised
  alarm the actions the violation map names for its point (in a worker thread, so checking
  never waits for a service), clears an invariant named on ``/m/clear_inv`` and beats on
  ``/m/heartbeat`` (wall time) for the fail-open watchdog. An unknown publisher that breaks
  a ``max_pubs`` invariant is only reported, with a note: ROS 2 has no master to unregister
  it from.

Parameters: ``invariants`` (path; default the package's ``share/<pkg>/config/
invariants.json``), ``period`` (seconds), ``namespace`` (``/m``), ``watchdog`` (the
watchdog's node name, left out of the graph like the monitor itself), ``service_timeout``
(seconds to wait for a forwarded call or an action's call; 10), ``warm`` (seconds between
rehearsals of the checks while the blocked topics are quiet; 0.002; 0: off).

Every decision is a function of ``logic.py`` or of the shared ``imrosc/onboard/monitor.py``;
this module only talks to ROS. Python 3.8 syntax.
"""

from __future__ import annotations

import gc
import os
import queue
import struct
import sys
import threading
import time
import traceback
from typing import Any, Callable, Dict, List, Mapping, Optional, Sequence, Set, Tuple

import numpy as np

from .. import files
from .. import monitor as common
from ..fill import FillError
from . import cdr, logic, plumbing

try:  # only a ROS 2 system has these; the helpers above are usable without them
    import rclpy  # type: ignore[import-not-found, unused-ignore]
    from builtin_interfaces.msg import (  # type: ignore[import-not-found, unused-ignore]
        Time as TimeMsg,
    )
    from rclpy.callback_groups import (  # type: ignore[import-not-found, unused-ignore]
        MutuallyExclusiveCallbackGroup,
        ReentrantCallbackGroup,
    )
    from rclpy.executors import (  # type: ignore[import-not-found, unused-ignore]
        MultiThreadedExecutor,
        SingleThreadedExecutor,
    )
    from rclpy.node import Node  # type: ignore[import-not-found, unused-ignore]
    from rclpy.serialization import (  # type: ignore[import-not-found, unused-ignore]
        deserialize_message,
    )
    from std_msgs.msg import String  # type: ignore[import-not-found, unused-ignore]
except ImportError:  # pragma: no cover - exercised on ROS 2 systems only
    rclpy = None

QUEUE = plumbing.QUEUE
THREADS = 4
"""Executor threads of a node that relays services: the timer, ``/m/clear_inv`` (and the
topics' messages before Humble: in order) run in one mutually exclusive group; relayed
service calls wait for the real service in the others. A node that relays no service spins
one thread (:func:`executor_for`)."""
SERVICE_TIMEOUT = 10.0
WAIT = 0.5
"""Seconds the thread that takes the topics' messages waits at most before it looks
whether the node still runs (closing it wakes it at once)."""
STOP_TAKING = 30.0
"""Seconds the node's shutdown waits for its message thread to end (it ends within one
:data:`WAIT` and :data:`QUEUE` messages, which a loaded machine stretches)."""
Flatten = Callable[[Any], List[Any]]


def default_invariants(package: str) -> str:
    """The package's ``config/invariants.json``: in its share folder (ament index), else
    in the source package this module was copied into."""
    try:
        from ament_index_python.packages import (  # type: ignore[import-not-found, unused-ignore]
            get_package_share_directory,
        )

        return os.path.join(get_package_share_directory(package), "config", "invariants.json")
    except Exception:
        source = os.path.dirname(files.package_folder())  # the source package
        return os.path.normpath(os.path.join(source, "config", "invariants.json"))


class Topic:
    """A watched or blocked topic: its type, class, QoS, subscription and relay. A blocked
    topic is subscribed raw and relayed as the bytes it came in (``cdr.py``): ``read`` gives
    the values from the bytes, or is ``None`` when the node deserialises them instead."""

    def __init__(self, name: str, msgtype: Optional[str], relay: Optional[str]) -> None:
        self.name = name
        self.msgtype = msgtype
        self.relay_name = relay
        self.message_class: Any = None
        self.read: Optional[cdr.Reader] = None
        self.take: Optional[Callable[[], Any]] = None
        """The subscription's next message, ``None`` when none is waiting
        (:func:`plumbing.taker`)."""
        self.qos: Optional[logic.Qos] = None
        self.relay_qos: Optional[logic.Qos] = None
        self.subscription: Any = None
        self.relay: Any = None


class Monitor(common.Checking):
    """The node's state: the engine and what the spec says (:class:`common.Checking`), its
    ROS endpoints and what it learnt from the graph."""

    def __init__(
        self,
        node: Any,
        spec: files.SpecDocument,
        document: Mapping[str, Any],
        engine_class: Callable[..., Any],
        flatteners: Mapping[str, Flatten],
    ) -> None:
        self.node = node
        self.log = node.get_logger()
        self.warn = getattr(self.log, "warning", None) or self.log.warn  # Foxy has warn only
        namespace = str(plumbing.get_param(node, "namespace", spec["namespace"]))
        super().__init__(spec, document, engine_class, namespace, self.stop)
        self.period = float(plumbing.get_param(node, "period", spec["period"]))
        self.timeout = float(plumbing.get_param(node, "service_timeout", SERVICE_TIMEOUT))
        self.warm = max(0.0, float(plumbing.get_param(node, "warm", common.WARM)))
        self.clock = node.get_clock()
        self.wall_clock = False
        """Whether ROS time is the system clock (no ``use_sim_time``): :meth:`now` then reads
        ``time.time()`` (0.06 us) instead of building an rclpy ``Time`` (7 us); checked again
        at every poll."""
        self.name = logic.node_name(node.get_namespace(), node.get_name())
        watchdog = str(plumbing.get_param(node, "watchdog", spec["watchdog"]))
        self.own: Set[str] = {self.name, logic.resolve_node(node.get_namespace(), watchdog)}
        self.stand_ins = common.learnt_publishers(document.get("invariants", ()))
        """Per topic, the publishers ``ros2 bag play`` stands for (``common.PLAYBACK``)."""
        ns = self.namespace
        self.flatteners = flatteners
        self.layouts: Mapping[str, Sequence[Mapping[str, Any]]] = {
            name: info.get("variables", []) for name, info in document.get("topics", {}).items()
        }
        self.broken = node.create_publisher(
            String, ns + "/broken_inv", plumbing.profile(logic.DEFAULT)
        )
        self.checks = MutuallyExclusiveCallbackGroup()
        self.calls = ReentrantCallbackGroup()
        self.parameters = plumbing.ParameterAsker(
            node, self.calls, self.lock, lambda text: self.warn("imrosc: " + text)
        )
        self.topics = {
            t["name"]: Topic(t["name"], t.get("ros2_type"), self.topic_relays.get(t["name"]))
            for t in spec["topics"]
        }
        self.waiter: Optional[plumbing.Waiter] = None
        """Where the topics' messages are waited for and taken, in a thread of their own
        (:meth:`take_messages`); ``None`` where rclpy cannot (before Humble): the executor
        runs the subscriptions' callbacks then."""
        self.by_the_waiter: Any = None
        if plumbing.Waiter.available():
            self.waiter = plumbing.Waiter(node.context)
            self.by_the_waiter = plumbing.NotByTheExecutor()
        self.endpoints = threading.Lock()
        """Held while a topic's subscription or relay is replaced and while its messages are
        checked and relayed: no message is relayed on a publisher being destroyed."""
        self.services: Dict[str, Tuple[Any, Any]] = {}
        self.action_out: Dict[str, Tuple[Any, Any]] = {}
        self.action_clients: Dict[str, Tuple[Any, Any]] = {}
        self.pending_actions = set(self.actions)
        self.work = queue.Queue()  # type: queue.Queue[str]
        self.beat = node.create_publisher(TimeMsg, ns + "/heartbeat", 1)
        node.create_subscription(
            String,
            ns + "/clear_inv",
            self.checked("/clear_inv", self.on_clear),
            QUEUE,
            callback_group=self.checks,
        )
        threading.Thread(target=self.worker, name="imrosc-actions", daemon=True).start()
        threading.Thread(target=self.heartbeat, name="imrosc-heartbeat", daemon=True).start()
        if self.warm and self.topic_relays:
            threading.Thread(
                target=self.keep_warm, args=(self.warm, rclpy.ok), name="imrosc-warm", daemon=True
            ).start()
        self.guard.run("the timer", self.tick)
        self.timer = node.create_timer(
            self.period, self.checked("the timer", self.tick), callback_group=self.checks
        )
        self.taking: Optional[threading.Thread] = None
        if self.waiter is not None:
            self.taking = threading.Thread(
                target=self.take_messages, name="imrosc-messages", daemon=True
            )
            self.taking.start()

    def checked(self, where: str, callback: Callable[..., Any]) -> Callable[..., Any]:
        """``callback`` under the guard: the first exception stops the node (:meth:`stop`).
        An exception once ROS is shutting down (Ctrl-C: a relay publishing on a context just
        closed) is the shutdown's, not a failure of the checks."""

        def unless_shut_down(*args: Any) -> Any:
            try:
                return callback(*args)
            except Exception:
                if rclpy.ok():
                    raise
                return None

        def run(*args: Any) -> Any:
            return self.guard.run(where, unless_shut_down, *args)

        return run

    def stop(self, where: str, error: BaseException) -> None:
        """A check raised: report it on ``/m/broken_inv`` and in the log, stop the heartbeat
        and shut ROS down, which ends the node's spin (the guard already keeps every callback
        from checking or relaying)."""
        text = common.failure_text(where, error)
        self.log.fatal(f"{text}\n{traceback.format_exc()}")
        try:
            self.broken.publish(String(data=common.failure_json(where, error, time.time())))
        except Exception as failed:  # the report is best effort; the shutdown is not
            self.log.error(f"imrosc: cannot publish the failure: {failed}")
        shutdown = getattr(rclpy, "try_shutdown", None) or rclpy.shutdown
        # let the report reach its subscribers before the node's endpoints close
        threading.Timer(0.5, shutdown).start()

    def now(self) -> float:
        """ROS time in seconds (simulated time with ``use_sim_time``)."""
        if self.wall_clock:
            return time.time()
        return float(self.clock.now().nanoseconds) / 1e9

    # -- setting up -------------------------------------------------------------------------

    def connect(self, view: logic.GraphView) -> None:
        """Set up, or adapt to the graph, the subscriptions, relays, relayed services and
        action endpoints."""
        for topic in self.topics.values():
            self.connect_topic(topic, view)
        for name, relay in sorted(self.service_relays.items()):
            if name in self.services:
                continue
            kinds = view.service_types.get(name)
            found = plumbing.service_class(kinds[0]) if kinds else None
            if found is None:
                continue
            client = self.node.create_client(found, name, callback_group=self.calls)
            server = self.node.create_service(
                found, relay, self.handler(name, client), callback_group=self.calls
            )
            self.services[name] = (client, server)
        for ident in sorted(self.pending_actions):
            self.connect_action(ident, view)

    def connect_topic(self, topic: Topic, view: logic.GraphView) -> None:
        """Subscribe (again, when the publishers' QoS asks for another) and relay."""
        if topic.message_class is None:
            kinds = view.types.get(topic.name) or ()
            topic.msgtype = topic.msgtype or (kinds[0] if kinds else None)
            if not topic.msgtype:
                return
            topic.message_class = plumbing.message_class(topic.msgtype)
            if topic.message_class is None:
                self.log.error(
                    f"imrosc: no message class {topic.msgtype} for {topic.name}",
                    throttle_duration_sec=60.0,
                )
                topic.msgtype = None
                return
            if topic.relay_name is not None and topic.name in self.flatteners:
                layout = self.layouts.get(topic.name, ())
                topic.read = cdr.reader(topic.message_class, layout, plumbing.message_class)
        publishers = logic.publisher_qos(view, topic.name, self.own)
        wanted = logic.qos_update(topic.qos, publishers, topic.msgtype)
        offer = None
        if topic.relay_name is not None:
            offer = logic.qos_update(topic.relay_qos, publishers, topic.msgtype, logic.relay_qos)
        if wanted is None and offer is None:
            return
        with self.endpoints:
            if wanted is not None:
                self.subscribe(topic, wanted)
            if offer is not None:
                if topic.relay is not None:
                    self.node.destroy_publisher(topic.relay)
                topic.relay_qos = offer
                topic.relay = self.node.create_publisher(
                    topic.message_class,
                    topic.relay_name,
                    plumbing.profile(offer, plumbing.TOPIC_DEPTH),
                )

    def subscribe(self, topic: Topic, qos: logic.Qos) -> None:
        """(Re)subscribe to ``topic`` with ``qos``: taken by :attr:`waiter` where it can,
        else in the executor's checks group."""
        if topic.subscription is not None:
            self.node.destroy_subscription(topic.subscription)
        topic.qos = qos
        topic.subscription = self.node.create_subscription(
            topic.message_class,
            topic.name,
            self.checked(f"message on {topic.name}", self.on_message_of(topic)),
            plumbing.profile(qos, plumbing.TOPIC_DEPTH),
            callback_group=self.checks if self.waiter is None else self.by_the_waiter,
            raw=topic.relay_name is not None,
        )
        topic.take = plumbing.taker(topic.subscription)
        if self.waiter is not None:
            self.waiter.put(topic.name, topic.subscription)

    def connect_action(self, ident: str, view: logic.GraphView) -> None:
        """The publisher and message of a topic action, the client of a service action."""
        action = self.actions[ident]
        name = action["name"]
        if action["target"] == "topic":
            kinds = view.types.get(name) or ()
            msgtype = action.get("ros2_type") or (kinds[0] if kinds else None)
            found = plumbing.message_class(msgtype) if msgtype else None
            if found is None:
                return
            self.pending_actions.discard(ident)
            try:
                message = logic.fill(found(), action["value"], plumbing.fill_class)
            except (FillError, TypeError, ValueError, AssertionError) as error:
                self.log.error(f"imrosc: action {ident} is disabled: {error}")
                return
            offer = logic.relay_qos(logic.publisher_qos(view, name, self.own), msgtype)
            publisher = self.node.create_publisher(
                found, action["destination"], plumbing.profile(offer)
            )
            self.action_out[ident] = (publisher, message)
            return
        kinds = view.service_types.get(name) or ()
        found = plumbing.service_class(kinds[0]) if kinds else None
        if found is None:
            return
        self.pending_actions.discard(ident)
        self.action_clients[ident] = (
            self.node.create_client(found, name, callback_group=self.calls),
            found,
        )

    # -- what happens -----------------------------------------------------------------------

    def take_messages(self) -> None:
        """The thread that waits for the topics' messages (:class:`plumbing.Waiter`) and
        checks and relays them, each topic's in order, while the node runs."""
        waiter = self.waiter
        assert waiter is not None
        takers = {name: self.checked(f"message on {name}", self.take_all) for name in self.topics}
        while rclpy.ok() and self.guard.failure is None and not waiter.closed:
            for name in waiter.wait(WAIT):
                takers[name](self.topics[name])

    def take_all(self, topic: Topic) -> None:
        """Check and relay the messages waiting on ``topic``, in order, up to :data:`QUEUE`
        of them (the others' turn comes after)."""
        flatten = self.flatteners.get(topic.name)
        with self.endpoints:
            take = topic.take
            if take is None:
                return
            for _ in range(QUEUE):
                message = take()
                if message is None:
                    return
                self.check_message(topic, flatten, message)

    def stop_taking(self) -> None:
        """End the thread of :meth:`take_messages` before the node is destroyed: it wakes at
        once (:meth:`plumbing.Waiter.close`) and takes at most :data:`QUEUE` messages more,
        so it ends; waiting for it to end, however long a loaded machine makes that, keeps
        the node's endpoints, and the interpreter, from being torn down under it (a daemon
        thread still inside rclpy at the interpreter's exit crashes the process)."""
        if self.waiter is not None:
            self.waiter.close()
        if self.taking is not None:
            self.taking.join(timeout=STOP_TAKING)
            if self.taking.is_alive():
                self.log.warning(f"imrosc: the message thread did not end within {STOP_TAKING:g} s")

    def on_message_of(self, topic: Topic) -> Callable[[Any], None]:
        """The subscription callback of ``topic`` where the executor takes its messages
        (no :attr:`waiter`): a message object, or the bytes of a blocked topic's message
        (relayed as they are). The messages that arrived meanwhile are then taken in the
        same callback, in order, up to :data:`QUEUE` of them (:func:`plumbing.taker`):
        rclpy's executor rebuilds its wait set and makes a task for every message it hands
        over, which costs more than the checks, so a node that fell behind (a loaded
        machine) catches up at the cost of the checks alone."""
        flatten = self.flatteners.get(topic.name)

        def on_message(message: Any) -> None:
            self.check_message(topic, flatten, message)
            take = topic.take
            if take is None:
                return
            for _ in range(QUEUE - 1):
                more = take()
                if more is None:
                    return
                self.check_message(topic, flatten, more)

        return on_message

    def check_message(self, topic: Topic, flatten: Optional[Flatten], message: Any) -> None:
        """Check one message of ``topic`` and relay it unless it is withheld."""
        name = topic.name
        if topic.relay_name is not None:
            readable, values = self.read(topic, message, flatten)
            if not readable:  # neither checked nor relayed
                return
        else:
            values = flatten(message) if flatten is not None else None
        with self.lock:
            now = self.now()
            found, caused, raised, alarmed = self.check_values(name, now, values)
        if topic.relay is not None:
            self.last_relayed = time.time()
            if not common.withheld(caused, alarmed):
                topic.relay.publish(message)
            else:
                self.warn(common.blocked_line(name, caused, alarmed), throttle_duration_sec=1.0)
        self.report(found + caused, raised, alarmed)

    def read(
        self, topic: Topic, data: bytes, flatten: Optional[Flatten]
    ) -> Tuple[bool, Optional[List[Any]]]:
        """Whether a message that came as bytes is readable, and its values: read by
        ``topic.read``, or, when it cannot read them (no plan for the layout, another
        encapsulation), from the message rclpy deserialises (bytes that do not deserialise
        are logged, and the message is neither checked nor relayed)."""
        if flatten is None:
            return True, None
        if topic.read is not None:
            try:
                values: List[Any] = topic.read(data)
                return True, values
            except (struct.error, IndexError, ValueError, TypeError):
                pass
        try:
            message = deserialize_message(data, topic.message_class)
        except Exception as error:  # the type support raises several kinds on bad bytes
            self.log.error(
                f"imrosc: a message on {topic.name} does not deserialise: {error}",
                throttle_duration_sec=60.0,
            )
            return False, None
        return True, flatten(message)

    def handler(self, service: str, client: Any) -> Callable[[Any, Any], Any]:
        """The callback of ``/m/<service>``: check, forward, check, answer. A refused or
        withheld call, or one the service does not answer in time, is answered with
        ``response``, the type's default response (ROS 2 services have no error reply)."""
        blocked = service in self.blocked_services

        def serve(request: Any, response: Any) -> Any:
            if self.guard.failure is not None:  # stopped: a default answer, nothing forwarded
                return response
            try:
                return forward(request, response)
            except Exception as error:
                self.log.error(f"imrosc: relaying {service} failed: {error}")
                return response

        def check(engine: Any, values: Any) -> Any:
            """The call's violations, and the alarms they raise, under the guard."""
            with self.lock:
                now = self.now()
                found = engine.advance(now) if engine is self.engine else []
                caused = engine.call(service, now, values)
                raised, alarmed = common.take_alarms(engine, found + caused)
            return found, caused, raised, alarmed

        def forward(request: Any, default: Any) -> Any:
            precheck = self.precheck
            if blocked and precheck is not None:
                values = common.request_values(logic.message_data, request)
                done = self.guard.run(f"call of {service}", check, precheck, values)
                if done is None:
                    return default
                _, refused, raised, alarmed = done
                if common.withheld(refused, alarmed):
                    self.report(refused, raised, alarmed)
                    ids = common.withheld_for(refused, alarmed)
                    self.warn(f"imrosc: refused a request to {service}: {ids}")
                    return default
            start = self.now()
            answer = plumbing.call(client, request, self.timeout)
            values = common.call_values(logic.message_data, request, answer, self.now() - start)
            done = self.guard.run(f"call of {service}", check, self.engine, values)
            if done is None:
                return default
            found, caused, raised, alarmed = done
            self.report(found + caused, raised, alarmed)
            if blocked and common.withheld(caused, alarmed):
                ids = common.withheld_for(caused, alarmed)
                self.warn(f"imrosc: withheld the response of {service}: {ids}")
                return default
            return answer

        return serve

    def on_clear(self, message: Any) -> None:
        """``/m/clear_inv``: stop checking the invariant named by the message."""
        ident = str(message.data).strip()
        if self.clear_invariant(ident):
            self.log.info(f"imrosc: invariant {ident} cleared")
        else:
            self.warn(f"imrosc: /clear_inv names no invariant: {ident!r}")

    def tick(self) -> None:
        """The timer: the clock, the graph and the parameters; adapt and retry the setup."""
        try:
            view: Optional[logic.GraphView] = plumbing.read_graph(self.node)
        except Exception as error:
            self.warn(f"imrosc: cannot read the graph: {error}")
            view = None
        self.wall_clock = not getattr(self.clock, "ros_time_is_active", True)
        graph = None
        if view is not None and view.complete:  # else a node is half discovered: wait
            graph = logic.snapshot(
                view, self.own, self.topic_relays, self.service_relays, self.stand_ins
            )
        with self.lock:
            answers = self.parameters.answers
            params = logic.param_values(answers, self.spec["params"]) if answers else None
            found, raised, alarmed = self.poll_engine(self.now(), graph, params)
        if view is not None:
            self.connect(view)
            self.ask_params(view)
        self.report(found, raised, alarmed)

    def ask_params(self, view: logic.GraphView) -> None:
        """Ask each node for the parameters the invariants read (the answers are fed to the
        engine at the next poll)."""
        requests = logic.parameter_requests(self.spec["params"], view.nodes)
        for owner, asked in requests.items():
            if owner not in self.own:
                self.parameters.ask(owner, asked)

    def compile(self, compiler: str) -> None:
        """Compile the checks with numba while the node relays (numpy checks meanwhile) and
        log what is in use (:func:`common.compile_engines`)."""
        try:
            self.log.info(self.compile_checks(compiler))
        except Exception as error:  # numpy's checks go on: nothing is lost but speed
            self.warn(f"imrosc: compiling the checks failed ({error}): numpy checks them")

    def heartbeat(self) -> None:
        """Beat on ``/m/heartbeat`` every period of wall time while the node runs."""
        while rclpy.ok() and self.guard.failure is None:
            try:
                self.beat.publish(self.node.get_clock().now().to_msg())
            except Exception:  # shutting down
                return
            time.sleep(self.period)

    # -- what the monitor does about it -----------------------------------------------------

    def report(
        self, violations: Sequence[Any], raised: Sequence[Any], alarmed: Sequence[Any]
    ) -> None:
        """Warn on ``/m/broken_inv`` (a ``max_pubs`` violation with a note: ROS 2 cannot
        unregister the publisher) and in the log (an alarm or a violation alone); queue the
        actions of the newly raised alarms."""
        for report in common.reports(violations, raised, alarmed, self.violation_map):
            self.broken.publish(String(data=logic.report_warning(report)))
            if report.alarm:  # two call sites: alarms and violations are throttled apart
                self.warn(common.log_line(report), throttle_duration_sec=1.0)
            else:
                self.warn(common.log_line(report), throttle_duration_sec=1.0)
        for ident in common.select_actions(raised, self.violation_map):
            self.work.put(ident)

    def worker(self) -> None:
        """Take the queued actions one by one (a service call may take its time)."""
        while rclpy.ok():
            try:
                ident = self.work.get(timeout=0.5)
            except queue.Empty:
                continue
            try:
                self.act(ident)
            except Exception as error:
                self.log.error(f"imrosc: action {ident} failed: {error}")

    def act(self, ident: str) -> None:
        """Publish the action's message or call its service."""
        action = self.actions[ident]
        if action["target"] == "topic":
            out = self.action_out.get(ident)
            if out is None:
                self.warn(f"imrosc: action {ident} is not ready", throttle_duration_sec=10.0)
                return
            publisher, message = out
            publisher.publish(message)
            return
        ready = self.action_clients.get(ident)
        if ready is None or not ready[0].service_is_ready():
            self.warn(f"imrosc: action {ident}: service {action['name']} is not available")
            return
        client, found = ready
        request = logic.fill(found.Request(), action["value"], plumbing.fill_class)
        plumbing.call(client, request, self.timeout)


def executor_for(monitor: Monitor) -> Any:
    """The executor the node spins: a ``MultiThreadedExecutor`` when it relays services (a
    relayed call waits for the real service inside its callback, so another thread must take
    the response), else a ``SingleThreadedExecutor``. rclpy's multi-threaded executor hands
    every callback to a worker thread through a future and rebuilds its wait set for each,
    which at 1 kHz cost several times the checks (bench/monitor_latency.py); without relayed
    services nothing waits in a callback (actions run in their own thread, parameters are
    asked asynchronously). The topics' messages are taken by the node's own thread
    (:meth:`Monitor.take_messages`) where rclpy allows it, else by this executor, in order
    (one thread, or the exclusive group)."""
    if monitor.service_relays:
        return MultiThreadedExecutor(num_threads=THREADS)
    return SingleThreadedExecutor()


def main(
    package: str,
    engine_class: Callable[..., Any],
    flatteners: Mapping[str, Flatten],
    args: Optional[List[str]] = None,
) -> None:
    """Run the monitor node of ``package`` until ROS shuts down."""
    if rclpy is None:
        sys.exit("imrosc monitor: rclpy is not importable; run it on a ROS 2 system")
    np.seterr(all="ignore")  # the engine checks NaN and infinities itself
    rclpy.init(args=args)
    node = Node(
        package,
        allow_undeclared_parameters=True,
        automatically_declare_parameters_from_overrides=True,
    )
    path = str(plumbing.get_param(node, "invariants", "") or default_invariants(package))
    try:
        spec = files.load_monitor_spec()
        document = files.load_invariants(path)
    except (OSError, ValueError) as error:
        node.get_logger().fatal(f"imrosc monitor: {error}")
        sys.exit(1)
    try:
        monitor = Monitor(node, spec, document, engine_class, flatteners)
    except files.InvariantsError as error:  # the engine cannot be built from the file
        node.get_logger().fatal(f"imrosc monitor: {path}: {error}")
        sys.exit(1)
    # the engine's tens of thousands of objects live as long as the node: out of the
    # collector's sight, a full collection no longer walks them (17 ms for 1,000 invariants,
    # a stall of the relay; the objects made later are collected as before)
    gc.collect()
    gc.freeze()
    compiler = monitor.engine.compiler()
    node.get_logger().info(
        f"imrosc monitor {logic.node_name(node.get_namespace(), node.get_name())}: checking "
        f"{len(document['invariants'])} invariants from {path}; {common.checks_plan(compiler)}"
    )
    executor = executor_for(monitor)
    executor.add_node(node)
    if compiler is not None:
        threading.Thread(
            target=monitor.compile, args=(compiler,), name="imrosc-compile", daemon=True
        ).start()
    plumbing.spin_until_stopped(executor, node, monitor.stop_taking)
    if monitor.guard.failure is not None:
        sys.exit(1)  # the launch reports the exit
