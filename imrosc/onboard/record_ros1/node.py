"""imrosc's recording node (thesis section 3.2, Figures 3.4, 3.5 and 3.8), for ROS 1.

``imrosc record`` starts it under the robot's own Python (rospy lives there, imrosc is not
installed there) next to ``rosbag record``: ``python -m imrosc.onboard.record_ros1.node
SPEC``, with only ``imrosc`` on the module path (a link to imrosc's package folder, as for
the ROS 2 recorder), ``SPEC`` a JSON object saying what to record (see :func:`load_spec`).
The node

* relays every service of the scope: the server was remapped to ``/rec/<srv>``; the node
  advertises ``<srv>`` itself once ``/rec/<srv>`` is served, forwards each request there,
  answers the client, and publishes one call record on ``/imrosc/srvs``;
* polls the master every ``period`` seconds for the node graph and the parameters, and
  publishes a full snapshot on ``/imrosc/arch`` and ``/imrosc/params`` at start and whenever
  it changed.

Records are ``std_msgs/String`` messages holding the canonical JSON of
``docs/record-format.md``, written by the one record encoder (``imrosc/onboard/records.py``).
Nothing is published before ``rosbag record`` is connected to all three record topics, so
no record is lost at start; on SIGINT or SIGTERM the relays are withdrawn, calls in flight
are answered and recorded, every queued record is published, and the node exits.

What the node tells ``imrosc record`` goes to its standard output, one JSON object a line:
``{"event": "ready"}``, ``{"event": "relay", ...}``, ``{"event": "warning", "message": ...}``,
``{"event": "stats", ...}`` (last).

The node and the recording machinery (``rosbag record``) are left out of the architecture
snapshots: they are not part of the robot. So are nodes that the master still lists but that
do not answer any more (a node killed with SIGKILL cannot unregister), and the ``/rec/<srv>``
names: the relayed service is recorded as served by the node that serves ``/rec/<srv>``.

It runs on ROS Noetic's Python 3.8 and Debian's ROS 1 (Python 3.11): standard library and
rospy only. Importing it needs no rospy (what it decides is tested where imrosc runs).
"""

from __future__ import annotations

import contextlib
import json
import math
import queue
import signal
import sys
import threading
import time
import warnings
import xmlrpc.client
from typing import Any, Callable, Dict, List, Optional, Set, Tuple

from .. import records
from ..service_pool import ServicePool

DEFAULT_PREFIX = "/rec"
_SERVER_ERROR = "service cannot process request: "
_RESPONDED = "responded with an error: "
_STOP_SIGNALS = (signal.SIGINT, signal.SIGTERM)
SWITCH_INTERVAL = 0.0005
"""Seconds a thread may hold the GIL while another waits (Python's default is 5 ms): a relay
thread woken by the server's answer must not wait behind the thread publishing records."""


def plain(value: Any) -> Any:
    """A rospy message (or a field of one) as JSON data.

    Messages become objects of their fields, times and durations float seconds, ``uint8[]``
    (bytes) and other arrays lists; other values stay as they are.

    >>> class Time:
    ...     def to_sec(self): return 1.5
    >>> plain([b"\\x01\\x02", Time(), (1, "x")])
    [[1, 2], 1.5, [1, 'x']]
    """
    if hasattr(value, "_slot_types") and hasattr(value, "__slots__"):
        return {name: plain(getattr(value, name)) for name in value.__slots__}
    if hasattr(value, "to_sec"):
        return float(value.to_sec())
    if isinstance(value, (bytes, bytearray)):
        return list(value)
    if isinstance(value, (list, tuple)):
        return [plain(item) for item in value]
    return value


def json_value(value: Any) -> Any:
    """A parameter value from the master's XML-RPC as JSON data.

    >>> json_value({"a": xmlrpc.client.Binary(b"ab"), "b": [1, (2.5, True)]})
    {'a': [97, 98], 'b': [1, [2.5, True]]}
    """
    if isinstance(value, dict):
        return {str(key): json_value(item) for key, item in value.items()}
    if isinstance(value, (list, tuple)):
        return [json_value(item) for item in value]
    if isinstance(value, xmlrpc.client.Binary):
        return list(value.data)
    if isinstance(value, xmlrpc.client.DateTime):
        return str(value)
    if isinstance(value, float) and not math.isfinite(value):
        return value
    return value


# -- snapshots from what the master says ----------------------------------------------------


def snapshot(
    state: Any, hidden: Any, relayed: Dict[str, str]
) -> Tuple[Dict[str, Tuple[List[str], List[str]]], Dict[str, List[str]]]:
    """The architecture of ``getSystemState``'s ``[pubs, subs, srvs]`` as the robot has it.

    Nodes in ``hidden`` (the recorder, rosbag, nodes that do not answer) are left out, so are
    the record topics and what is left without any node; ``relayed`` maps each ``/rec/<srv>``
    to ``<srv>``, whose servers are then those of ``/rec/<srv>``.

    >>> state = [[["/t", ["/a", "/rec"]], ["/imrosc/arch", ["/rec"]]],
    ...          [["/t", ["/bag"]], ["/u", ["/bag"]]],
    ...          [["/s", ["/rec"]], ["/rec/s", ["/srv"]], ["/rec/get_loggers", ["/rec"]]]]
    >>> snapshot(state, {"/rec", "/bag"}, {"/rec/s": "/s"})
    ({'/t': (['/a'], [])}, {'/s': ['/srv']})
    """
    pubs, subs, srvs = state
    topics: Dict[str, Tuple[Set[str], Set[str]]] = {}
    for index, entries in enumerate((pubs, subs)):
        for topic, nodes in entries:
            if topic.startswith(records.RECORD_PREFIX) or not records.is_global_name(topic):
                continue
            ends = topics.setdefault(topic, (set(), set()))
            ends[index].update(n for n in nodes if n not in hidden and records.is_global_name(n))
    services: Dict[str, Set[str]] = {}
    for service, nodes in srvs:
        name = relayed.get(service, service)
        if not records.is_global_name(name):
            continue
        services.setdefault(name, set()).update(
            n for n in nodes if n not in hidden and records.is_global_name(n)
        )
    return (
        {t: (sorted(p), sorted(s)) for t, (p, s) in sorted(topics.items()) if p or s},
        {s: sorted(n) for s, n in sorted(services.items()) if n},
    )


_MISSING = object()


def lookup(tree: Any, name: str) -> Any:
    """The value of parameter ``name`` in the parameter tree (``_MISSING`` if unset).

    >>> lookup({"a": {"b": 1}}, "/a/b"), lookup({"a": {"b": 1}}, "/a"), lookup({}, "/x") is _MISSING
    (1, {'b': 1}, True)
    """
    node = tree
    for part in name.strip("/").split("/"):
        if not isinstance(node, dict) or part not in node:
            return _MISSING
        node = node[part]
    return node


def leaves(tree: Any, prefix: str = "") -> Dict[str, Any]:
    """Every leaf parameter of the tree by global name (invalid names are left out).

    >>> leaves({"a": {"b": 1, "c": {}}, "d": [1], "bad-name": 2})
    {'/a/b': 1, '/d': [1]}
    """
    found: Dict[str, Any] = {}
    for key, value in tree.items():
        name = f"{prefix}/{key}"
        if not records.is_global_name(name):
            continue
        if isinstance(value, dict):
            found.update(leaves(value, name))
        else:
            found[name] = value
    return found


def param_values(tree: Any, names: Optional[List[str]]) -> Dict[str, Any]:
    """The parameters to record: ``names`` (those set), or every leaf when ``names`` is None.

    >>> param_values({"a": {"b": 1, "c": 2}}, ["/a", "/x"])
    {'/a': {'b': 1, 'c': 2}}
    """
    tree = json_value(tree if isinstance(tree, dict) else {})
    if names is None:
        return leaves(tree)
    found = {}
    for name in names:
        value = lookup(tree, name)
        if value is not _MISSING and records.is_global_name(name):
            found[name] = value
    return found


def load_spec(text: str) -> Dict[str, Any]:
    """The node's instructions (the JSON argument ``imrosc record`` passes).

    ``node``: this node's name; ``rosbag``: the name of the ``rosbag record`` node; ``services``:
    the services to relay; ``params``: the parameters to record (``null``: all); ``period``:
    seconds between polls; ``prefix``: where servers were remapped (``/rec``); ``ready_timeout``:
    seconds to wait for rosbag; ``ping``: whether to leave out nodes that do not answer.

    >>> sorted(load_spec('{"node": "/r", "rosbag": "/b"}').items())[:3]
    [('node', '/r'), ('params', []), ('period', 1.0)]
    """
    spec: Dict[str, Any] = {
        "services": [],
        "params": [],
        "period": 1.0,
        "prefix": DEFAULT_PREFIX,
        "ready_timeout": 20.0,
        "ping": True,
    }
    spec.update(json.loads(text))
    for key in ("node", "rosbag"):
        if not records.is_global_name(spec.get(key)):
            raise ValueError(f"{key!r} must be a global node name")
    return spec


def client_message(error: str) -> str:
    """What the relay tells its client when the call failed, so that the client sees what
    the server said (rospy puts ``service cannot process request: `` in front again).

    >>> client_message("service [/rec/s] responded with an error: b'service cannot process "
    ...                "request: no task'")
    'no task'
    >>> client_message("unable to connect to service: refused")
    'unable to connect to service: refused'
    """
    _, found, said = error.partition(_RESPONDED)
    message = said if found else error
    if message[:2] in ("b'", 'b"') and message.endswith(message[1]):
        message = message[2:-1]  # rospy shows the server's message as bytes
    return message[len(_SERVER_ERROR) :] if message.startswith(_SERVER_ERROR) else message


_EMIT_LOCK = threading.Lock()


def emit(event: str, **fields: Any) -> None:
    """Tell ``imrosc record`` something (one JSON line on standard output, whole)."""
    fields["event"] = event
    line = json.dumps(fields, sort_keys=True) + "\n"
    with _EMIT_LOCK:
        sys.stdout.write(line)
        sys.stdout.flush()


# -- talking to the master and to nodes -----------------------------------------------------


class _Transport(xmlrpc.client.Transport):
    """XML-RPC with a timeout: a dead node or a hung master must not hang the recorder."""

    def __init__(self, timeout: float) -> None:
        super().__init__()
        self._timeout = timeout

    def make_connection(self, host: Any) -> Any:
        connection = super().make_connection(host)
        connection.timeout = self._timeout
        return connection


def _proxy(uri: str, timeout: float) -> xmlrpc.client.ServerProxy:
    return xmlrpc.client.ServerProxy(uri, transport=_Transport(timeout))


class Master:
    """The master API (``ROS_MASTER_URI``) as this node."""

    def __init__(self, uri: str, caller: str) -> None:
        self.proxy = _proxy(uri, 5.0)
        self.caller = caller
        self.uris: Dict[str, str] = {}

    def call(self, method: str, *args: Any) -> Any:
        code, message, value = getattr(self.proxy, method)(self.caller, *args)
        if code != 1:
            raise RuntimeError(f"master {method}: {message}")
        return value

    def unreachable(self, nodes: Any) -> Set[str]:
        """The nodes whose XML-RPC server refuses connections (they are gone).

        A node that is slow to answer counts as alive; only a refused or reset connection
        (the process is gone, its port closed) counts as dead.
        """
        dead = set()
        for node in nodes:
            uri = self.uris.get(node)
            try:
                if uri is None:
                    uri = self.uris[node] = str(self.call("lookupNode", node))
                _proxy(uri, 1.0).getPid(self.caller)
            except (ConnectionRefusedError, ConnectionResetError):
                self.uris.pop(node, None)
                dead.add(node)
            except (OSError, xmlrpc.client.Error, RuntimeError, ValueError):
                self.uris.pop(node, None)  # timed out or odd: ask again next time
        for node in set(self.uris) - set(nodes):
            del self.uris[node]
        return dead


# -- the node -------------------------------------------------------------------------------


class Recorder:
    """The recording node: record publishers, service relays and the polling loop."""

    def __init__(self, spec: Dict[str, Any], rospy: Any, string_type: Any) -> None:
        self.spec = spec
        self.rospy = rospy
        self.string = string_type
        self.name = rospy.get_name()
        import rosgraph  # type: ignore[import-not-found]

        self.master = Master(rosgraph.get_master_uri(), self.name)
        self.hidden = {self.name, spec["rosbag"]}
        self.prefix = spec["prefix"].rstrip("/")
        self.targets = {f"{self.prefix}{s}": s for s in spec["services"]}
        self.relays: Dict[str, Relay] = {}
        self.servers: Dict[str, str] = {}
        self.warned: Set[str] = set()
        self.outbox = queue.Queue()  # type: queue.Queue[Optional[Tuple[str, Callable[[], Optional[str]], str]]]
        self.published = dict.fromkeys(records.RECORD_TOPICS, 0)
        self.calls: Dict[str, int] = {}
        self.counts_lock = threading.Lock()
        self.last = {records.ARCH_TOPIC: "", records.PARAMS_TOPIC: ""}
        with warnings.catch_warnings():  # queue_size=None: publishing is synchronous on purpose
            warnings.simplefilter("ignore")
            self.publishers = {
                topic: rospy.Publisher(topic, string_type, latch=topic != records.SRVS_TOPIC)
                for topic in records.RECORD_TOPICS
            }
        self.writer = threading.Thread(target=self._write, name="imrosc-records", daemon=True)
        self.writer.start()

    def warn(self, key: str, message: str) -> None:
        if key not in self.warned:
            self.warned.add(key)
            emit("warning", message=message)

    # records go out in order, from one thread, synchronously (nothing left in a queue at exit)
    def publish(self, topic: str, text: str) -> None:
        self.outbox.put((topic, lambda: text, ""))

    def _write(self) -> None:
        while True:
            item = self.outbox.get()
            if item is None:
                return
            topic, make, service = item
            try:
                text = make()
            except Exception as error:  # a message imrosc cannot encode
                self.warn(f"encode:{service}", f"cannot record a call of {service}: {error}")
                continue
            if text is None:
                continue
            try:
                self.publishers[topic].publish(self.string(data=text))
            except Exception as error:  # a closed connection at shutdown, say
                self.warn("publish", f"cannot publish on {topic}: {error}")
                continue
            with self.counts_lock:
                self.published[topic] += 1
                if service:
                    self.calls[service] = self.calls.get(service, 0) + 1

    def wait_for_rosbag(self, stop: threading.Event) -> bool:
        """Wait until ``rosbag record`` is connected to every record topic."""
        deadline = time.monotonic() + float(self.spec["ready_timeout"])
        rosbag = self.spec["rosbag"]
        while not stop.is_set():
            if all(p.impl.has_connection(rosbag) for p in self.publishers.values()):
                return True
            if time.monotonic() > deadline:
                emit("error", message=f"{rosbag} did not subscribe to the record topics")
                return False
            stop.wait(0.02)
        return False

    def poll(self) -> None:
        """One look at the master: relays, architecture and parameters."""
        state = self.master.call("getSystemState")
        nodes = {n for entries in state for _, names in entries for n in names}
        dead = self.master.unreachable(nodes - self.hidden) if self.spec["ping"] else set()
        if dead:
            state = [
                [[name, [n for n in names if n not in dead]] for name, names in entries]
                for entries in state
            ]
        self._update_relays(state[2])
        topics, services = snapshot(state, self.hidden | dead, dict(self.targets))
        self._changed(records.ARCH_TOPIC, records.arch_text(topics, services))
        names = self.spec["params"]
        if names is None or names:
            tree = self.master.call("getParam", "/")
            self._changed(records.PARAMS_TOPIC, records.params_text(param_values(tree, names)))

    def _changed(self, topic: str, text: str) -> None:
        if text != self.last[topic]:
            self.last[topic] = text
            self.publish(topic, text)

    def _update_relays(self, srvs: Any) -> None:
        served = {name: [n for n in nodes if n != self.name] for name, nodes in srvs}
        for target, service in sorted(self.targets.items()):
            servers = served.get(target, [])
            if servers:
                self.servers[service] = servers[0]
            relay = self.relays.get(service)
            if relay is not None and not servers:
                relay.close()
                del self.relays[service]
                emit("unrelay", service=service)
            elif relay is None and servers:
                others = served.get(service, [])
                if others:
                    self.warn(
                        f"double:{service}",
                        f"{service} is served by {', '.join(others)} and {target} by "
                        f"{', '.join(servers)}: not relaying {service}, its calls are not "
                        f"recorded",
                    )
                    continue
                self._start_relay(service, target)
            elif relay is None and served.get(service):
                self.warn(
                    f"plain:{service}",
                    f"{service} is served by {', '.join(served[service])} under its own name: "
                    f"its calls are not recorded; remap the server's {service} to {target}",
                )

    def _start_relay(self, service: str, target: str) -> None:
        try:
            cls, raw = self._service_class(target)
        except Exception as error:
            self.warn(f"probe:{service}", f"cannot learn the type of {target}: {error}")
            return
        if raw:
            self.warn(
                f"raw:{service}",
                f"service type {cls._type} of {service} cannot be imported here: its calls are "
                f"relayed and recorded without request and response fields",
            )
        try:
            self.relays[service] = Relay(self, service, target, cls, raw)
        except Exception as error:
            self.warn(f"serve:{service}", f"cannot serve {service}: {error}")
            return
        emit("relay", service=service, target=target, type=cls._type, raw=raw)

    def _service_class(self, target: str) -> Tuple[Any, bool]:
        import rosservice  # type: ignore[import-not-found]

        uri = self.master.call("lookupService", target)
        header = rosservice.get_service_headers(target, uri)
        type_name = header.get("type", "")
        cls = _import_service(type_name)
        if cls is not None and cls._md5sum == header.get("md5sum"):
            return cls, False
        return _raw_service(header), True

    def record_call(self, service: str, text: Callable[[], Optional[str]]) -> None:
        self.outbox.put((records.SRVS_TOPIC, text, service))

    def close(self) -> None:
        """Withdraw the relays (answering calls in flight), then publish what is queued."""
        for relay in self.relays.values():
            relay.close()
        for relay in self.relays.values():
            relay.drain(2.0)
        self.outbox.put(None)
        self.writer.join(10.0)


def _import_service(type_name: str) -> Any:
    """The service class of ``pkg/Name`` from the Python path (None if it is not there)."""
    package, _, name = type_name.partition("/")
    if not package or not name:
        return None
    try:
        module = __import__(f"{package}.srv", fromlist=[name])
        return getattr(module, name)
    except (ImportError, AttributeError):
        pass
    try:
        import roslib.message  # type: ignore[import-not-found]

        return roslib.message.get_service_class(type_name)
    except Exception:
        return None


def _raw_service(header: Dict[str, str]) -> Any:
    """A service class that forwards requests and responses as bytes (its type is unknown)."""
    from rospy.msg import AnyMsg  # type: ignore[import-not-found]

    md5sum = header.get("md5sum", "*")
    request = type(
        "RawRequest",
        (AnyMsg,),
        {"__slots__": [], "_type": header.get("request_type", "*"), "_md5sum": md5sum},
    )
    response = type(
        "RawResponse",
        (AnyMsg,),
        {"__slots__": [], "_type": header.get("response_type", "*"), "_md5sum": md5sum},
    )
    return type(
        "RawService",
        (object,),
        {
            "_type": header.get("type", "*"),
            "_md5sum": md5sum,
            "_request_class": request,
            "_response_class": response,
        },
    )


class Relay:
    """Serves ``service`` and forwards each call to ``target`` (the remapped server).

    Connections to the server are persistent and pooled (:class:`ServicePool`), so a call
    costs one extra local hop, not a new connection; the recorded delay is the wall-clock
    seconds of the forwarded call, whatever clock ROS runs on.
    """

    def __init__(self, recorder: Recorder, service: str, target: str, cls: Any, raw: bool):
        self.recorder = recorder
        self.rospy = recorder.rospy
        self.service = service
        self.raw = raw
        self.calls = ServicePool(self.rospy, target, cls)
        self.server = self.rospy.Service(service, cls, self.handle)

    def handle(self, request: Any) -> Any:
        stamp = self.rospy.get_time()
        started = time.perf_counter()
        try:
            response = self.calls.call(request)
        except Exception as error:
            delay = time.perf_counter() - started
            self._record(request, None, stamp, delay)
            raise self.rospy.ServiceException(client_message(str(error))) from None
        self._record(request, response, stamp, time.perf_counter() - started)
        return response

    def _record(self, request: Any, response: Any, stamp: float, delay: float) -> None:
        """Queue the call's record; it is encoded by the publishing thread, after the client
        has its answer (messages are not changed once sent)."""
        fallback = self.recorder.servers.get(self.service, "")

        def text() -> Optional[str]:
            client = (getattr(request, "_connection_header", None) or {}).get("callerid", "")
            server = fallback
            if response is not None:
                header = getattr(response, "_connection_header", None) or {}
                server = header.get("callerid") or fallback
            if not (records.is_global_name(client) and records.is_global_name(server)):
                self.recorder.warn(
                    f"names:{self.service}",
                    f"a call of {self.service} from {client!r} to {server!r} is not recorded: "
                    f"the node names are not valid",
                )
                return None
            fields = {} if self.raw else plain(request)
            answer = None if response is None else {} if self.raw else plain(response)
            record: str = records.call_text(
                self.service, client, server, fields, answer, stamp, delay
            )
            return record

        self.recorder.record_call(self.service, text)

    def close(self) -> None:
        """Stop serving (calls already accepted are still answered)."""
        with contextlib.suppress(Exception):
            self.server.shutdown("imrosc record stops")

    def drain(self, timeout: float) -> None:
        """Wait until no call is in flight, then close the server connections."""
        self.calls.drain(timeout)


def run(argv: List[str]) -> int:
    """The node's main loop; returns the exit status."""
    if len(argv) != 2:
        sys.stderr.write("usage: python -m imrosc.onboard.record_ros1.node SPEC_JSON\n")
        return 2
    try:
        spec = load_spec(argv[1])
    except ValueError as error:
        sys.stderr.write(f"imrosc recorder: bad specification: {error}\n")
        return 2
    stop = threading.Event()

    def on_signal(number: int, frame: Any) -> None:
        stop.set()

    for number in _STOP_SIGNALS:
        signal.signal(number, on_signal)
    sys.setswitchinterval(SWITCH_INTERVAL)
    import rospy  # type: ignore[import-not-found]
    from std_msgs.msg import String  # type: ignore[import-not-found]

    rospy.init_node(spec["node"].lstrip("/"), disable_signals=True, disable_rosout=True)
    recorder = Recorder(spec, rospy, String)
    try:
        if not recorder.wait_for_rosbag(stop):
            return 0 if stop.is_set() else 1
        period = float(spec["period"])
        first = True
        while not stop.is_set():
            try:
                recorder.poll()
            except (OSError, xmlrpc.client.Error, RuntimeError) as error:
                recorder.warn("poll", f"cannot reach the master: {error}")
            if first:
                emit("ready")
                first = False
            stop.wait(period)
        with contextlib.suppress(OSError, xmlrpc.client.Error, RuntimeError):
            recorder.poll()  # the graph as it is at the end
    finally:
        recorder.close()
        with recorder.counts_lock:
            emit("stats", published=dict(recorder.published), calls=dict(recorder.calls))
        rospy.signal_shutdown("imrosc record stops")
    return 0


if __name__ == "__main__":
    sys.exit(run(sys.argv))
