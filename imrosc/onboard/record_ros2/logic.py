"""What the ROS 2 recorder decides, without rclpy: plain functions the node calls.

* the call record of a paired call (:func:`call_record`), written with the one record
  encoder (``imrosc/onboard/records.py``, imported as ``records``);
* the architecture of one reading of rclpy's graph API (``monitor_ros2``'s
  :class:`GraphView`) with the recorder, rosbag2 and hidden names left out
  (:func:`arch_of`);
* the parameters of the scope as a snapshot (:func:`params_of`);
* change detection: a snapshot is published only when its text differs from the last one
  published on its topic (:class:`Changes`);
* service calls from service introspection events (``<service>/_service_event``, type
  ``<pkg>/srv/<Name>_Event``): :func:`event_of` reads one event, :class:`Pairing` pairs the
  request and response events of one call by client gid and sequence number into a
  :class:`Call`, :func:`client_node` names the client from its gid.

Python 3.8 syntax, standard library only (and ``monitor_ros2``'s plain logic, ``onboard``):
this module is copied into generated packages.

>>> changes = Changes()
>>> changes.changed("/imrosc/params", "{}"), changes.changed("/imrosc/params", "{}")
(True, False)
"""

from __future__ import annotations

from typing import Any, Dict, Iterable, List, Mapping, NamedTuple, Optional, Sequence, Set, Tuple

from .. import files, records
from ..monitor_ros2 import logic as graph

SPEC_FILE = "recorder.json"
SPEC_FORMAT = "imrosc-recorder"
SPEC_VERSION = 1
EVENT_SUFFIX = "/_service_event"
ROSBAG_NODES = frozenset({"/rosbag2_recorder", "/rosbag2_player"})
"""rosbag2's nodes: the recording machinery, not part of the robot."""
UNKNOWN_NODE = "/unknown"
"""The node named in a call record when the graph cannot tell the client or the server."""

REQUEST_SENT, REQUEST_RECEIVED, RESPONSE_SENT, RESPONSE_RECEIVED = 0, 1, 2, 3
"""``service_msgs/msg/ServiceEventInfo`` event types."""
CLIENT, SERVER = "client", "server"
_SIDES = {REQUEST_SENT: CLIENT, RESPONSE_RECEIVED: CLIENT}
_REQUESTS = (REQUEST_SENT, REQUEST_RECEIVED)
_RESPONSES = (RESPONSE_SENT, RESPONSE_RECEIVED)
DONE = 1000
"""Calls given out that :class:`Pairing` remembers, for the late events of their other side."""


def is_hidden(name: str) -> bool:
    """Whether a ROS 2 name is hidden (a token starts with ``_``, as ``ros2`` hides it).

    >>> is_hidden("/a/_service_event"), is_hidden("/_ros2cli_1"), is_hidden("/a/b")
    (True, True, False)
    """
    return any(token.startswith("_") for token in name.split("/"))


def json_data(value: Any) -> Any:
    """Data from ``monitor_ros2.logic.message_data`` or a parameter as JSON data: bytes
    as lists of integers, tuples as lists.

    >>> json_data({"a": b"\\x01\\x02", "b": (1, [b"\\x03"])})
    {'a': [1, 2], 'b': [1, [3]]}
    """
    if isinstance(value, dict):
        return {str(key): json_data(item) for key, item in value.items()}
    if isinstance(value, (bytes, bytearray)):
        return list(bytes(value)) if len(value) != 1 else int(value[0])
    if isinstance(value, (list, tuple)):
        return [json_data(item) for item in value]
    return value


# -- snapshots ------------------------------------------------------------------------------


def arch_of(
    view: graph.GraphView, hidden: Iterable[str] = ()
) -> Tuple[Dict[str, Tuple[List[str], List[str]]], Dict[str, List[str]]]:
    """The architecture in one reading of the graph, as the robot has it.

    Nodes in ``hidden`` (the recorder), rosbag2's nodes and hidden nodes are left out; so
    are the record topics, hidden topics and services (``<service>/_service_event``,
    ``ros2`` daemons), names that are not global ROS names and what is left without any
    node.

    >>> view = graph.GraphView(
    ...     {"/t": (["/a", "/rec"], ["/rosbag2_recorder"]), "/imrosc/arch": (["/rec"], []),
    ...      "/s/_service_event": (["/a"], [])}, {}, {},
    ...     {"/s": ["/b"], "/rec/get_parameters": ["/rec"]}, {}, ["/a", "/b", "/rec"])
    >>> arch_of(view, ["/rec"])
    ({'/t': (['/a'], [])}, {'/s': ['/b']})
    """
    mine = set(hidden) | ROSBAG_NODES

    def kept(nodes: Iterable[str]) -> List[str]:
        return sorted(
            {n for n in nodes if n not in mine and records.is_global_name(n) and not is_hidden(n)}
        )

    topics: Dict[str, Tuple[List[str], List[str]]] = {}
    for name, (pubs, subs) in sorted(view.topics.items()):
        if (
            name.startswith(records.RECORD_PREFIX)
            or is_hidden(name)
            or not records.is_global_name(name)
        ):
            continue
        ends = (kept(pubs), kept(subs))
        if ends[0] or ends[1]:
            topics[name] = ends
    services: Dict[str, List[str]] = {}
    for name, servers in sorted(view.services.items()):
        if is_hidden(name) or not records.is_global_name(name):
            continue
        nodes = kept(servers)
        if nodes:
            services[name] = nodes
    return topics, services


def params_of(answers: Mapping[str, Any], names: Iterable[str]) -> Dict[str, Any]:
    """The scope's parameters that are set, by record name, as JSON data (``answers`` from
    ``monitor_ros2.logic.parameter_answers``).

    >>> params_of({"/a/gain": 2.0, "/a/raw": [b"\\x01", b"\\x02"], "/x": 1}, ["/a/gain", "/a/raw"])
    {'/a/gain': 2.0, '/a/raw': [1, 2]}
    """
    return {name: json_data(answers[name]) for name in sorted(set(names)) if name in answers}


class Changes:
    """The last text published on each record topic: :meth:`changed` says whether a new one
    differs (and remembers it)."""

    def __init__(self) -> None:
        self.last: Dict[str, str] = {}

    def changed(self, topic: str, text: str) -> bool:
        """Whether ``text`` differs from the last text on ``topic``; it becomes the last."""
        if self.last.get(topic) == text:
            return False
        self.last[topic] = text
        return True


# -- the spec -------------------------------------------------------------------------------


def load_spec(directory: Optional[str] = None) -> Dict[str, Any]:
    """The package's recorder spec (``recorder.json`` of the package's Python package):
    ``services`` and ``params`` of the scope, the default ``period``."""
    return check_spec(files.load_spec(directory, SPEC_FILE))


def check_spec(spec: Any) -> Dict[str, Any]:
    """``spec`` if it is a recorder spec; ``ValueError`` with the reason otherwise.

    >>> check_spec({"format": "imrosc-recorder", "version": 1, "services": ["/s"],
    ...             "params": [], "period": 0.5})["services"]
    ['/s']
    """
    if not isinstance(spec, dict) or spec.get("format") != SPEC_FORMAT:
        raise ValueError("not an imrosc recorder spec")
    if spec.get("version") != SPEC_VERSION:
        raise ValueError(f"recorder spec version {spec.get('version')!r}; this node reads 1")
    for key in ("services", "params"):
        names = spec.get(key)
        if not isinstance(names, list) or not all(records.is_global_name(n) for n in names):
            raise ValueError(f"recorder spec: {key!r} must be a list of global names")
    period = spec.get("period")
    if isinstance(period, bool) or not isinstance(period, (int, float)) or period <= 0:
        raise ValueError("recorder spec: 'period' must be a positive number")
    return spec


# -- service calls from introspection events ------------------------------------------------


def event_topic(service: str) -> str:
    """The topic of a service's introspection events.

    >>> event_topic("/a/reset")
    '/a/reset/_service_event'
    """
    return service.rstrip("/") + EVENT_SUFFIX


def request_topic(service: str) -> str:
    """The DDS topic of a service's requests (``no_mangle``), whose writers are its
    clients: their gids are the ``client_gid`` of the events.

    >>> request_topic("/a/reset")
    'rq/a/resetRequest'
    """
    return "rq" + service + "Request"


def event_service(type_name: str) -> Optional[Tuple[str, str]]:
    """The module and service class of an event type (``pkg/srv/Name_Event``), ``None``
    for any other type.

    >>> event_service("std_srvs/srv/SetBool_Event"), event_service("std_msgs/msg/String")
    (('std_srvs.srv', 'SetBool'), None)
    """
    try:
        module, name = graph.interface_name(type_name, "srv")
    except ValueError:
        return None
    if not name.endswith("_Event") or len(name) <= len("_Event"):
        return None
    return module, name[: -len("_Event")]


class ServiceEvent(NamedTuple):
    """One introspection event: its type, stamp (seconds), the client's gid, the sequence
    number, and the request or response it carries (``None`` without contents)."""

    kind: int
    stamp: float
    client_gid: bytes
    sequence: int
    request: Optional[Dict[str, Any]] = None
    response: Optional[Dict[str, Any]] = None


def gid_bytes(gid: Any) -> bytes:
    """A gid (``uint8[16]`` array, list of integers or bytes) as bytes.

    >>> gid_bytes([1, 2, 255]), gid_bytes(b"ab")
    (b'\\x01\\x02\\xff', b'ab')
    """
    if isinstance(gid, (bytes, bytearray)):
        return bytes(gid)
    return bytes(bytearray(int(b) & 0xFF for b in gid))


def event_of(message: Any) -> ServiceEvent:
    """A :class:`ServiceEvent` of an rclpy ``<Name>_Event`` message."""
    info = message.info
    stamp = float(info.stamp.sec) + float(info.stamp.nanosec) / 1e9

    def first(items: Any) -> Optional[Dict[str, Any]]:
        if items is None or len(items) == 0:
            return None
        data = json_data(graph.message_data(items[0]))
        return data if isinstance(data, dict) else None

    return ServiceEvent(
        int(info.event_type),
        stamp,
        gid_bytes(info.client_gid),
        int(info.sequence_number),
        first(message.request),
        first(message.response),
    )


class Call(NamedTuple):
    """One call paired from its events: ``response`` is ``None`` when it got no answer."""

    service: str
    client_gid: bytes
    request: Dict[str, Any]
    response: Optional[Dict[str, Any]]
    stamp: float
    delay: float


def same_participant(gid: bytes, other: bytes) -> bool:
    """Whether two DDS gids (GUIDs: a 12-byte participant prefix, a 4-byte entity id) are
    different endpoints of one participant.

    >>> p = bytes(range(12))
    >>> same_participant(p + b"\\0\\0\\x2a\\x03", p + b"\\0\\0\\x29\\x04")
    True
    >>> same_participant(p + b"\\0\\0\\x2a\\x03", bytes(16)), same_participant(b"ab", b"ab")
    (False, False)
    """
    return len(gid) >= 16 and len(other) >= 16 and gid[:12] == other[:12] and gid != other


def _side(kind: int) -> str:
    return _SIDES.get(kind, SERVER)


def pair(service: str, events: Mapping[int, ServiceEvent]) -> Optional[Call]:
    """The call of the events of one ``(client gid, sequence number)``; ``None`` without
    a request event. Times come from one side when it has both of its events (the
    client's first: request sent to response received), else from the request and the
    response events there are; the request and response contents from whichever event
    carries them (``{}`` when introspection records metadata only).

    >>> gid = b"\\x01" * 16
    >>> events = {REQUEST_SENT: ServiceEvent(REQUEST_SENT, 10.0, gid, 1, {"data": True}),
    ...           REQUEST_RECEIVED: ServiceEvent(REQUEST_RECEIVED, 10.1, gid, 1),
    ...           RESPONSE_SENT: ServiceEvent(RESPONSE_SENT, 10.2, gid, 1, None, {"ok": 1}),
    ...           RESPONSE_RECEIVED: ServiceEvent(RESPONSE_RECEIVED, 10.5, gid, 1)}
    >>> call = pair("/s", events)
    >>> call.request, call.response, call.stamp, round(call.delay, 6)
    ({'data': True}, {'ok': 1}, 10.0, 0.5)
    >>> pair("/s", {RESPONSE_SENT: events[RESPONSE_SENT]}) is None
    True
    """
    requests = [events[k] for k in _REQUESTS if k in events]
    responses = [events[k] for k in _RESPONSES if k in events]
    if not requests:
        return None
    request = next((e.request for e in requests if e.request is not None), None)
    answered = bool(responses)
    response: Optional[Dict[str, Any]] = None
    if answered:
        response = next((e.response for e in responses if e.response is not None), None) or {}
    if REQUEST_SENT in events and RESPONSE_RECEIVED in events:
        start, end = events[REQUEST_SENT].stamp, events[RESPONSE_RECEIVED].stamp
    elif REQUEST_RECEIVED in events and RESPONSE_SENT in events:
        start, end = events[REQUEST_RECEIVED].stamp, events[RESPONSE_SENT].stamp
    else:
        start = min(e.stamp for e in requests)
        end = max(e.stamp for e in responses) if responses else start
    return Call(
        service, requests[0].client_gid, request or {}, response, start, max(0.0, end - start)
    )


class Pairing:
    """Introspection events waiting to become calls.

    A call is complete when it has a response and both events of every side (client,
    server) that has published events of its service so far; otherwise it is given out
    ``settle`` seconds after its first response event (a side that stopped introspecting),
    or as failed (no response) ``timeout`` seconds after its first event. ``now`` is any
    monotonic clock in seconds.
    """

    def __init__(self, settle: float = 1.0, timeout: float = 10.0) -> None:
        self.settle = settle
        self.timeout = timeout
        self.pending: Dict[Tuple[str, bytes, int], Dict[int, ServiceEvent]] = {}
        self.first: Dict[Tuple[str, bytes, int], float] = {}
        self.answered: Dict[Tuple[str, bytes, int], float] = {}
        self.sides: Dict[str, Set[str]] = {}
        self.aliases: Dict[Tuple[str, bytes, int], Tuple[str, bytes, int]] = {}
        """The other side's name of a waiting call (see :meth:`_key`)."""
        self.done: Dict[Tuple[str, bytes, int], Set[str]] = {}
        """The last calls given out and the sides they had (at most :data:`DONE`)."""
        self.dropped = 0
        """Calls seen only by their response (the recorder started in between)."""
        self.unfinished = 0
        """Calls unanswered when the node stopped, within their time (:meth:`drain`)."""

    def add(self, service: str, event: ServiceEvent, now: float) -> List[Call]:
        """Take one event; the calls it completes."""
        self.sides.setdefault(service, set()).add(_side(event.kind))
        key = self._key(service, event)
        if key is None:  # the other side of a call given out already
            return []
        self.pending.setdefault(key, {}).setdefault(event.kind, event)
        self.first.setdefault(key, now)
        if event.kind in _RESPONSES:
            self.answered.setdefault(key, now)
        if self._complete(key):
            return self._take([key])
        return []

    def _key(self, service: str, event: ServiceEvent) -> Optional[Tuple[str, bytes, int]]:
        """The call an event belongs to. The two sides name the client differently: the
        client's events carry the gid of its request writer, the server's the gid of the
        client's response reader (rmw_fastrtps, Jazzy), two endpoints of one DDS
        participant. An event of one side therefore joins the waiting call of the other
        side with the same sequence number whose gid has the same participant prefix
        (:func:`same_participant`; the nearest in time if there are several). ``None``
        for an event of the side a call given out already lacked (before the recorder had
        seen that side introspect): it belongs to that call."""
        own = (service, event.client_gid, event.sequence)
        if own in self.pending:
            return own
        if own in self.aliases and self.aliases[own] in self.pending:
            return self.aliases[own]
        side = _side(event.kind)
        others = [
            (abs(min(e.stamp for e in events.values()) - event.stamp), key)
            for key, events in self.pending.items()
            if key[0] == service
            and key[2] == event.sequence
            and same_participant(key[1], event.client_gid)
            and all(_side(kind) != side for kind in events)
        ]
        if not others:
            for key, sides in self.done.items():
                if (
                    key[0] == service
                    and key[2] == event.sequence
                    and same_participant(key[1], event.client_gid)
                    and side not in sides
                ):
                    return None
            return own
        found = min(others)[1]
        self.aliases[own] = found
        return found

    def _complete(self, key: Tuple[str, bytes, int]) -> bool:
        events = self.pending[key]
        if not any(k in events for k in _RESPONSES):
            return False
        wanted = {k for k in (*_REQUESTS, *_RESPONSES) if _side(k) in self.sides[key[0]]}
        return wanted <= set(events)

    def _take(self, keys: Sequence[Tuple[str, bytes, int]]) -> List[Call]:
        calls: List[Call] = []
        taken = set(keys)
        for alias in [a for a, key in self.aliases.items() if key in taken]:
            del self.aliases[alias]
        for key in keys:
            events = self.pending.pop(key)
            self.first.pop(key, None)
            self.answered.pop(key, None)
            self.done[key] = {_side(kind) for kind in events}
            while len(self.done) > DONE:
                del self.done[next(iter(self.done))]
            call = pair(key[0], events)
            if call is None:
                self.dropped += 1
            else:
                calls.append(call)
        return sorted(calls, key=lambda c: c.stamp)

    def due(self, now: float) -> List[Call]:
        """The calls whose wait is over at ``now``."""
        keys = [
            key
            for key, start in self.first.items()
            if (key in self.answered and now - self.answered[key] >= self.settle)
            or now - start >= self.timeout
        ]
        return self._take(keys)

    def drain(self, now: Optional[float] = None) -> List[Call]:
        """The waiting calls when the node stops: the answered ones, and as failed those
        whose ``timeout`` is over at ``now``. One still unanswered within its time is left
        out and counted in :attr:`unfinished`: the recording ended before its answer, which
        does not make it a failed call (the client's call in flight at Ctrl-C). Without
        ``now`` every waiting call is given out."""
        keys = list(self.pending)
        if now is not None:
            late = [
                key
                for key in keys
                if key not in self.answered and now - self.first.get(key, now) < self.timeout
            ]
            self.unfinished += len(late)
            for key in late:
                self.pending.pop(key)
                self.first.pop(key, None)
            self.aliases = {a: key for a, key in self.aliases.items() if key not in late}
            keys = [key for key in keys if key not in late]
        return self._take(keys)


def client_node(
    gid: bytes,
    writers: Sequence[Tuple[bytes, str]],
    event_publishers: Iterable[str] = (),
    servers: Iterable[str] = (),
) -> str:
    """The node of a client: the node of the request writer with its gid (the graph's gids
    may be longer than the event's 16 bytes: a prefix matches), else the one node other than
    the servers that publishes the service's events, else :data:`UNKNOWN_NODE`.

    >>> client_node(b"\\x01\\x02", [(b"\\x01\\x02\\x00\\x00", "/a/car"), (b"\\x09", "/b")])
    '/a/car'
    >>> client_node(b"\\x07", [], ["/srv", "/ctl"], ["/srv"]), client_node(b"\\x07", [])
    ('/ctl', '/unknown')
    """
    for writer, node in writers:
        if gid and writer[: len(gid)] == gid and records.is_global_name(node):
            return node
    others = sorted(set(event_publishers) - set(servers))
    if len(others) == 1 and records.is_global_name(others[0]):
        return others[0]
    return UNKNOWN_NODE


def server_node(servers: Iterable[str]) -> str:
    """The node that serves a call: the service's server (the first by name if the graph
    lists several, which ROS 2 allows), else :data:`UNKNOWN_NODE`.

    >>> server_node(["/b", "/a"]), server_node([])
    ('/a', '/unknown')
    """
    named = sorted(n for n in servers if records.is_global_name(n))
    return named[0] if named else UNKNOWN_NODE


def call_record(call: Call, client: str, server: str) -> str:
    """The ``/imrosc/srvs`` text of a paired call."""
    return records.call_text(
        call.service, client, server, call.request, call.response, call.stamp, call.delay
    )
