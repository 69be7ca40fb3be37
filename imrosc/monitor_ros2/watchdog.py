"""The fail-open watchdog of a ROS 2 monitor package (rclpy).

By default a monitor fails closed: when it dies, the blocked topics' remapped subscribers
(``/m/<topic>``) and the relayed services' clients (``/m/<service>``) hear nothing. Launched
with ``fail_open:=true``, this node listens to the monitor's heartbeat (``/m/heartbeat``);
when it has been silent for ``timeout`` seconds of wall time (default three periods, at
least one second), the watchdog relays every blocked topic to ``/m/<topic>`` unchecked
(with the QoS its publishers offer) and serves every relayed service, forwarding calls;
when the heartbeat comes back it stops and destroys its relays and services.

Parameters: ``namespace``, ``period``, ``timeout``, ``service_timeout``. Python 3.8 syntax.
"""

from __future__ import annotations

import sys
import threading
import time
from typing import Any, Callable, Dict, List, Mapping, Optional, Tuple

from ..monitor_ros1 import logic as common
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


class Watchdog:
    """Relays blocked topics and services while the monitor's heartbeat is silent."""

    def __init__(self, node: Any, spec: Mapping[str, Any]) -> None:
        self.node = node
        self.log = node.get_logger()
        self.warn = getattr(self.log, "warning", None) or self.log.warn  # Foxy has warn only
        self.spec = spec
        self.namespace = str(plumbing.get_param(node, "namespace", spec["namespace"]))
        period = float(plumbing.get_param(node, "period", spec["period"]))
        self.timeout = float(plumbing.get_param(node, "timeout", max(3.0 * period, 1.0)))
        self.call_timeout = float(plumbing.get_param(node, "service_timeout", 10.0))
        self.name = logic.node_name(node.get_namespace(), node.get_name())
        self.last_beat = time.monotonic()  # a grace period for the monitor to start
        self.relaying = False
        self.endpoints: List[Tuple[str, Any]] = []
        self.lock = threading.Lock()
        self.calls = ReentrantCallbackGroup()
        node.create_subscription(TimeMsg, self.namespace + "/heartbeat", self.on_beat, 1)
        threading.Thread(target=self.watch, name="imrosc-watchdog", daemon=True).start()

    def on_beat(self, message: Any) -> None:
        """The monitor is alive."""
        del message
        self.last_beat = time.monotonic()

    def watch(self) -> None:
        """Check the heartbeat four times per timeout; start or stop relaying."""
        while rclpy.ok():
            wanted = common.should_relay(self.last_beat, time.monotonic(), self.timeout)
            with self.lock:
                try:
                    if wanted and not self.relaying:
                        self.warn("imrosc watchdog: the monitor is silent; failing open")
                        self.start()
                    elif not wanted and self.relaying:
                        self.warn("imrosc watchdog: the monitor is back; relaying stops")
                        self.stop()
                except Exception as error:
                    self.log.error(f"imrosc watchdog: {error}")
            time.sleep(self.timeout / 4.0)

    def start(self) -> None:
        """Relay every blocked topic and serve every relayed service."""
        self.relaying = True
        ns = self.namespace
        view = plumbing.read_graph(self.node)
        own = {self.name}
        for topic in self.spec["topics"]:
            if not topic.get("relay"):
                continue
            name = topic["name"]
            kinds = view.types.get(name) or ()
            msgtype: Optional[str] = topic.get("ros2_type") or (kinds[0] if kinds else None)
            found = plumbing.message_class(msgtype) if msgtype else None
            if found is None:
                self.log.error(f"imrosc watchdog: cannot relay {name}: type unknown")
                continue
            publishers = logic.publisher_qos(view, name, own)
            publisher = self.node.create_publisher(
                found,
                logic.relay_name(ns, name),
                plumbing.profile(logic.relay_qos(publishers, msgtype)),
            )
            subscription = self.node.create_subscription(
                found,
                name,
                publisher.publish,
                plumbing.profile(logic.subscription_qos(publishers, msgtype)),
            )
            self.endpoints += [("subscription", subscription), ("publisher", publisher)]
        for service in self.spec["services"]:
            name = service["name"]
            kinds = view.service_types.get(name) or ()
            found = plumbing.service_class(kinds[0]) if kinds else None
            if found is None:
                self.log.error(f"imrosc watchdog: cannot relay {name}: not served")
                continue
            client = self.node.create_client(found, name, callback_group=self.calls)
            server = self.node.create_service(
                found, logic.relay_name(ns, name), self.forward(client), callback_group=self.calls
            )
            self.endpoints += [("service", server), ("client", client)]

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
        for kind, endpoint in self.endpoints:
            destroy[kind](endpoint)
        self.endpoints = []


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
    Watchdog(node, logic.load_spec())
    executor = MultiThreadedExecutor(num_threads=THREADS)
    executor.add_node(node)
    try:
        executor.spin()
    except KeyboardInterrupt:
        pass
    finally:
        executor.shutdown()
        node.destroy_node()
        if rclpy.ok():
            rclpy.shutdown()
