"""The fail-open watchdog of a ROS 2 monitor package (rclpy).

By default a monitor fails closed: when it dies, the blocked topics' remapped subscribers
(``/m/<topic>``) and the relayed services' clients (``/m/<service>``) hear nothing. Launched
with ``fail_open:=true``, this node listens to the monitor's heartbeat (``/m/heartbeat``);
when it has been silent for ``timeout`` seconds of wall time (default three periods, at
least one second), the watchdog relays every blocked topic to ``/m/<topic>`` unchecked
(with the QoS its publishers offer) and serves every relayed service, forwarding calls;
when the heartbeat comes back it stops and destroys its relays and services. Discovery
takes its time: a topic whose publishers are not discovered yet and a service not served
yet are looked for again at every check of the heartbeat while failing open, and relayed
as soon as they are found (a relay follows its publishers' QoS as they come and go).

Parameters: ``namespace``, ``period``, ``timeout``, ``startup`` (seconds to wait for the
monitor's first beat: ``timeout``, at least five), ``service_timeout``. Python 3.8 syntax.
"""

from __future__ import annotations

import sys
import threading
import time
from typing import Any, Callable, Dict, List, Mapping, Optional, Set, Tuple

from .. import files
from .. import monitor as common
from . import logic, plumbing

try:  # only a ROS 2 system has these
    import rclpy  # type: ignore[import-not-found, unused-ignore]
    from builtin_interfaces.msg import (  # type: ignore[import-not-found, unused-ignore]
        Time as TimeMsg,
    )
    from rclpy.callback_groups import (  # type: ignore[import-not-found, unused-ignore]
        ReentrantCallbackGroup,
    )
    from rclpy.executors import (  # type: ignore[import-not-found, unused-ignore]
        MultiThreadedExecutor,
    )
    from rclpy.node import Node  # type: ignore[import-not-found, unused-ignore]
except ImportError:  # pragma: no cover - exercised on ROS 2 systems only
    rclpy = None

THREADS = 4


class Relay:
    """One blocked topic relayed while failing open: its type, the QoS it hears its
    publishers with and the QoS it offers on ``/m/<topic>``."""

    def __init__(self, topic: Mapping[str, Any]) -> None:
        self.name: str = topic["name"]
        self.msgtype: Optional[str] = topic.get("ros2_type")
        self.message_class: Any = None
        self.qos: Optional[logic.Qos] = None
        self.offer: Optional[logic.Qos] = None
        self.subscription: Any = None
        self.publisher: Any = None

    def forward(self, message: Any) -> None:
        """Relay one message unchecked."""
        publisher = self.publisher
        if publisher is not None:
            publisher.publish(message)


class Watchdog:
    """Relays blocked topics and services while the monitor's heartbeat is silent."""

    def __init__(self, node: Any, spec: files.SpecDocument) -> None:
        self.node = node
        self.log = node.get_logger()
        self.warn = getattr(self.log, "warning", None) or self.log.warn  # Foxy has warn only
        self.spec = spec
        self.namespace = str(plumbing.get_param(node, "namespace", spec["namespace"]))
        period = float(plumbing.get_param(node, "period", spec["period"]))
        self.timeout = float(plumbing.get_param(node, "timeout", max(3.0 * period, 1.0)))
        self.call_timeout = float(plumbing.get_param(node, "service_timeout", 10.0))
        self.name = logic.node_name(node.get_namespace(), node.get_name())
        self.startup = float(plumbing.get_param(node, "startup", max(self.timeout, common.STARTUP)))
        self.started = time.monotonic()
        self.last_beat: Optional[float] = None  # no beat yet: ``startup`` applies
        self.relaying = False
        self.endpoints: List[Tuple[str, Any]] = []
        self.topics: Dict[str, Relay] = {}
        self.pending: List[str] = []  # relayed services not served yet
        self.reported: Set[str] = set()
        self.lock = threading.Lock()
        self.calls = ReentrantCallbackGroup()
        node.create_subscription(TimeMsg, self.namespace + "/heartbeat", self.on_beat, 1)
        threading.Thread(target=self.watch, name="imrosc-watchdog", daemon=True).start()

    def on_beat(self, message: Any) -> None:
        """The monitor is alive."""
        del message
        self.last_beat = time.monotonic()

    def watch(self) -> None:
        """Check the heartbeat four times per timeout; start or stop relaying; while
        relaying, relay what was not discovered yet and follow the publishers' QoS."""
        while rclpy.ok():
            wanted = common.should_relay(
                self.last_beat, time.monotonic(), self.timeout, self.started, self.startup
            )
            with self.lock:
                try:
                    if wanted and not self.relaying:
                        self.warn("imrosc watchdog: the monitor is silent; failing open")
                        self.start()
                    elif wanted:
                        self.resolve()
                    elif self.relaying:
                        self.warn("imrosc watchdog: the monitor is back; relaying stops")
                        self.stop()
                except Exception as error:
                    self.log.error(f"imrosc watchdog: {error}")
            time.sleep(self.timeout / 4.0)

    def start(self) -> None:
        """Relay every blocked topic and serve every relayed service (those not discovered
        yet at the next ticks)."""
        self.relaying = True
        self.topics = {
            topic["name"]: Relay(topic) for topic in self.spec["topics"] if topic.get("relay")
        }
        self.pending = [service["name"] for service in self.spec["services"]]
        self.reported = set()
        self.resolve()

    def resolve(self) -> None:
        """One look at the graph: (re)create the topic relays whose publishers were found or
        changed their QoS, serve the relayed services now served. A name not discovered yet
        is logged once and tried again at the next tick."""
        if not self.topics and not self.pending:
            return
        view = plumbing.read_graph(self.node)
        for relay in self.topics.values():
            self.relay_topic(view, relay)
        self.pending = [name for name in self.pending if not self.serve_service(view, name)]

    def relay_topic(self, view: logic.GraphView, relay: Relay) -> None:
        """Create or update the relay of one blocked topic."""
        name = relay.name
        if relay.message_class is None:
            kinds = view.types.get(name) or ()
            relay.msgtype = relay.msgtype or (kinds[0] if kinds else None)
            found = plumbing.message_class(relay.msgtype) if relay.msgtype else None
            if found is None:
                self.not_yet(name, "type unknown")
                return
            relay.message_class = found
        publishers = logic.publisher_qos(view, name, {self.name})
        if relay.subscription is None and not any(q is not None for q in publishers):
            self.not_yet(name, "no publisher yet")  # a late best-effort one would not match
            return
        offer = logic.qos_update(relay.offer, publishers, relay.msgtype, logic.relay_qos)
        if offer is not None:
            if relay.publisher is not None:
                self.node.destroy_publisher(relay.publisher)
            relay.offer = offer
            relay.publisher = self.node.create_publisher(
                relay.message_class,
                common.relay_name(self.namespace, name),
                plumbing.profile(offer, plumbing.TOPIC_DEPTH),
            )
        wanted = logic.qos_update(relay.qos, publishers, relay.msgtype)
        if wanted is not None:
            if relay.subscription is not None:
                self.node.destroy_subscription(relay.subscription)
            relay.qos = wanted
            relay.subscription = self.node.create_subscription(
                relay.message_class,
                name,
                relay.forward,
                plumbing.profile(wanted, plumbing.TOPIC_DEPTH),
            )

    def serve_service(self, view: logic.GraphView, name: str) -> bool:
        """Serve ``/m/<name>`` if ``name`` is served now; whether it is."""
        kinds = view.service_types.get(name) or ()
        found = plumbing.service_class(kinds[0]) if kinds else None
        if found is None:
            self.not_yet(name, "not served")
            return False
        client = self.node.create_client(found, name, callback_group=self.calls)
        server = self.node.create_service(
            found,
            common.relay_name(self.namespace, name),
            self.forward(client),
            callback_group=self.calls,
        )
        self.endpoints += [("service", server), ("client", client)]
        if name in self.reported:
            self.warn(f"imrosc watchdog: relaying {name} now")
        return True

    def not_yet(self, name: str, why: str) -> None:
        """Log once per failing open that ``name`` cannot be relayed yet."""
        if name not in self.reported:
            self.reported.add(name)
            self.warn(f"imrosc watchdog: cannot relay {name} yet: {why}; trying again")

    def forward(self, client: Any) -> Callable[[Any, Any], Any]:
        """A service callback that forwards the request (the default response when the
        service does not answer)."""

        def serve(request: Any, response: Any) -> Any:
            try:
                return plumbing.call(client, request, self.call_timeout)
            except Exception as error:
                self.log.error(f"imrosc watchdog: forwarding failed: {error}")
                return response

        return serve

    def stop(self) -> None:
        """Stop relaying: the monitor is back."""
        self.relaying = False
        destroy: Dict[str, Callable[[Any], Any]] = {
            "subscription": self.node.destroy_subscription,
            "publisher": self.node.destroy_publisher,
            "service": self.node.destroy_service,
            "client": self.node.destroy_client,
        }
        for relay in self.topics.values():
            if relay.subscription is not None:
                self.endpoints.append(("subscription", relay.subscription))
            if relay.publisher is not None:
                self.endpoints.append(("publisher", relay.publisher))
        for kind, endpoint in self.endpoints:
            destroy[kind](endpoint)
        self.endpoints = []
        self.topics = {}
        self.pending = []


def main(package: str, args: Optional[List[str]] = None) -> None:
    """Run the fail-open watchdog of ``package`` until ROS shuts down."""
    if rclpy is None:
        sys.exit("imrosc watchdog: rclpy is not importable; run it on a ROS 2 system")
    rclpy.init(args=args)
    node = Node(
        package + "_watchdog",
        allow_undeclared_parameters=True,
        automatically_declare_parameters_from_overrides=True,
    )
    Watchdog(node, files.load_monitor_spec())
    executor = MultiThreadedExecutor(num_threads=THREADS)
    executor.add_node(node)
    plumbing.spin_until_stopped(executor, node)
