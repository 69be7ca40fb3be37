"""The ROS 2 recorder node (rclpy): publishes the record topics that ``imrosc record --ros2``
(or ``ros2 bag record``) saves.

Every ``period`` seconds (and at start) it reads the graph (rclpy's graph API, through
``monitor_ros2``'s :func:`plumbing.read_graph`) and asks the nodes for the scope's
parameters (``GetParameters`` on ``/<node>/get_parameters``), and publishes an
architecture (``/imrosc/arch``) or parameter (``/imrosc/params``) snapshot when it differs
from the last one it published. A half-discovered graph (an endpoint whose node DDS has not
named yet) is not published; the next poll reads it again.

Service calls come from service introspection (ROS 2 Iron and later): for each ``<call>``
service of the scope it subscribes to ``<service>/_service_event`` as soon as the topic
shows up with its ``<pkg>/srv/<Name>_Event`` type, pairs the events of each call
(:class:`logic.Pairing`) and publishes one ``/imrosc/srvs`` record per call. The server and
client must have introspection enabled (``configure_introspection(clock, qos,
ServiceIntrospectionState.CONTENTS)``); without it no event topic appears and the calls are
not recorded (the node says so once).

The record topics are reliable and transient local (the last snapshot, the last calls), so
``ros2 bag record`` started later still gets the current snapshots. Python 3.8 syntax.
"""

from __future__ import annotations

import json
import signal
import sys
import threading
import time
from typing import Any, Dict, List, Optional, Set, Tuple

from .. import records
from ..monitor_ros2 import logic as graph
from ..monitor_ros2 import plumbing
from . import logic

try:  # only a ROS 2 system has these
    import rclpy  # type: ignore[import-not-found, unused-ignore]
    from rclpy.callback_groups import (  # type: ignore[import-not-found, unused-ignore]
        MutuallyExclusiveCallbackGroup,
        ReentrantCallbackGroup,
    )
    from rclpy.executors import (  # type: ignore[import-not-found, unused-ignore]
        MultiThreadedExecutor,
    )
    from rclpy.node import Node  # type: ignore[import-not-found, unused-ignore]
    from std_msgs.msg import String  # type: ignore[import-not-found, unused-ignore]
except ImportError:  # pragma: no cover - exercised on ROS 2 systems only
    rclpy = None

THREADS = 4
SNAPSHOT_DEPTH = 1
"""The record topics keep the last snapshot for late joiners (transient local)."""
CALL_DEPTH = 100
"""... and the last calls."""
EVENT_DEPTH = 100
ATTRIBUTE = 3.0
"""Seconds a paired call whose client or server the graph does not know yet waits for
discovery before it is recorded with ``/unknown``: DDS tells a node of the service's event
topic and of its request endpoints at different times, and on a loaded machine the first
calls came in a second before the endpoints that name their nodes."""
LINGER = 0.3
"""Seconds the node lives on after its last records (their reliable delivery)."""


def event_class_of(type_name: str) -> Any:
    """The message class of ``<pkg>/srv/<Name>_Event`` (``<Name>.Event``), or ``None``."""
    found = logic.event_service(type_name)
    if found is None:
        return None
    service_class = plumbing.interface_class(found[0].split(".")[0] + "/" + found[1], "srv")
    return getattr(service_class, "Event", None)


class Recorder:
    """The node's state: what it published last, the event subscriptions, waiting calls."""

    def __init__(self, node: Any, spec: Dict[str, Any]) -> None:
        self.node = node
        self.log = node.get_logger()
        log_warning = getattr(self.log, "warning", None) or self.log.warn  # Foxy: warn only
        self.warn = log_warning
        if spec.get("events"):  # imrosc record: the user sees them too

            def warn(text: str) -> None:
                log_warning(text)
                prefix = "imrosc recorder: "
                say(
                    {
                        "event": "warning",
                        "message": text[len(prefix) :] if text.startswith(prefix) else text,
                    }
                )

            self.warn = warn
        self.period = float(plumbing.get_param(node, "period", spec["period"]))
        self.name = graph.node_name(node.get_namespace(), node.get_name())
        self.services: List[str] = list(spec["services"])
        self.params: List[str] = list(spec["params"])
        self.lock = threading.Lock()
        self.changes = logic.Changes()
        self.pairing = logic.Pairing(
            settle=max(1.0, self.period),
            timeout=float(plumbing.get_param(node, "call_timeout", 10.0)),
        )
        self.answered_once = not self.params
        """Whether the parameters may be published: none to ask, or nothing pending."""
        self.events: Dict[str, Any] = {}
        self.writers: Dict[str, List[Tuple[bytes, str]]] = {}
        self.event_publishers: Dict[str, List[str]] = {}
        self.servers: Dict[str, List[str]] = {}
        self.told: Set[str] = set()
        self.started = time.monotonic()
        self.polls = MutuallyExclusiveCallbackGroup()
        self.calls = ReentrantCallbackGroup()
        self.parameters = plumbing.ParameterAsker(
            node, self.calls, self.lock, lambda text: self.warn("imrosc recorder: " + text)
        )
        snapshot = plumbing.profile(
            graph.Qos(graph.RELIABLE, graph.TRANSIENT_LOCAL), SNAPSHOT_DEPTH
        )
        calls = plumbing.profile(graph.Qos(graph.RELIABLE, graph.TRANSIENT_LOCAL), CALL_DEPTH)
        self.publishers = {
            records.ARCH_TOPIC: node.create_publisher(String, records.ARCH_TOPIC, snapshot),
            records.PARAMS_TOPIC: node.create_publisher(String, records.PARAMS_TOPIC, snapshot),
            records.SRVS_TOPIC: node.create_publisher(String, records.SRVS_TOPIC, calls),
        }
        self.published = dict.fromkeys(records.RECORD_TOPICS, 0)
        self.counts: Dict[str, int] = {}
        """Calls published, by service."""
        self.unattributed: List[Tuple[float, logic.Call]] = []
        """Paired calls waiting for the graph to name their client or server, with the
        monotonic time they were paired (:data:`ATTRIBUTE`)."""
        self.await_subscribers(float(spec.get("wait", 0.0)))
        self.tick()
        self.timer = node.create_timer(
            self.period, plumbing.guarded(self.log, "poll", self.tick), callback_group=self.polls
        )

    def await_subscribers(self, seconds: float) -> None:
        """Wait until every record topic has a subscriber (at most ``seconds``)."""
        end = time.monotonic() + seconds
        publishers = list(self.publishers.values())
        while time.monotonic() < end:
            if all(p.get_subscription_count() > 0 for p in publishers):
                return
            time.sleep(0.05)
        if seconds > 0:
            self.warn("imrosc recorder: the record topics have no subscriber yet")

    def publish(self, topic: str, text: str) -> None:
        message = String()
        message.data = text
        self.publishers[topic].publish(message)
        self.published[topic] += 1

    def tick(self) -> None:
        """The timer: the graph, the parameters, the event subscriptions, late calls."""
        try:
            view: Optional[graph.GraphView] = plumbing.read_graph(self.node)
        except Exception as error:
            self.warn(f"imrosc recorder: cannot read the graph: {error}")
            view = None
        if view is not None and view.complete:  # else a node is half discovered: wait
            topics, services = logic.arch_of(view, [self.name])
            text = records.arch_text(topics, services)
            if self.changes.changed(records.ARCH_TOPIC, text):
                self.publish(records.ARCH_TOPIC, text)
        with self.lock:
            known = self.answered_once or self.parameters.answered
            params = logic.params_of(self.parameters.answers, self.params) if known else None
        if params is not None:
            text = records.params_text(params)
            if self.changes.changed(records.PARAMS_TOPIC, text):
                self.publish(records.PARAMS_TOPIC, text)
        if view is not None:
            self.ask_params(view)
            self.connect(view)
        self.flush(self.pairing_due())

    def pairing_due(self) -> List[logic.Call]:
        with self.lock:
            return self.pairing.due(time.monotonic())

    def ask_params(self, view: graph.GraphView) -> None:
        """Ask each node for the scope's parameters (the answers are published at the next
        poll; with nothing to wait for, what is known is published)."""
        requests = graph.parameter_requests(self.params, view.nodes)
        for owner, asked in requests.items():
            if owner == self.name:
                continue
            if owner not in view.nodes:  # not running (yet): its parameters are not set
                self.parameters.forget(asked)
            else:
                self.parameters.ask(owner, asked)
        with self.lock:
            if not self.parameters.pending:
                self.answered_once = True

    def connect(self, view: graph.GraphView) -> None:
        """Subscribe to the event topic of each scope service once it has a type; note
        who writes its requests, publishes its events and serves it."""
        for service in self.services:
            topic = logic.event_topic(service)
            self.servers[service] = list(view.services.get(service, ()))
            self.event_publishers[service] = list(view.topics.get(topic, ((), ()))[0])
            self.read_writers(service)
            if service in self.events:
                continue
            kinds = [k for k in view.types.get(topic, ()) if logic.event_service(k)]
            if not kinds:
                waited = time.monotonic() - self.started
                if service not in self.told and waited > 5 * self.period + 2.0:
                    self.told.add(service)
                    self.warn(
                        f"imrosc recorder: no {topic} yet: calls of {service} are recorded "
                        "only when its server or clients enable service introspection "
                        "(ROS 2 Iron and later)"
                    )
                continue
            event_class = event_class_of(kinds[0])
            if event_class is None:
                if service not in self.told:
                    self.told.add(service)
                    self.warn(f"imrosc recorder: no class {kinds[0]} for {topic}: not recorded")
                continue
            self.events[service] = self.node.create_subscription(
                event_class,
                topic,
                plumbing.guarded(self.log, f"event of {service}", self.on_event_of(service)),
                plumbing.profile(graph.DEFAULT, EVENT_DEPTH),
                callback_group=self.calls,
            )
            self.log.info(f"imrosc recorder: recording calls of {service} from {topic}")

    def on_event_of(self, service: str) -> Any:
        def on_event(message: Any) -> None:
            event = logic.event_of(message)
            with self.lock:
                calls = self.pairing.add(service, event, time.monotonic())
            self.flush(calls)

        return on_event

    def read_writers(self, service: str) -> None:
        """Note who writes the requests of ``service`` (the graph as this node knows it now)."""
        try:
            writers = self.node.get_publishers_info_by_topic(
                logic.request_topic(service), no_mangle=True
            )
            self.writers[service] = [
                (
                    logic.gid_bytes(getattr(info, "endpoint_gid", b"")),
                    graph.node_name(info.node_namespace, info.node_name),
                )
                for info in writers
            ]
        except Exception:
            self.writers[service] = []

    def read_event_publishers(self, service: str) -> None:
        """Note who publishes the events of ``service`` (the graph as this node knows it)."""
        try:
            found = self.node.get_publishers_info_by_topic(
                logic.event_topic(service), no_mangle=True
            )
            self.event_publishers[service] = sorted(
                {graph.node_name(info.node_namespace, info.node_name) for info in found}
            )
        except Exception:
            pass

    def client_of(self, call: logic.Call) -> str:
        """The node that made ``call``; when the graph of the last poll does not know its
        request writer yet (a client newer than the poll), the graph is read again."""
        for attempt in range(2):
            if attempt:
                self.read_writers(call.service)
                self.read_event_publishers(call.service)
            client = logic.client_node(
                call.client_gid,
                self.writers.get(call.service, []),
                self.event_publishers.get(call.service, []),
                self.servers.get(call.service, []),
            )
            if client != logic.UNKNOWN_NODE:
                break
        return client

    def read_servers(self, service: str) -> None:
        """Note who serves ``service``: the readers of its requests (the graph as this node
        knows it now), when there are any."""
        try:
            readers = self.node.get_subscriptions_info_by_topic(
                logic.request_topic(service), no_mangle=True
            )
        except Exception:
            return
        found = sorted({graph.node_name(info.node_namespace, info.node_name) for info in readers})
        if found:
            self.servers[service] = found

    def server_of(self, call: logic.Call) -> str:
        """The node that served ``call``; when the last poll knew no server, the graph is
        read again."""
        server = logic.server_node(self.servers.get(call.service, []))
        if server == logic.UNKNOWN_NODE:
            self.read_servers(call.service)
            server = logic.server_node(self.servers.get(call.service, []))
        return server

    def flush(self, calls: List[logic.Call], final: bool = False) -> None:
        """Publish paired calls, first those that waited for their client or server. One
        whose client or server the graph does not know yet waits for the next flush, for
        :data:`ATTRIBUTE` seconds at most (``final``: not at all)."""
        now = time.monotonic()
        with self.lock:
            waiting = self.unattributed + [(now, call) for call in calls]
            self.unattributed = []
        for since, call in waiting:
            client = self.client_of(call)
            server = self.server_of(call)
            unknown = logic.UNKNOWN_NODE in (client, server)
            if unknown and not final and now - since < ATTRIBUTE:
                with self.lock:
                    self.unattributed.append((since, call))
                continue
            self.publish(records.SRVS_TOPIC, logic.call_record(call, client, server))
            self.counts[call.service] = self.counts.get(call.service, 0) + 1

    def close(self) -> None:
        """Publish the calls still waiting."""
        with self.lock:
            calls = self.pairing.drain(time.monotonic())
        self.flush(calls, final=True)


def init(args: Optional[List[str]] = None) -> None:
    """``rclpy.init`` without rclpy's signal handlers where it can (Humble and later): SIGINT
    and SIGTERM then end :func:`spin` with the context still valid, so that the last calls
    can still be published."""
    try:
        from rclpy.signals import (  # type: ignore[import-not-found, unused-ignore]
            SignalHandlerOptions,
        )
    except ImportError:  # Foxy, Galactic: rclpy's handlers shut the context down
        rclpy.init(args=args)
        return
    rclpy.init(args=args, signal_handler_options=SignalHandlerOptions.NO)


def spin(executor: Any, step: float = 0.1) -> None:
    """Spin ``executor`` until SIGINT or SIGTERM (or ROS shuts down)."""
    stop = threading.Event()

    def on_signal(number: int, frame: Any) -> None:
        stop.set()

    previous = {
        number: signal.signal(number, on_signal) for number in (signal.SIGINT, signal.SIGTERM)
    }
    try:
        while not stop.is_set() and rclpy.ok():
            executor.spin_once(timeout_sec=step)
    except plumbing.SPIN_ENDED:
        pass
    finally:
        for number, handler in previous.items():
            signal.signal(number, handler)


def main(package: str, args: Optional[List[str]] = None) -> None:
    """Run the recorder node of ``package`` (its ``recorder.json``) until SIGINT or SIGTERM."""
    if rclpy is None:
        sys.exit("imrosc recorder: rclpy is not importable; run it on a ROS 2 system")
    try:
        spec = logic.load_spec()
    except (OSError, ValueError) as error:
        sys.exit(f"imrosc recorder: {error}")
    init(args)
    serve(package + "_recorder", spec)


def serve(name: str, spec: Dict[str, Any]) -> None:
    """Run the recorder node ``name`` with ``spec`` (after :func:`init`) until SIGINT or
    SIGTERM, then publish the calls still waiting. With ``events`` in the spec it says on
    standard output, one JSON object a line, when it is ``ready`` and, at the end, what it
    published (``stats``); with ``wait`` it first waits (at most that many seconds) until
    each record topic has a subscriber, so that its first snapshots reach the bag
    (``imrosc record``)."""
    node = Node(
        name,
        allow_undeclared_parameters=True,
        automatically_declare_parameters_from_overrides=True,
    )
    events = bool(spec.get("events"))
    recorder = Recorder(node, spec)
    node.get_logger().info(
        f"imrosc recorder {recorder.name}: recording the graph, {len(recorder.params)} "
        f"parameters and the calls of {len(recorder.services)} services"
    )
    if events:
        say({"event": "ready"})
    executor = MultiThreadedExecutor(num_threads=THREADS)
    executor.add_node(node)
    try:
        spin(executor)
    finally:
        try:
            if rclpy.ok():
                recorder.close()
                time.sleep(LINGER)  # reliable delivery of the last records
        except Exception as error:
            node.get_logger().error(f"imrosc recorder: last calls: {error}")
        if events:
            say({"event": "stats", "published": recorder.published, "calls": recorder.counts})
        executor.shutdown()
        node.destroy_node()
        if rclpy.ok():
            rclpy.shutdown()


def say(event: Dict[str, Any]) -> None:
    """One event line on standard output (for ``imrosc record``)."""
    sys.stdout.write(json.dumps(event, sort_keys=True) + "\n")
    sys.stdout.flush()
