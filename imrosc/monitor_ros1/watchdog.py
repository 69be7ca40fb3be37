"""The fail-open watchdog of a monitor package (ROS 1, rospy).

By default a monitor fails closed: when it dies, the blocked topics' remapped subscribers
(``/m/<topic>``) and the relayed services' clients (``/m/<service>``) hear nothing. Launched
with ``fail_open:=true``, this node listens to the monitor's heartbeat (``/m/heartbeat``);
when it has been silent for ``~timeout`` seconds of wall time (default three periods, at
least one second), the watchdog relays every blocked topic to ``/m/<topic>`` unchecked and
serves every relayed service, forwarding calls; when the heartbeat comes back it stops (the
monitor registers its services again when it restarts, which replaces the watchdog's).

Parameters: ``~namespace``, ``~period``, ``~timeout``. Python 3.8 syntax.
"""

from __future__ import annotations

import sys
import threading
import time
from typing import Any, Callable, Dict, List, Mapping, Optional

from . import logic
from .node import load_spec, relay_name

try:  # only a ROS 1 robot has these
    import rosgraph  # type: ignore[import-not-found, unused-ignore]
    import roslib.message  # type: ignore[import-not-found, unused-ignore]
    import rospy  # type: ignore[import-not-found, unused-ignore]
    import rosservice  # type: ignore[import-not-found, unused-ignore]
    from std_msgs.msg import Time as TimeMsg  # type: ignore[import-not-found, unused-ignore]
except ImportError:  # pragma: no cover - exercised on robots only
    rospy = None


class Watchdog:
    """Relays blocked topics and services while the monitor's heartbeat is silent."""

    def __init__(self, spec: Mapping[str, Any]) -> None:
        self.spec = spec
        self.namespace: str = rospy.get_param("~namespace", spec["namespace"])
        period = float(rospy.get_param("~period", spec["period"]))
        self.timeout = float(rospy.get_param("~timeout", max(3.0 * period, 1.0)))
        self.master = rosgraph.Master(rospy.get_name())
        self.last_beat = time.monotonic()  # a grace period for the monitor to start
        self.relaying = False
        self.endpoints: List[Any] = []
        self.lock = threading.Lock()
        rospy.Subscriber(self.namespace + "/heartbeat", TimeMsg, self.on_beat, queue_size=1)
        threading.Thread(target=self.watch, name="imrosc-watchdog", daemon=True).start()

    def on_beat(self, message: Any) -> None:
        """The monitor is alive."""
        del message
        self.last_beat = time.monotonic()

    def watch(self) -> None:
        """Check the heartbeat four times per timeout; start or stop relaying."""
        while not rospy.is_shutdown():
            wanted = logic.should_relay(self.last_beat, time.monotonic(), self.timeout)
            with self.lock:
                if wanted and not self.relaying:
                    rospy.logwarn("imrosc watchdog: the monitor is silent; failing open")
                    self.start()
                elif not wanted and self.relaying:
                    rospy.logwarn("imrosc watchdog: the monitor is back; relaying stops")
                    self.stop()
            time.sleep(self.timeout / 4.0)

    def topic_class(self, msgtype: Optional[str], topic: str) -> Any:
        if not msgtype:
            try:
                msgtype = dict(self.master.getTopicTypes()).get(topic)
            except Exception:
                return None
        return roslib.message.get_message_class(msgtype) if msgtype else None

    def start(self) -> None:
        """Relay every blocked topic and serve every relayed service."""
        self.relaying = True
        ns = self.namespace
        for topic in self.spec["topics"]:
            if not topic.get("relay"):
                continue
            found = self.topic_class(topic.get("type"), topic["name"])
            if found is None:
                rospy.logerr(f"imrosc watchdog: cannot relay {topic['name']}: type unknown")
                continue
            publisher = rospy.Publisher(relay_name(ns, topic["name"]), found, queue_size=100)
            subscriber = rospy.Subscriber(topic["name"], found, publisher.publish, queue_size=100)
            self.endpoints += [subscriber, publisher]
        for service in self.spec["services"]:
            try:
                found = rosservice.get_service_class_by_name(service["name"])
            except Exception:
                rospy.logerr(f"imrosc watchdog: cannot relay {service['name']}: not served")
                continue
            forward = self.forward(service["name"], found)
            self.endpoints.append(rospy.Service(relay_name(ns, service["name"]), found, forward))

    @staticmethod
    def forward(name: str, service_class: Any) -> Callable[[Any], Any]:
        def serve(request: Any) -> Any:
            return rospy.ServiceProxy(name, service_class)(request)

        return serve

    def stop(self) -> None:
        """Stop relaying: the monitor is back."""
        self.relaying = False
        for endpoint in self.endpoints:
            if hasattr(endpoint, "unregister"):
                endpoint.unregister()
            else:
                endpoint.shutdown()
        self.endpoints = []


def main(package: str) -> None:
    """Run the fail-open watchdog of ``package`` until ROS shuts down."""
    if rospy is None:
        sys.exit("imrosc watchdog: rospy is not importable; run it on a ROS 1 system")
    rospy.init_node(package + "_watchdog")
    spec: Dict[str, Any] = load_spec()
    Watchdog(spec)
    rospy.spin()
