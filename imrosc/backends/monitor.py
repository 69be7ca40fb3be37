"""The monitor to synthesize, as typed data shared by the ``ros1`` and ``ros2`` backends.

:func:`monitor_spec` reads the passed IR, the ``<monitor>``'s invariants file and what the bags
and the graph tell, checks every name, type and field path that will reach a generated file,
and returns a :class:`MonitorSpec`: the package and node names, the topics the node subscribes
to (with their ROS 1 ``pkg/Type`` and ROS 2 ``pkg/msg/Type`` names and the Python expression of
each flattened value), the blocked topics and the services it relays, the actions, the
violation map from scope ids to action ids, the parameters it polls, its period, the
``<monitor>``'s overrides of the invariants file's alarm rule and the paths inside the
package. Templates only format a spec; every decision is taken here.

Checks (each failure is a diagnostic naming the file, and nothing is rendered):

* a ``<monitor>`` exists (``monitor-missing``) and its invariants file loads
  (``invariants-unreadable``);
* every topic, service and parameter name is a valid global ROS name (``bad-name``);
* every message type is ``pkg/Type`` or ``pkg/msg/Type`` (``bad-type-name``);
* every field path is a chain of Python identifiers, none a keyword, with at most one
  trailing ``[index]`` (``bad-field-path``): a path becomes attribute access in generated
  code, so nothing else may reach it;
* the project gives a valid ROS package name (``bad-package-name``).

>>> flat_expression("pose.position.x", "float", None)
'float(m.pose.position.x)'
>>> flat_expression("ranges", "float", "avg")
'avg_(m.ranges)'
>>> flat_expression("values[3]", "float", None)
'float(at_(m.values, 3))'
>>> ros_types("geometry_msgs/msg/PoseStamped")
('geometry_msgs', 'geometry_msgs/PoseStamped', 'geometry_msgs/msg/PoseStamped')
>>> scope_id("a?cmd.data==3"), scope_id("a")
('a', 'a')
"""

from __future__ import annotations

import json
import keyword
import math
import re
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from imrosc import ir
from imrosc.backends.registry import BuildInputs
from imrosc.diagnostics import Diagnostic, make
from imrosc.invariants import InvariantsFileError, load
from imrosc.onboard.files import SPEC_FORMAT, SPEC_VERSION, SpecDocument
from imrosc.onboard.monitor import relay_name
from imrosc.runtime import Engine
from imrosc.runtime.points import Pairing
from imrosc.schema.names import BAD_NAME, check_graph_name, is_global_name

NAMESPACE = "/m"
"""Where the node publishes its warnings and relays blocked topics (thesis 4.3)."""
INVARIANTS_PATH = "config/invariants.json"

VARIABLE_TYPES = frozenset({"float", "int", "uint", "bool", "string", "time", "bytes"})
STATISTICS = {"len": "len_", "avg": "avg_", "std": "std_", "min": "min_", "max": "max_"}
"""Derived statistics and the helper function that computes each (``flat.py``)."""
HELPERS = ("at_", *STATISTICS.values())
"""Every helper of ``flat.py`` a flattener expression may call."""

_IDENTIFIER = r"[A-Za-z][A-Za-z0-9_]*"
"""A ROS message field name: a letter, then letters, digits and underscores."""
_PATH = re.compile(
    rf"(?P<fields>{_IDENTIFIER}(?:\.{_IDENTIFIER})*)(?:\[(?P<index>[0-9]{{1,9}})\])?"
)
_TYPE = re.compile(r"(?P<pkg>[A-Za-z][A-Za-z0-9_]*)/(?:msg/)?(?P<name>[A-Za-z][A-Za-z0-9_]*)")
_PACKAGE = re.compile(r"[a-z][a-z0-9_]*")


class SpecError(ValueError):
    """A value that cannot be rendered safely."""


def scope_id(point: str) -> str:
    """The scope id of a point key (``a``, ``a?1``, ``a?x==3``: the part before ``?``)."""
    return point.split("?", 1)[0]


def ros_types(msgtype: str) -> tuple[str, str, str]:
    """``(package, ROS 1 name, ROS 2 name)`` of ``pkg/Type`` or ``pkg/msg/Type``."""
    found = _TYPE.fullmatch(msgtype)
    if found is None:
        raise SpecError(f"message type {msgtype!r} is not pkg/Type or pkg/msg/Type")
    pkg, name = found["pkg"], found["name"]
    return pkg, f"{pkg}/{name}", f"{pkg}/msg/{name}"


def check_path(path: str) -> tuple[str, int | None]:
    """The fields and element index of a field path; :class:`SpecError` if it is not safe."""
    found = _PATH.fullmatch(path)
    if found is None:
        raise SpecError(
            f"field path {path!r} is not a chain of field names (a letter, then letters, digits "
            "and '_') with an optional [index]"
        )
    for part in found["fields"].split("."):
        if keyword.iskeyword(part):
            raise SpecError(f"field path {path!r} uses the Python keyword {part!r}")
    index = found["index"]
    return found["fields"], (int(index) if index is not None else None)


def flat_expression(path: str, kind: str, derived: str | None) -> str:
    """The Python expression of one flattened value of a message ``m`` (``flat.py`` helpers
    give the statistics), as ``imrosc.runtime.flatten.make_flattener`` computes it when no
    field is missing."""
    fields, index = check_path(path)
    if derived is not None:
        if derived not in STATISTICS:
            raise SpecError(f"unknown derived statistic {derived!r} of {path!r}")
        if index is not None:
            raise SpecError(f"a statistic of the element {path!r}")
        return f"{STATISTICS[derived]}(m.{fields})"
    if kind not in VARIABLE_TYPES:
        raise SpecError(f"unknown variable type {kind!r} of {path!r}")
    access = f"m.{fields}" if index is None else f"at_(m.{fields}, {index})"
    return f"str({access})" if kind == "string" else f"float({access})"


def careful_expression(path: str, derived: str | None) -> str:
    """The raw value behind one flattened value, for the per-field fallback."""
    fields, index = check_path(path)
    if derived is not None:
        return f"{STATISTICS[derived]}(m.{fields})"
    return f"m.{fields}" + (f"[{index}]" if index is not None else "")


@dataclass(frozen=True)
class FlatValue:
    """One flattened value of a topic: its name, the fast and the careful expression."""

    name: str
    text: bool
    expression: str
    careful: str


@dataclass(frozen=True)
class TopicSpec:
    """A topic the node subscribes to.

    ``flattener`` is the generated function's name (``None`` for a blocked topic that no
    invariant watches: relayed unchecked); ``relay`` is ``/m/<topic>`` for a blocked topic.
    Types are ``None`` when neither the invariants file nor the bags know them (the node asks
    the master at run time).
    """

    name: str
    package: str | None
    ros1_type: str | None
    ros2_type: str | None
    flattener: str | None
    values: tuple[FlatValue, ...]
    relay: str | None


@dataclass(frozen=True)
class ServiceSpec:
    """A service the node relays: served on ``relay``, forwarded to ``name``; ``block`` says
    whether a call that breaks an invariant is refused (else only checked)."""

    name: str
    relay: str
    block: bool


@dataclass(frozen=True)
class ActionSpec:
    """Publish ``value`` on ``destination`` (``/m/<topic>`` when the topic is blocked, so the
    message reaches the remapped subscribers directly) or call a service with it."""

    id: str
    target: str
    name: str
    destination: str
    package: str | None
    ros1_type: str | None
    ros2_type: str | None
    value: Mapping[str, Any]


@dataclass(frozen=True)
class MonitorSpec:
    """Everything a monitor backend renders."""

    project: str
    source: str
    package: str
    node: str
    watchdog: str
    namespace: str
    period: float
    invariants_source: str
    invariants: Mapping[str, Any]
    topics: tuple[TopicSpec, ...]
    services: tuple[ServiceSpec, ...]
    actions: tuple[ActionSpec, ...]
    violations: Mapping[str, tuple[str, ...]]
    params: tuple[str, ...]
    launch: str | None
    depends: tuple[str, ...]
    invariants_path: str = INVARIANTS_PATH
    alarms: Mapping[str, int | float] = field(default_factory=dict)
    """The ``<monitor>``'s overrides of the invariants file's alarm rule (``persist``,
    ``seconds``, ``distinct``, ``window``, ``severe``; only the given ones)."""
    launch_ros2: str | None = None
    """The ``<monitor>``'s ``launch_ros2``: the system's ROS 2 launch XML, which the ``ros2``
    backend rewrites instead of ``launch``."""

    @property
    def topic_relays(self) -> dict[str, str]:
        """Blocked topic to relay topic."""
        return {t.name: t.relay for t in self.topics if t.relay is not None}

    @property
    def service_relays(self) -> dict[str, str]:
        """Relayed service to the name the node serves."""
        return {s.name: s.relay for s in self.services}

    def runtime_document(self, banner: str) -> SpecDocument:
        """What the node reads at start (``spec.json``): plain JSON data, never code."""
        return {
            "$comment": banner,
            "format": SPEC_FORMAT,
            "version": SPEC_VERSION,
            "project": self.project,
            "package": self.package,
            "node": self.node,
            "watchdog": self.watchdog,
            "namespace": self.namespace,
            "period": self.period,
            "topics": [
                {"name": t.name, "type": t.ros1_type, "ros2_type": t.ros2_type, "relay": t.relay}
                for t in self.topics
            ],
            "services": [
                {"name": s.name, "relay": s.relay, "block": s.block} for s in self.services
            ],
            "actions": {
                a.id: {
                    "target": a.target,
                    "name": a.name,
                    "destination": a.destination,
                    "type": a.ros1_type,
                    "ros2_type": a.ros2_type,
                    "value": a.value,
                }
                for a in self.actions
            },
            "violations": {key: list(ids) for key, ids in self.violations.items()},
            "params": list(self.params),
            "alarms": dict(self.alarms),
        }


def dumps(document: Mapping[str, Any]) -> bytes:
    """Deterministic JSON bytes (NaN and infinities as JSON's extensions, which Python reads)."""
    return (json.dumps(document, indent=1, ensure_ascii=False) + "\n").encode("utf-8")


def json_value(value: Any) -> Any:
    """An IR action value (frozen: tuples) as JSON data."""
    if isinstance(value, Mapping):
        return {str(k): json_value(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [json_value(v) for v in value]
    return value


class _Checker:
    """Collects diagnostics while a spec is built."""

    def __init__(self, config: str, inv_label: str, inv_text: str) -> None:
        self.config = config
        self.inv_label = inv_label
        self.inv_text = inv_text
        self.found: list[Diagnostic] = []

    def in_invariants(self, code: str, message: str, needle: str) -> None:
        line, column = _locate(self.inv_text, json.dumps(needle, ensure_ascii=False))
        self.found.append(make(self.inv_label, line, column, code, message))

    def in_config(self, code: str, message: str, span: ir.Span) -> None:
        self.found.append(make(self.config, span.line, span.column, code, message))

    def name(self, name: Any, kind: str, where: str, span: ir.Span | None = None) -> bool:
        """Whether ``name`` is a valid global ROS name; report it otherwise."""
        text = name if isinstance(name, str) else repr(name)
        problems = check_graph_name(name, kind) if isinstance(name, str) else []
        bad = [p.message for p in problems if p.code == BAD_NAME]
        if not isinstance(name, str):
            bad = [f"{kind} name {text} is not a string"]
        elif not bad and not is_global_name(name):
            bad = [f"{kind} name {name!r} is not global"]
        if not bad:
            return True
        message = f"{where}: {bad[0]}"
        if span is None:
            self.in_invariants(BAD_NAME, message, text)
        else:
            self.in_config(BAD_NAME, message, span)
        return False


def _valid_name(name: str) -> bool:
    problems = check_graph_name(name, "topic")
    return is_global_name(name) and not any(p.code == BAD_NAME for p in problems)


def _locate(text: str, needle: str) -> tuple[int, int]:
    """1-based line and column of the first ``needle`` in ``text`` (1:1 if absent)."""
    at = text.find(needle)
    if at < 0:
        return 1, 1
    line = text.count("\n", 0, at) + 1
    return line, at - (text.rfind("\n", 0, at) + 1) + 1


def _types(check: _Checker, msgtype: Any, topic: str) -> tuple[str | None, str | None, str | None]:
    if msgtype is None:
        return None, None, None
    try:
        if not isinstance(msgtype, str):
            raise SpecError(f"message type {msgtype!r} is not a string")
        return ros_types(msgtype)
    except SpecError as error:
        check.in_invariants("bad-type-name", f"topic {topic}: {error}", str(msgtype))
        return None, None, None


def _values(check: _Checker, topic: str, variables: Any) -> tuple[FlatValue, ...]:
    values: list[FlatValue] = []
    if not isinstance(variables, list):
        check.in_invariants("bad-field-path", f"topic {topic}: variables are not a list", topic)
        return ()
    for variable in variables:
        path = variable.get("path") if isinstance(variable, dict) else None
        try:
            if not isinstance(path, str):
                raise SpecError(f"variable {variable!r} has no field path")
            kind, derived = variable.get("type"), variable.get("derived")
            if derived is not None and not isinstance(derived, str):
                raise SpecError(f"derived {derived!r} of {path!r} is not a statistic")
            values.append(
                FlatValue(
                    str(variable.get("name", path)),
                    kind == "string" and derived is None,
                    flat_expression(path, str(kind), derived),
                    careful_expression(path, derived),
                )
            )
        except SpecError as error:
            check.in_invariants("bad-field-path", f"topic {topic}: {error}", str(path))
    return tuple(values)


def _document_names(check: _Checker, document: Mapping[str, Any]) -> tuple[set[str], set[str]]:
    """Check the names the points use; return the services and parameters they watch. The
    engine was built from ``document`` first, so every point's pairing reads."""
    services: set[str] = set()
    params: set[str] = set()
    points = document.get("points")
    if not isinstance(points, dict):
        check.in_invariants(BAD_NAME, "'points' is not an object", "points")
        return services, params
    for key, info in sorted(points.items()):
        if not isinstance(info, dict):
            continue
        kind = info.get("kind")
        where = f"point {key}"
        trigger = info.get("trigger", "")
        if kind == "call" and check.name(trigger, "service", where):
            services.add(trigger)
        elif kind == "param" and check.name(trigger, "parameter", where):
            params.add(trigger)
        elif kind == "publish":
            check.name(trigger, "topic", where)
        pairing = Pairing.from_json(info)
        for name in pairing.inputs:
            check.name(name, "topic", where)
        for name in pairing.params:
            if check.name(name, "parameter", where):
                params.add(name)
        for _, event_kind, name in pairing.events:
            is_call = event_kind == "call"
            if check.name(name, "service" if is_call else "topic", where) and is_call:
                services.add(name)
        for condition in pairing.filters:
            if condition.topic is not None:
                check.name(condition.topic, "topic", where)
    return services, params


def package_name(project: str) -> str:
    """The monitor package of a project: ``<project>_monitor``."""
    return f"{project}_monitor"


def monitor_spec(inputs: BuildInputs) -> MonitorSpec | None:
    """The spec of the project's monitor; ``None`` (with diagnostics appended to
    ``inputs.diagnostics``) when something cannot be rendered safely."""
    project = inputs.project
    monitor = project.monitor
    if monitor is None:
        inputs.diagnostics.append(
            make(
                project.source,
                project.span.line,
                project.span.column,
                "monitor-missing",
                "a monitor backend needs a <monitor> element in the configuration",
            )
        )
        return None
    base = Path(project.source).parent
    inv_path = base / monitor.inv
    inv_label = str(inv_path)
    try:
        document = load(inv_path)
        text = inv_path.read_text(encoding="utf-8")
    except (InvariantsFileError, OSError, UnicodeDecodeError) as error:
        inputs.diagnostics.append(
            make(
                project.source,
                monitor.span.line,
                monitor.span.column,
                "invariants-unreadable",
                f"invariants file of <monitor>: {error}",
            )
        )
        return None
    learnt_for = document.get("project")
    if learnt_for is not None and learnt_for != project.name:
        inputs.diagnostics.append(
            make(
                project.source,
                monitor.span.line,
                monitor.span.column,
                "project-mismatch",
                f"{inv_label} was inferred for project {learnt_for!r}, not {project.name!r}",
            )
        )
    try:
        Engine(document)  # what the node does first: a file it cannot load fails the build
    except Exception as error:  # any failure: the document is malformed
        inputs.diagnostics.append(
            make(
                project.source,
                monitor.span.line,
                monitor.span.column,
                "invariants-unreadable",
                f"invariants file of <monitor>: {inv_label}: the runtime engine cannot load it "
                f"({type(error).__name__}: {error})",
            )
        )
        return None
    check = _Checker(project.source, inv_label, text)
    package = package_name(project.name)
    if not _PACKAGE.fullmatch(package):
        check.in_config(
            "bad-package-name",
            f"project {project.name!r} gives the package name {package!r}; a ROS package name "
            "is lowercase letters, digits and '_', starting with a letter",
            project.span,
        )
    spec = _build(inputs, monitor, document, check, package, inv_label)
    inputs.diagnostics.extend(check.found)
    if any(d.severity.value == "error" for d in check.found):
        return None
    return spec


def _build(
    inputs: BuildInputs,
    monitor: ir.Monitor,
    document: Mapping[str, Any],
    check: _Checker,
    package: str,
    inv_label: str,
) -> MonitorSpec:
    project = inputs.project
    namespace = NAMESPACE
    watched_services, params = _document_names(check, document)
    topics_doc = document.get("topics")
    if not isinstance(topics_doc, dict):
        check.in_invariants(BAD_NAME, "'topics' is not an object", "topics")
        topics_doc = {}
    graph_services = set(inputs.graph.services()) if inputs.graph is not None else set()
    call_services = {p.service for p in project.points if isinstance(p, ir.CallPoint)}
    known_services = watched_services | graph_services | call_services
    for name in monitor.block:
        check.name(name, "blocked topic or service", "<block>", monitor.span)
    blocked_topics = [n for n in monitor.block if n not in known_services]
    blocked_services = {n for n in monitor.block if n in known_services}

    types: dict[str, Any] = {name: known.msgtype for name, known in inputs.topic_types.items()}
    topics: list[TopicSpec] = []
    names = sorted(set(topics_doc) | set(blocked_topics))
    for number, name in enumerate(names):
        info = topics_doc.get(name)
        if name in topics_doc and not check.name(name, "topic", "topics"):
            continue
        if name not in topics_doc and not _valid_name(name):
            continue  # a bad blocked name: reported at <block> above
        msgtype = info.get("type") if isinstance(info, dict) else types.get(name)
        pkg, ros1, ros2 = _types(check, msgtype, name)
        values = _values(check, name, info.get("variables")) if isinstance(info, dict) else ()
        topics.append(
            TopicSpec(
                name,
                pkg,
                ros1,
                ros2,
                f"flatten_{number}" if isinstance(info, dict) else None,
                values,
                relay_name(namespace, name) if name in blocked_topics else None,
            )
        )
    services = tuple(
        ServiceSpec(name, relay_name(namespace, name), name in blocked_services)
        for name in sorted(watched_services | blocked_services)
    )
    known_types = {t.name: t for t in topics}
    actions: list[ActionSpec] = []
    for action in monitor.actions:
        check.name(action.name, action.target, f"action {action.id}", action.span)
        pkg = ros1 = ros2 = None
        if action.target == "topic":
            known = known_types.get(action.name)
            if known is not None and known.ros1_type is not None:
                pkg, ros1, ros2 = known.package, known.ros1_type, known.ros2_type
            elif action.name in types:
                pkg, ros1, ros2 = _types(check, types[action.name], action.name)
            else:
                check.in_config(
                    "action-type-unknown",
                    f"action {action.id}: no invariants file or bag knows the type of "
                    f"{action.name}; the node asks the master for it at run time",
                    action.span,
                )
        relay = relay_name(namespace, action.name)
        destination = (
            relay if action.target == "topic" and action.name in blocked_topics else action.name
        )
        actions.append(
            ActionSpec(
                action.id,
                action.target,
                action.name,
                destination,
                pkg,
                ros1,
                ros2,
                json_value(action.value),
            )
        )
    violations: dict[str, list[str]] = {}
    for rule in monitor.violations:
        for point in rule.points:
            taken = violations.setdefault(point, [])
            taken += [a for a in rule.actions if a not in taken]
    depends = sorted(
        {t.package for t in topics if t.package} | {a.package for a in actions if a.package}
    )
    period = monitor.period if math.isfinite(monitor.period) and monitor.period > 0 else 1.0
    return MonitorSpec(
        project=project.name,
        source=project.source,
        package=package,
        node=package,
        watchdog=f"{package}_watchdog",
        namespace=namespace,
        period=period,
        invariants_source=inv_label,
        invariants=document,
        topics=tuple(topics),
        services=services,
        actions=tuple(actions),
        violations={key: tuple(ids) for key, ids in sorted(violations.items())},
        params=tuple(sorted(params)),
        launch=monitor.launch,
        launch_ros2=monitor.launch_ros2,
        depends=tuple(depends),
        alarms=monitor.alarms.given(),
    )


def invariants_copy(spec: MonitorSpec, banner: str) -> bytes:
    """The invariants file as the package carries it: the same document, marked as generated
    (so a rebuild may overwrite it) and naming where it was copied from."""
    document: dict[str, Any] = {
        "$comment": f"{banner}; copied from {spec.invariants_source}",
        **{k: v for k, v in spec.invariants.items() if k != "$comment"},
    }
    return dumps(document)


def flattener_helpers(spec: MonitorSpec) -> list[str]:
    """The helpers of ``imrosc/onboard/flat.py`` the generated flatteners call."""
    used = {"careful"} if any(t.flattener for t in spec.topics) else set()
    for topic in spec.topics:
        for value in topic.values:
            used |= {name for name in HELPERS if f"{name}(" in value.expression}
    return sorted(used)
