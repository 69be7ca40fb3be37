"""The monitor node for ROS 1 (rospy): thin plumbing around the runtime engine.

A generated monitor package runs :func:`main` with its runtime engine class and its
generated flatteners. The node

* runs the engine under the invariants file's alarm rule, overridden by the ``<monitor>``'s
  ``alarm_*`` attributes (``spec.json``'s ``alarms``); after each call it takes the alarms
  raised and the violations that belong to an alarm;
* subscribes to every topic of the invariants file with the real message class, flattens
  each message and feeds it to the engine; a blocked topic's message is republished on
  ``/m/<topic>`` unless one of its violations belongs to an alarm (the rewritten launch file
  remaps the topic's subscribers there); a message's publisher is its connection's
  ``callerid``, and one the architecture does not know breaks ``max_pubs`` and nothing else
  (``Engine.intruder``), so its messages are withheld and the known publishers' relayed;
* serves ``/m/<service>`` for every watched or blocked service, forwards the call to the real
  service and feeds the call to the engine; for a blocked service it refuses a request that
  breaks an invariant of the request in alarm before forwarding it and withholds a response
  that breaks one after;
* every ``~period`` seconds advances the engine's clock, polls the master
  (``getSystemState``) into ``engine.graph`` and the parameters the invariants read into
  ``engine.params`` (each only when they changed), and retries what could not be set up yet
  (a topic whose type only the master knows, a service not yet served);
* publishes every violation as JSON on ``/m/broken_inv`` (with ``alarm``: whether it belongs
  to an alarm, and ``rule``: the rule of the alarm it raised), and on each newly raised alarm
  takes the actions that the violation map names for its point (in a worker thread, so
  checking never waits for a service) and unregisters unknown publishers that broke a
  ``max_pubs`` invariant from the master (``~unregister``); it clears an invariant named on
  ``/m/clear_inv``, and beats on ``/m/heartbeat`` for the fail-open watchdog.

Parameters: ``~invariants`` (path; default the package's ``config/invariants.json``),
``~period`` (seconds), ``~namespace`` (``/m``), ``~unregister`` (true), ``~watchdog`` (the
watchdog's node name, left out of the graph like the monitor itself).

Every decision is a function of ``common.py``; this module only talks to ROS. Python 3.8
syntax: it runs on ROS Noetic robots.
"""

from __future__ import annotations

import os
import queue
import struct
import sys
import threading
import time
import traceback
import xmlrpc.client
from typing import Any, Callable, Dict, List, Mapping, Optional, Sequence, Set, Tuple

import numpy as np

from .. import files
from .. import monitor as common
from ..service_pool import ServicePool
from . import messages, wire

try:  # only a ROS 1 robot has these; the helpers above are usable without them
    import rosgraph  # type: ignore[import-not-found, unused-ignore]
    import roslib.message  # type: ignore[import-not-found, unused-ignore]
    import rospy  # type: ignore[import-not-found, unused-ignore]
    import rosservice  # type: ignore[import-not-found, unused-ignore]
    from std_msgs.msg import String  # type: ignore[import-not-found, unused-ignore]
    from std_msgs.msg import Time as TimeMsg  # type: ignore[import-not-found, unused-ignore]
except ImportError:  # pragma: no cover - exercised on robots only
    rospy = None

QUEUE = 100
Flatten = Callable[[Any], List[Any]]


def default_invariants(package: str) -> str:
    """The package's ``config/invariants.json``: through rospkg, else beside the scripts."""
    try:
        import rospkg  # type: ignore[import-not-found, unused-ignore]

        return os.path.join(rospkg.RosPack().get_path(package), "config", "invariants.json")
    except Exception:
        scripts = os.path.dirname(files.package_folder())  # the package's scripts/
        return os.path.normpath(os.path.join(scripts, "..", "config", "invariants.json"))


class Monitor(common.Checking):
    """The node's state: the engine and what the spec says (:class:`common.Checking`), its
    ROS endpoints and what it learnt from the master."""

    def __init__(
        self,
        spec: files.SpecDocument,
        document: Mapping[str, Any],
        engine_class: Callable[..., Any],
        flatteners: Mapping[str, Flatten],
    ) -> None:
        namespace = str(rospy.get_param("~namespace", spec["namespace"]))
        super().__init__(spec, document, engine_class, namespace, self.stop)
        self.period = float(rospy.get_param("~period", spec["period"]))
        self.wall_clock = not rospy.get_param("/use_sim_time", False)
        """rospy's clock is the wall clock (read directly on the relay's path: warm, 0.06 us
        against 1.6 us for ``rospy.get_time``, which builds a ``Time`` each call)."""
        self.warm = max(0.0, float(rospy.get_param("~warm", common.WARM)))
        self.unregister = bool(rospy.get_param("~unregister", True))
        self.stand_ins = common.learnt_publishers(document.get("invariants", ()))
        """Per topic its learnt publishers, for whom ``rosbag play`` stands in."""
        self.name: str = rospy.get_name()
        watchdog = str(rospy.get_param("~watchdog", spec["watchdog"]))
        if not watchdog.startswith("/"):
            watchdog = rospy.get_namespace() + watchdog
        self.own: Set[str] = {self.name, watchdog}
        ns = self.namespace
        self.flatteners = flatteners
        self.layouts: Mapping[str, Sequence[Mapping[str, Any]]] = {
            name: info.get("variables", []) for name, info in document.get("topics", {}).items()
        }
        self.readers: Dict[str, Tuple[wire.Reader, Any]] = {}
        """Blocked topics relayed as bytes: their reader and their decoded class."""
        self.by_id = {inv["id"]: inv for inv in document["invariants"]}
        self.state: Sequence[Any] = ([], [], [])
        self.master = rosgraph.Master(self.name)
        self.master_api: Any = xmlrpc.client.ServerProxy(rosgraph.get_master_uri())
        self.broken = rospy.Publisher(ns + "/broken_inv", String, queue_size=QUEUE)
        self.beat = rospy.Publisher(ns + "/heartbeat", TimeMsg, queue_size=1)
        self.pending_topics = {t["name"]: t for t in spec["topics"]}
        self.pending_services = set(self.service_relays)
        self.pending_actions = set(self.actions)
        self.subscribers: Dict[str, Any] = {}
        self.relays: Dict[str, Any] = {}
        self.servers: Dict[str, Any] = {}
        self.action_out: Dict[str, Tuple[Any, Any]] = {}
        self.work = queue.Queue()  # type: queue.Queue[Tuple[Any, ...]]
        rospy.Subscriber(ns + "/clear_inv", String, self.on_clear, queue_size=QUEUE)
        threading.Thread(target=self.worker, name="imrosc-actions", daemon=True).start()
        threading.Thread(target=self.heartbeat, name="imrosc-heartbeat", daemon=True).start()
        if self.warm and self.topic_relays:
            running = lambda: not rospy.is_shutdown()  # noqa: E731 - rospy's, as rclpy.ok
            threading.Thread(
                target=self.keep_warm, args=(self.warm, running), name="imrosc-warm", daemon=True
            ).start()
        self.connect()
        self.tick(None)
        self.timer = rospy.Timer(rospy.Duration(self.period), self.tick)

    def stop(self, where: str, error: BaseException) -> None:
        """A check raised: report it on ``/m/broken_inv`` and in the log, stop the heartbeat
        and shut the node down (the guard already keeps every callback from checking or
        relaying)."""
        text = common.failure_text(where, error)
        rospy.logfatal(f"{text}\n{traceback.format_exc()}")
        try:
            self.broken.publish(String(data=common.failure_json(where, error, time.time())))
        except Exception as failed:  # the report is best effort; the shutdown is not
            rospy.logerr(f"imrosc: cannot publish the failure: {failed}")
        # let the report reach its subscribers before the node's connections close
        threading.Timer(0.5, rospy.signal_shutdown, args=(text,)).start()

    # -- setting up -------------------------------------------------------------------------

    def topic_class(self, msgtype: Optional[str], topic: str) -> Any:
        """The message class of a topic: by its type name, else by what the master says."""
        if not msgtype:
            try:
                known = dict(self.master.getTopicTypes())
            except Exception:
                return None
            msgtype = known.get(topic)
            if not msgtype:
                return None
        found = roslib.message.get_message_class(msgtype)
        if found is None:
            rospy.logerr_throttle(60.0, f"imrosc: no message class {msgtype} for {topic}")
        return found

    def service_class(self, service: str) -> Any:
        """The service class of a running service (``None`` until it is served)."""
        try:
            return rosservice.get_service_class_by_name(service)
        except Exception:
            return None

    def connect(self) -> None:
        """Set up what can be set up now: subscriptions, relays, served services, action
        publishers (types the master alone knows, services not served yet wait)."""
        for name, topic in sorted(self.pending_topics.items()):
            found = self.topic_class(topic.get("type"), name)
            if found is None:
                continue
            relay = self.topic_relays.get(name)
            subscribed = found
            if relay is not None:
                self.relays[name] = rospy.Publisher(relay, found, queue_size=QUEUE)
                read = (
                    wire.reader(found, self.layouts.get(name, ()), roslib.message.get_message_class)
                    if name in self.flatteners
                    else None
                )
                if read is not None:  # relayed as the bytes it came in (wire.py)
                    self.readers[name] = (read, found)
                    subscribed = wire.raw_class(found)
            self.subscribers[name] = rospy.Subscriber(
                name,
                subscribed,
                self.on_message,
                callback_args=name,
                queue_size=QUEUE,
                # a relay adds no Nagle delay of its own: without it, a burst from the
                # publisher waits for the delayed acknowledgement (40 ms on Linux)
                tcp_nodelay=relay is not None,
            )
            del self.pending_topics[name]
        for name in sorted(self.pending_services):
            found = self.service_class(name)
            if found is None:
                continue
            handler = self.handler(name, found)
            self.servers[name] = rospy.Service(self.service_relays[name], found, handler)
            self.pending_services.discard(name)
        for ident in sorted(self.pending_actions):
            action = self.actions[ident]
            if action["target"] != "topic":
                self.pending_actions.discard(ident)
                continue
            found = self.topic_class(action.get("type"), action["name"])
            if found is None:
                continue
            self.pending_actions.discard(ident)
            try:
                message = messages.fill(found(), action["value"], self.message_class)
            except (messages.FillError, TypeError, ValueError) as error:
                rospy.logerr(f"imrosc: action {ident} is disabled: {error}")
                continue
            publisher = rospy.Publisher(action["destination"], found, queue_size=QUEUE)
            self.action_out[ident] = (publisher, message)

    def message_class(self, msgtype: str) -> Any:
        """A message class by name (for lists of messages in action values)."""
        found = roslib.message.get_message_class(msgtype)
        if found is None:
            raise messages.FillError(f"unknown message type {msgtype}")
        return found

    # -- what happens -----------------------------------------------------------------------

    def on_message(self, message: Any, topic: str) -> None:
        """A message on a watched or blocked topic: check it, relay it if blocked and clean."""
        self.guard.run(f"message on {topic}", self.check_message, message, topic)

    def check_message(self, message: Any, topic: str) -> None:
        """:meth:`on_message` under the guard."""
        raw = self.readers.get(topic)
        if raw is not None:
            values = self.read(message, topic, raw)
            if values is None:
                return
        else:
            flatten = self.flatteners.get(topic)
            values = flatten(message) if flatten is not None else None
        publisher = self.publisher(message)
        with self.lock:
            now = time.time() if self.wall_clock else rospy.get_time()
            found, caused, raised, alarmed = self.check_values(topic, now, values, publisher)
        relay = self.relays.get(topic)
        if relay is not None:
            self.last_relayed = time.time()
            if not common.withheld(caused, alarmed):
                relay.publish(message)
            else:
                rospy.logwarn_throttle(1.0, common.blocked_line(topic, caused, alarmed))
        self.report(found + caused, raised, alarmed)

    def publisher(self, message: Any) -> Optional[str]:
        """The node that sent ``message`` (the ``callerid`` of the connection rospy received
        it on); ``None`` for the monitor's own messages (an action published on a watched
        topic) or when rospy does not say."""
        header = getattr(message, "_connection_header", None)
        callerid = header.get("callerid") if isinstance(header, dict) else None
        if not callerid or callerid in self.own:
            return None
        return str(callerid)

    def read(self, message: Any, topic: str, raw: Tuple[wire.Reader, Any]) -> Optional[List[Any]]:
        """The values of a message relayed as bytes; bytes the plan cannot read are decoded
        as rospy would (``None``, and the message is not relayed, when they do not decode)."""
        read, decoded_class = raw
        try:
            return read(message._buff)
        except (struct.error, IndexError, ValueError, TypeError):
            pass
        try:
            decoded = decoded_class().deserialize(message._buff)
        except Exception as error:  # genpy raises several kinds on bad bytes
            rospy.logerr_throttle(60.0, f"imrosc: a message on {topic} does not decode: {error}")
            return None
        return self.flatteners[topic](decoded)

    def handler(self, service: str, service_class: Any) -> Callable[[Any], Any]:
        """The handler of ``/m/<service>``: check, forward, check, answer. A request whose
        violations are alone (no alarm) is forwarded, and the whole call reported then. Calls
        go over pooled persistent connections, and the delay checked is the wall-clock
        seconds of the forwarded call, as ``imrosc record`` measured the delays it learnt."""
        blocked = service in self.blocked_services
        calls = ServicePool(rospy, service, service_class)

        def serve(request: Any) -> Any:
            response = self.guard.run(f"call of {service}", checked, request)
            if response is None:
                raise rospy.ServiceException(f"imrosc monitor stopped: {self.guard.failure}")
            return response

        def checked(request: Any) -> Any:
            precheck = self.precheck
            if blocked and precheck is not None:
                with self.lock:
                    values = common.request_values(messages.message_data, request)
                    refused = precheck.call(service, rospy.get_time(), values)
                    raised, alarmed = common.take_alarms(precheck, refused)
                if common.withheld(refused, alarmed):
                    self.report(refused, raised, alarmed)
                    ids = common.withheld_for(refused, alarmed)
                    raise rospy.ServiceException(f"imrosc monitor refused the request: {ids}")
            started = time.perf_counter()
            response = calls.call(request)
            values = common.call_values(
                messages.message_data, request, response, time.perf_counter() - started
            )
            with self.lock:
                now = rospy.get_time()
                found = self.engine.advance(now)
                caused = self.engine.call(service, now, values)
                raised, alarmed = common.take_alarms(self.engine, found + caused)
            self.report(found + caused, raised, alarmed)
            if blocked and common.withheld(caused, alarmed):
                ids = common.withheld_for(caused, alarmed)
                raise rospy.ServiceException(f"imrosc monitor withheld the response: {ids}")
            return response

        return serve

    def on_clear(self, message: Any) -> None:
        """``/m/clear_inv``: stop checking the invariant named by the message."""
        self.guard.run("/clear_inv", self.clear, message)

    def clear(self, message: Any) -> None:
        """:meth:`on_clear` under the guard."""
        ident = str(message.data).strip()
        if self.clear_invariant(ident):
            rospy.loginfo(f"imrosc: invariant {ident} cleared")
        else:
            rospy.logwarn(f"imrosc: /clear_inv names no invariant: {ident!r}")

    def tick(self, event: Any) -> None:
        """The timer: the clock, the graph and the parameters; retry the setup."""
        del event
        self.guard.run("the timer", self.poll)

    def poll(self) -> None:
        """:meth:`tick` under the guard."""
        try:
            state = self.master.getSystemState()
        except Exception:
            state = None
        params: Optional[Dict[str, Any]]
        try:
            params = common.param_values(rospy.get_param, self.spec["params"])
        except Exception:
            params = self.params
        graph = None
        if state is not None:
            self.state = state
            graph = common.logical_graph(
                state, self.own, self.topic_relays, self.service_relays, self.stand_ins
            )
        with self.lock:
            found, raised, alarmed = self.poll_engine(rospy.get_time(), graph, params)
        if self.pending_topics or self.pending_services or self.pending_actions:
            self.connect()
        self.report(found, raised, alarmed)

    def compile(self, compiler: str) -> None:
        """Compile the checks with numba while the node relays (numpy checks meanwhile) and
        log what is in use (:func:`common.compile_engines`)."""
        try:
            rospy.loginfo(self.compile_checks(compiler))
        except Exception as error:  # numpy's checks go on: nothing is lost but speed
            rospy.logwarn(f"imrosc: compiling the checks failed ({error}): numpy checks them")

    def heartbeat(self) -> None:
        """Beat on ``/m/heartbeat`` every period of wall time while the node runs."""
        while not rospy.is_shutdown() and self.guard.failure is None:
            self.beat.publish(TimeMsg(data=rospy.Time.now()))
            time.sleep(self.period)

    # -- what the monitor does about it -----------------------------------------------------

    def report(
        self, violations: Sequence[Any], raised: Sequence[Any], alarmed: Sequence[Any]
    ) -> None:
        """Warn on ``/m/broken_inv`` and in the log (an alarm or a violation alone); queue
        the actions and the unregistrations of the newly raised alarms."""
        for report in common.reports(violations, raised, alarmed, self.violation_map):
            self.broken.publish(String(data=common.report_json(report)))
            if report.alarm:  # two call sites: alarms and violations are throttled apart
                rospy.logwarn_throttle(1.0, common.log_line(report))
            else:
                rospy.logwarn_throttle(1.0, common.log_line(report))
        for ident in common.select_actions(raised, self.violation_map):
            self.work.put(("action", ident))
        if self.unregister and raised:
            for node, topic in common.to_unregister(
                [alarm.violation for alarm in raised],
                self.by_id,
                self.state,
                self.own,
                self.topic_relays,
            ):
                self.work.put(("unregister", node, topic))

    def worker(self) -> None:
        """Take the queued actions one by one (a service call may take its time)."""
        while not rospy.is_shutdown():
            try:
                job = self.work.get(timeout=0.5)
            except queue.Empty:
                continue
            try:
                if job[0] == "action":
                    self.act(job[1])
                else:
                    self.unregister_publisher(job[1], job[2])
            except Exception as error:
                rospy.logerr(f"imrosc: {job[0]} {job[1:]} failed: {error}")

    def act(self, ident: str) -> None:
        """Publish the action's message or call its service."""
        action = self.actions[ident]
        if action["target"] == "topic":
            out = self.action_out.get(ident)
            if out is None:
                rospy.logwarn_throttle(10.0, f"imrosc: action {ident} is not ready")
                return
            publisher, message = out
            publisher.publish(message)
            return
        service = action["name"]
        found = self.service_class(service)
        if found is None:
            rospy.logwarn(f"imrosc: action {ident}: service {service} is not available")
            return
        request = messages.fill(found._request_class(), action["value"], self.message_class)
        rospy.ServiceProxy(service, found)(request)

    def unregister_publisher(self, node: str, topic: str) -> None:
        """Remove ``node`` as a publisher of ``topic`` from the master, on its behalf: the
        master tells the subscribers, which drop their connections to it."""
        code, status, uri = self.master_api.lookupNode(self.name, node)
        if code != 1:
            rospy.logwarn(f"imrosc: cannot look up {node}: {status}")
            return
        code, status, _ = self.master_api.unregisterPublisher(node, topic, uri)
        if code != 1:
            rospy.logwarn(f"imrosc: cannot unregister {node} of {topic}: {status}")
            return
        rospy.logwarn(f"imrosc: unregistered unknown publisher {node} of {topic}")
        if topic not in self.topic_relays:
            # a watched topic: the system's rospy subscribers keep their connection to the
            # publisher and hear it still, so the node keeps hearing and checking it too
            return
        # a blocked topic, which only the node hears: roscpp subscribers drop a publisher the
        # master no longer lists, rospy ones only connect to new publishers, so the node
        # closes its own connection to it and relays nothing of it
        subscriber = self.subscribers.get(topic)
        impl = getattr(subscriber, "impl", None)
        for connection in list(getattr(impl, "connections", ())):
            if getattr(connection, "endpoint_id", None) == uri:
                connection.close()


def main(
    package: str,
    engine_class: Callable[..., Any],
    flatteners: Mapping[str, Flatten],
) -> None:
    """Run the monitor node of ``package`` until ROS shuts down."""
    if rospy is None:
        sys.exit("imrosc monitor: rospy is not importable; run it on a ROS 1 system")
    np.seterr(all="ignore")  # the engine checks NaN and infinities itself
    rospy.init_node(package)
    path = rospy.get_param("~invariants", "") or default_invariants(package)
    try:
        spec = files.load_monitor_spec()
        document = files.load_invariants(path)
    except (OSError, ValueError) as error:
        rospy.logfatal(f"imrosc monitor: {error}")
        sys.exit(1)
    try:
        monitor = Monitor(spec, document, engine_class, flatteners)
    except files.InvariantsError as error:  # the engine cannot be built from the file
        rospy.logfatal(f"imrosc monitor: {path}: {error}")
        sys.exit(1)
    compiler = monitor.engine.compiler()
    rospy.loginfo(
        f"imrosc monitor {rospy.get_name()}: checking {len(document['invariants'])} "
        f"invariants from {path}; {common.checks_plan(compiler)}"
    )
    if compiler is not None:
        threading.Thread(
            target=monitor.compile, args=(compiler,), name="imrosc-compile", daemon=True
        ).start()
    rospy.spin()
    if monitor.guard.failure is not None:
        sys.exit(1)  # roslaunch reports the exit (and a required="true" node ends the launch)
