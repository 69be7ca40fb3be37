"""What the ROS 2 monitor node decides, without rclpy: plain functions the node calls.

The decisions ROS 1 and ROS 2 share (which actions a batch of violations takes, the JSON
warning, folding the monitor's relays out of the graph, the invariants checked before a
blocked call is forwarded, flattening JSON values, the watchdog's decision, the package's
files and relay names) are those of ``imrosc/onboard/monitor.py``, imported here as
``common``; this module adds what differs in ROS 2:

* QoS: a subscription that matches every publisher of its topic
  (:func:`subscription_qos`), the relay's offer on ``/m/<topic>`` (:func:`relay_qos`), and
  when to change them (:func:`qos_update`);
* the graph from rclpy's graph API (:func:`node_name`, :func:`system_state`,
  :func:`snapshot`);
* parameters: which node to ask for which name (:func:`parameter_requests`) and the value
  of an ``rcl_interfaces/ParameterValue`` (:func:`parameter_value`);
* messages: a ROS 2 message as JSON-like data (:func:`message_data`, through
  ``get_fields_and_field_types``; ``common.call_values`` makes a service call the
  engine's values of it), an action's YAML value filled into a message (:func:`fill`);
* the warning on ``/m/broken_inv``, with a note on an unknown publisher, which ROS 2 cannot
  unregister (:func:`warning`).

Python 3.8 syntax, standard library only (and ``..onboard``): this module is copied into
generated packages.

>>> subscription_qos([Qos(RELIABLE, VOLATILE), Qos(BEST_EFFORT, VOLATILE)], "std_msgs/msg/UInt8")
Qos(reliability='best_effort', durability='volatile')
>>> subscription_qos([], "sensor_msgs/msg/Imu") == SENSOR_DATA
True
>>> parameter_requests(["/a/car_ctrl/gains/p"], ["/a/car_ctrl"])
{'/a/car_ctrl': [('/a/car_ctrl/gains/p', 'gains.p')]}
"""

from __future__ import annotations

import json
import math
import re
from typing import (
    Any,
    Callable,
    Dict,
    FrozenSet,
    Iterable,
    List,
    Mapping,
    NamedTuple,
    Optional,
    Sequence,
    Tuple,
)

from .. import fill as check
from .. import monitor as common
from ..fill import FillError

RELIABLE, BEST_EFFORT = "reliable", "best_effort"
VOLATILE, TRANSIENT_LOCAL = "volatile", "transient_local"
_RELIABILITY = {1: RELIABLE, 2: BEST_EFFORT}
"""``rmw_qos_reliability_policy_e`` values (the same in every ROS 2 release)."""
_DURABILITY = {1: TRANSIENT_LOCAL, 2: VOLATILE}
"""``rmw_qos_durability_policy_e`` values."""


class Qos(NamedTuple):
    """The two QoS policies that decide whether a subscription hears a publisher."""

    reliability: str
    durability: str


SENSOR_DATA = Qos(BEST_EFFORT, VOLATILE)
"""``rclpy.qos.qos_profile_sensor_data``: what a sensor topic gets until a publisher shows."""
DEFAULT = Qos(RELIABLE, VOLATILE)
"""rclpy's default profile."""
SENSOR_PACKAGES = frozenset({"sensor_msgs"})


class GraphView(NamedTuple):
    """One reading of rclpy's graph API.

    ``topics``: topic to (publishers, subscribers), node names; ``types``: topic to its
    type names; ``publisher_qos``: topic to ``(node, Qos or None)`` per publisher;
    ``services``: service to the nodes that serve it; ``service_types``: service to its
    type names; ``nodes``: every node's full name; ``complete``: whether every endpoint's
    node was known (DDS discovers an endpoint before the name of its node; rclpy reports
    such an endpoint under :data:`UNKNOWN_NAMESPACE` / :data:`UNKNOWN_NAME`).
    """

    topics: Mapping[str, Tuple[Sequence[str], Sequence[str]]]
    types: Mapping[str, Sequence[str]]
    publisher_qos: Mapping[str, Sequence[Tuple[str, Optional[Qos]]]]
    services: Mapping[str, Sequence[str]]
    service_types: Mapping[str, Sequence[str]]
    nodes: Sequence[str]
    complete: bool = True


UNKNOWN_NAMESPACE = "_NODE_NAMESPACE_UNKNOWN_"
UNKNOWN_NAME = "_NODE_NAME_UNKNOWN_"
"""What rclpy's graph API names the node of an endpoint whose node is not discovered yet."""


# -- QoS ------------------------------------------------------------------------------------


def policy(value: Any, names: Mapping[int, str]) -> Optional[str]:
    """The name of a QoS policy value (an rclpy enum or its integer); ``None`` when it is
    ``SYSTEM_DEFAULT``, ``UNKNOWN`` or anything else a publisher does not report plainly."""
    try:
        return names.get(int(value))
    except (TypeError, ValueError):
        return None


def endpoint_qos(profile: Any) -> Optional[Qos]:
    """The :class:`Qos` of an endpoint's ``qos_profile`` (``None`` if it tells nothing)."""
    reliability = policy(getattr(profile, "reliability", None), _RELIABILITY)
    durability = policy(getattr(profile, "durability", None), _DURABILITY)
    if reliability is None or durability is None:
        return None
    return Qos(reliability, durability)


def is_sensor_type(msgtype: Optional[str]) -> bool:
    """Whether a message type is sensor data (``sensor_msgs/...``)."""
    return bool(msgtype) and str(msgtype).split("/", 1)[0] in SENSOR_PACKAGES


def subscription_qos(publishers: Iterable[Optional[Qos]], msgtype: Optional[str]) -> Qos:
    """A subscription QoS that hears every publisher: best effort as soon as one publisher
    is best effort (a reliable subscription does not match it), transient local only when
    every publisher is (a transient-local subscription does not match a volatile one).
    Without a publisher that reports its QoS: sensor data for ``sensor_msgs`` types, the
    default otherwise."""
    known = [q for q in publishers if q is not None]
    if not known:
        return SENSOR_DATA if is_sensor_type(msgtype) else DEFAULT
    best_effort = any(q.reliability == BEST_EFFORT for q in known)
    latched = all(q.durability == TRANSIENT_LOCAL for q in known)
    return Qos(BEST_EFFORT if best_effort else RELIABLE, TRANSIENT_LOCAL if latched else VOLATILE)


def relay_qos(publishers: Iterable[Optional[Qos]], msgtype: Optional[str]) -> Qos:
    """What the relay offers on ``/m/<topic>``: the source's QoS, so the remapped
    subscribers hear it as they heard the source. With mixed publishers the offer that
    serves every subscriber that matched one of them: reliable when one publisher is (a
    reliable offer serves best-effort subscriptions too), transient local when one is."""
    known = [q for q in publishers if q is not None]
    if not known:
        return SENSOR_DATA if is_sensor_type(msgtype) else DEFAULT
    reliable = any(q.reliability == RELIABLE for q in known)
    latched = any(q.durability == TRANSIENT_LOCAL for q in known)
    return Qos(RELIABLE if reliable else BEST_EFFORT, TRANSIENT_LOCAL if latched else VOLATILE)


def qos_update(
    current: Optional[Qos],
    publishers: Sequence[Optional[Qos]],
    msgtype: Optional[str],
    choose: Callable[[Iterable[Optional[Qos]], Optional[str]], Qos] = subscription_qos,
) -> Optional[Qos]:
    """The QoS an endpoint should be (re)created with now, or ``None`` to keep it: created
    at once (from the publishers seen, else the type's default), changed when the
    publishers ask for another QoS, kept when they go away.

    >>> qos_update(None, [], "sensor_msgs/msg/Imu") == SENSOR_DATA
    True
    >>> qos_update(SENSOR_DATA, [], "sensor_msgs/msg/Imu") is None
    True
    >>> qos_update(SENSOR_DATA, [Qos(RELIABLE, VOLATILE)], "sensor_msgs/msg/Imu")
    Qos(reliability='reliable', durability='volatile')
    """
    if current is None:
        return choose(publishers, msgtype)
    if not any(q is not None for q in publishers):
        return None
    wanted = choose(publishers, msgtype)
    return wanted if wanted != current else None


# -- the graph ------------------------------------------------------------------------------


def node_name(namespace: str, name: str) -> str:
    """A node's full name from rclpy's ``(namespace, name)``.

    >>> node_name("/", "car"), node_name("/a", "car"), node_name("/a/", "car")
    ('/car', '/a/car', '/a/car')
    """
    return namespace.rstrip("/") + "/" + name


def endpoint_node(namespace: str, name: str) -> Optional[str]:
    """The full name of an endpoint's node; ``None`` while discovery has not told it.

    >>> endpoint_node("/a", "car"), endpoint_node(UNKNOWN_NAMESPACE, UNKNOWN_NAME)
    ('/a/car', None)
    """
    if namespace == UNKNOWN_NAMESPACE or name == UNKNOWN_NAME:
        return None
    return node_name(namespace, name)


def resolve_node(namespace: str, name: str) -> str:
    """A node name as given in a parameter (``car`` or ``/a/car``) resolved in
    ``namespace``."""
    return name if name.startswith("/") else node_name(namespace, name)


def system_state(view: GraphView) -> List[List[List[Any]]]:
    """The graph in the shape of the ROS 1 master's ``getSystemState`` (publishers,
    subscribers, services; each ``[name, [node, ...]]``), for ``common.logical_graph``."""
    publishers = [[t, sorted(set(ends[0]))] for t, ends in sorted(view.topics.items())]
    subscribers = [[t, sorted(set(ends[1]))] for t, ends in sorted(view.topics.items())]
    services = [[s, sorted(set(nodes))] for s, nodes in sorted(view.services.items())]
    return [publishers, subscribers, services]


def snapshot(
    view: GraphView,
    own: Iterable[str],
    topic_relays: Mapping[str, str],
    service_relays: Mapping[str, str],
    stand_ins: Optional[Mapping[str, FrozenSet[str]]] = None,
) -> Dict[str, Dict[str, Any]]:
    """The graph the invariants were learnt on: the monitor's own nodes left out, nodes on
    the relays ``/m/<name>`` counted on ``<name>``, ``ros2 bag play`` standing for the
    publishers ``stand_ins`` learnt for a topic (``common.logical_graph``)."""
    state = system_state(view)
    return common.logical_graph(state, own, topic_relays, service_relays, stand_ins)


def publisher_qos(view: GraphView, topic: str, own: Iterable[str]) -> List[Optional[Qos]]:
    """The QoS of the publishers of ``topic`` other than the monitor's own nodes."""
    mine = set(own)
    return [qos for node, qos in view.publisher_qos.get(topic, ()) if node not in mine]


# -- parameters -----------------------------------------------------------------------------

NOT_SET = 0
_PARAMETER_FIELDS = {
    1: "bool_value",
    2: "integer_value",
    3: "double_value",
    4: "string_value",
    5: "byte_array_value",
    6: "bool_array_value",
    7: "integer_array_value",
    8: "double_array_value",
    9: "string_array_value",
}
"""``rcl_interfaces/msg/ParameterType`` to the field of ``ParameterValue`` that holds it."""


def parameter_requests(
    names: Iterable[str], nodes: Iterable[str]
) -> Dict[str, List[Tuple[str, str]]]:
    """Which node to ask for which parameter: node to ``(record name, ROS 2 name)``.

    Parameters are named ``/node/param`` as in the record format; ROS 2 keeps them per
    node. The node is the longest running node whose name is a prefix of the parameter
    name (else the name's parent namespace); the rest is the parameter, ``/`` becoming
    ``.`` (ROS 2's nested names).

    >>> parameter_requests(["/a/car_ctrl/landing_radius", "/b/x"], ["/a/car_ctrl", "/a"])
    {'/a/car_ctrl': [('/a/car_ctrl/landing_radius', 'landing_radius')], '/b': [('/b/x', 'x')]}
    """
    known = sorted(set(nodes), key=len, reverse=True)
    found: Dict[str, List[Tuple[str, str]]] = {}
    for name in sorted(set(names)):
        owner = next((n for n in known if name.startswith(n.rstrip("/") + "/")), None)
        if owner is None:
            owner = name.rsplit("/", 1)[0] or "/"
        rest = name[len(owner.rstrip("/")) + 1 :]
        if rest:
            found.setdefault(owner, []).append((name, rest.replace("/", ".")))
    return dict(sorted(found.items()))


def parameter_value(value: Any) -> Any:
    """The Python value of an ``rcl_interfaces/msg/ParameterValue``; ``KeyError`` when it is
    not set (the parameter is then left out, as ROS 1 leaves out a missing one)."""
    kind = int(getattr(value, "type", NOT_SET))
    field = _PARAMETER_FIELDS.get(kind)
    if field is None:
        raise KeyError(kind)
    found = getattr(value, field)
    if kind >= 5:
        return list(found)
    return found


def parameter_answers(
    asked: Sequence[Tuple[str, str]], values: Sequence[Any]
) -> Tuple[Dict[str, Any], List[str]]:
    """A ``GetParameters`` response as ``(values by record name, names not set)``."""
    answered: Dict[str, Any] = {}
    missing: List[str] = []
    for (record, _), value in zip(asked, values):
        try:
            answered[record] = parameter_value(value)
        except KeyError:
            missing.append(record)
    missing += [record for record, _ in asked[len(values) :]]
    return answered, missing


def param_values(answers: Mapping[str, Any], names: Iterable[str]) -> Dict[str, Any]:
    """The parameters in force, flattened as the recorder flattens them."""

    def read(name: str) -> Any:
        return answers[name]

    return common.param_values(read, names)


# -- messages -------------------------------------------------------------------------------

_SEQUENCE = re.compile(r"^sequence<(?P<element>[^,>]+)(?:,\s*(?P<bound>\d+))?>$")
_ARRAY = re.compile(r"^(?P<element>[^\[]+)\[(?P<size>\d+)\]$")
_BOUNDED_STRING = re.compile(r"^w?string<=(?P<bound>\d+)$")
_INTERFACE = re.compile(
    r"^(?P<pkg>[A-Za-z][A-Za-z0-9_]*)/(?:(?P<kind>msg|srv)/)?(?P<name>[A-Za-z][A-Za-z0-9_]*)$"
)
_FLOATS = frozenset({"float", "double", "long double", "float32", "float64"})
_TIMES = frozenset({"builtin_interfaces/Time", "builtin_interfaces/Duration"})


def interface_name(name: str, kind: str = "msg") -> Tuple[str, str]:
    """The module and class of an interface type: ``pkg/msg/Name``, ``pkg/srv/Name`` or
    ``pkg/Name``; ``ValueError`` for anything else (a name from the graph is imported).

    >>> interface_name("geometry_msgs/msg/Point"), interface_name("std_srvs/Trigger", "srv")
    (('geometry_msgs.msg', 'Point'), ('std_srvs.srv', 'Trigger'))
    """
    found = _INTERFACE.match(name)
    if found is None or (found["kind"] is not None and found["kind"] != kind):
        raise ValueError(f"{name!r} is not a {kind} type name")
    return f"{found['pkg']}.{kind}", found["name"]


def fields_of(message: Any) -> Optional[Dict[str, str]]:
    """The fields of a ROS 2 message and their types (``get_fields_and_field_types``);
    ``None`` for anything else."""
    fields = getattr(message, "get_fields_and_field_types", None)
    if fields is None:
        return None
    return dict(fields())


def message_data(message: Any) -> Any:
    """A ROS 2 message as JSON-like data: nested messages as objects, arrays as lists
    (byte arrays as bytes), ``builtin_interfaces`` times and durations in seconds."""
    fields = fields_of(message)
    if fields is None:
        if isinstance(message, (bytes, bytearray)):
            return bytes(message)
        items = message.tolist() if hasattr(message, "tolist") else message  # numpy, array
        if isinstance(items, (list, tuple)):
            return [message_data(item) for item in items]
        return items
    if set(fields) == {"sec", "nanosec"}:
        return float(message.sec) + float(message.nanosec) / 1e9
    return {name: message_data(getattr(message, name)) for name in fields}


def _scalar(kind: str, value: Any, where: str) -> Any:
    if kind == "boolean":
        return check.boolean(value, where)
    if kind in check.INTEGER_RANGES:
        return check.integer(kind, value, where)
    if kind in ("octet", "byte"):
        return bytes([check.integer("uint8", value, where)])
    if kind == "char":
        if isinstance(value, str) and len(value) == 1:
            return value
        return chr(check.integer("uint8", value, where))
    if kind in _FLOATS:
        return check.number(value, where)
    bounded = _BOUNDED_STRING.match(kind)
    if kind in ("string", "wstring") or bounded:
        text = check.text(value, where)
        if bounded and len(text) > int(bounded["bound"]):
            raise FillError(f"{where}: {text!r} is longer than {bounded['bound']} characters")
        return text
    raise FillError(f"{where}: cannot fill a field of type {kind}")


def _time(kind: str, value: Any, message_class: Callable[[str], Any], where: str) -> Any:
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
        raise FillError(f"{where}: {value!r} is not a number of seconds")
    nanos = round(float(value) * 1e9)
    stamp = message_class(kind)()
    stamp.sec, stamp.nanosec = divmod(nanos, 1_000_000_000)
    return stamp


def _convert(
    current: Any, kind: str, value: Any, where: str, message_class: Callable[[str], Any]
) -> Any:
    sequence = _SEQUENCE.match(kind)
    array = _ARRAY.match(kind)
    container = sequence or array
    if container is not None:
        element = container["element"].strip()
        if not isinstance(value, list):
            raise FillError(f"{where}: {value!r} is not a list")
        if array and len(value) != int(array["size"]):
            raise FillError(f"{where}: {len(value)} values for an array of {array['size']}")
        if sequence and sequence["bound"] and len(value) > int(sequence["bound"]):
            raise FillError(f"{where}: more than {sequence['bound']} values")
        return [
            _convert(None, element, item, f"{where}[{k}]", message_class)
            for k, item in enumerate(value)
        ]
    if "/" in kind:
        if kind in _TIMES and not isinstance(value, dict):
            return _time(kind, value, message_class, where)
        if not isinstance(value, dict):
            raise FillError(f"{where}: {value!r} is not a mapping of {kind}")
        target = current if fields_of(current) is not None else message_class(kind)()
        return fill(target, value, message_class, where + ".")
    if isinstance(value, dict):
        raise FillError(f"{where}: a mapping cannot fill a field of type {kind}")
    return _scalar(kind, value, where)


fill = check.filler(lambda message: fields_of(message) or {}, _convert)
"""Set the fields of a ROS 2 message (``get_fields_and_field_types``) from an action value
(``{header: {stamp: 1.5}}``); return it (:func:`imrosc.onboard.fill.filler`)."""


# -- warnings -------------------------------------------------------------------------------

NO_MASTER = (
    "ROS 2 has no master to unregister a publisher from: the unknown publisher(s) keep "
    "publishing; imrosc only warns"
)


def note(violation: Any) -> Optional[str]:
    """What the warning adds for a violation the ROS 2 node cannot act on as ROS 1 does."""
    if common.bounds_publishers(violation.family, violation.kind):
        return NO_MASTER
    return None


def warning(
    violation: Any, actions: Sequence[str] = (), alarm: bool = True, rule: Optional[str] = None
) -> str:
    """The ``/m/broken_inv`` warning: ROS 1's JSON object (``common.violation_json``), plus
    a ``note`` when ROS 2 cannot do what ROS 1 would (unregister an unknown publisher)."""
    text = common.violation_json(violation, actions, alarm, rule)
    extra = note(violation)
    if extra is None:
        return text
    document = json.loads(text)
    document["note"] = extra
    return json.dumps(document, sort_keys=True, allow_nan=False)


def report_warning(report: common.Report) -> str:
    """The ``/m/broken_inv`` warning of a report (``common.reports``)."""
    return warning(report.violation, report.actions, report.alarm, report.rule)
