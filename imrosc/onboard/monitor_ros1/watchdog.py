"""The fail-open watchdog of a monitor package (ROS 1, rospy).

By default a monitor fails closed: when it dies, the blocked topics' remapped subscribers
(``/m/<topic>``) and the relayed services' clients (``/m/<service>``) hear nothing. Launched
with ``fail_open:=true``, this node listens to the monitor's heartbeat (``/m/heartbeat``);
when it has been silent for ``~timeout`` seconds of wall time (default three periods, at
least one second), the watchdog relays every blocked topic to ``/m/<topic>`` unchecked and
serves every relayed service, forwarding calls; when the heartbeat comes back it stops (the
monitor registers its services again when it restarts, which replaces the watchdog's). A
topic whose type the master does not know yet and a service not registered yet are looked
for again at every check of the heartbeat while failing open, and relayed once found.

Parameters: ``~namespace``, ``~period``, ``~timeout``, ``~startup`` (seconds to wait for the
monitor's first beat: ``~timeout``, at least five). Python 3.8 syntax.
"""

from __future__ import annotations

import sys
import threading
import time
from typing import Any, Callable, List, Mapping, Optional, Set

from .. import files
from .. import monitor as common

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

    def __init__(self, spec: files.SpecDocument) -> None:
        self.spec = spec
        self.namespace: str = rospy.get_param("~namespace", spec["namespace"])
        period = float(rospy.get_param("~period", spec["period"]))
        self.timeout = float(rospy.get_param("~timeout", max(3.0 * period, 1.0)))
        self.master = rosgraph.Master(rospy.get_name())
        self.startup = float(rospy.get_param("~startup", max(self.timeout, common.STARTUP)))
        self.started = time.monotonic()
        self.last_beat: Optional[float] = None  # no beat yet: ``startup`` applies
        self.relaying = False
        self.endpoints: List[Any] = []
        self.pending_topics: List[Mapping[str, Any]] = []  # blocked topics of unknown type
        self.pending_services: List[str] = []  # relayed services not registered yet
        self.reported: Set[str] = set()
        self.lock = threading.Lock()
        rospy.Subscriber(self.namespace + "/heartbeat", TimeMsg, self.on_beat, queue_size=1)
        threading.Thread(target=self.watch, name="imrosc-watchdog", daemon=True).start()

    def on_beat(self, message: Any) -> None:
        """The monitor is alive."""
        del message
        self.last_beat = time.monotonic()

    def watch(self) -> None:
        """Check the heartbeat four times per timeout; start or stop relaying; while
        relaying, relay what was not found yet."""
        while not rospy.is_shutdown():
            wanted = common.should_relay(
                self.last_beat, time.monotonic(), self.timeout, self.started, self.startup
            )
            with self.lock:
                try:
                    if wanted and not self.relaying:
                        rospy.logwarn("imrosc watchdog: the monitor is silent; failing open")
                        self.start()
                    elif wanted:
                        self.resolve()
                    elif self.relaying:
                        rospy.logwarn("imrosc watchdog: the monitor is back; relaying stops")
                        self.stop()
                except Exception as error:
                    rospy.logerr(f"imrosc watchdog: {error}")
            time.sleep(self.timeout / 4.0)

    def topic_class(self, msgtype: Optional[str], topic: str) -> Any:
        if not msgtype:
            try:
                msgtype = dict(self.master.getTopicTypes()).get(topic)
            except Exception:
                return None
        return roslib.message.get_message_class(msgtype) if msgtype else None

    def start(self) -> None:
        """Relay every blocked topic and serve every relayed service (those not found yet
        at the next ticks)."""
        self.relaying = True
        self.pending_topics = [t for t in self.spec["topics"] if t.get("relay")]
        self.pending_services = [s["name"] for s in self.spec["services"]]
        self.reported = set()
        self.resolve()

    def resolve(self) -> None:
        """Relay the blocked topics and services found now; log the others once."""
        self.pending_topics = [t for t in self.pending_topics if not self.relay_topic(t)]
        self.pending_services = [s for s in self.pending_services if not self.serve(s)]

    def relay_topic(self, topic: Mapping[str, Any]) -> bool:
        """Relay one blocked topic if its type is known; whether it is relayed."""
        found = self.topic_class(topic.get("type"), topic["name"])
        if found is None:
            self.not_yet(topic["name"], "type unknown")
            return False
        ns = self.namespace
        publisher = rospy.Publisher(common.relay_name(ns, topic["name"]), found, queue_size=100)
        subscriber = rospy.Subscriber(topic["name"], found, publisher.publish, queue_size=100)
        self.endpoints += [subscriber, publisher]
        return True

    def serve(self, name: str) -> bool:
        """Serve ``/m/<name>`` if ``name`` is registered; whether it is."""
        try:
            found = rosservice.get_service_class_by_name(name)
        except Exception:
            self.not_yet(name, "not served")
            return False
        forward = self.forward(name, found)
        self.endpoints.append(
            rospy.Service(common.relay_name(self.namespace, name), found, forward)
        )
        if name in self.reported:
            rospy.logwarn(f"imrosc watchdog: relaying {name} now")
        return True

    def not_yet(self, name: str, why: str) -> None:
        """Log once per failing open that ``name`` cannot be relayed yet."""
        if name not in self.reported:
            self.reported.add(name)
            rospy.logwarn(f"imrosc watchdog: cannot relay {name} yet: {why}; trying again")

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
        self.pending_topics = []
        self.pending_services = []


def main(package: str) -> None:
    """Run the fail-open watchdog of ``package`` until ROS shuts down."""
    if rospy is None:
        sys.exit("imrosc watchdog: rospy is not importable; run it on a ROS 1 system")
    rospy.init_node(package + "_watchdog")
    Watchdog(files.load_monitor_spec())
    rospy.spin()
