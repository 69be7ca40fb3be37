"""What a monitor node decides, without ROS: plain functions both nodes call.

The ROS 1 node (``monitor_ros1/node.py``) and the ROS 2 node (``monitor_ros2/node.py``) are
middleware plumbing around the runtime engine; everything they decide alike is here, so it
is tested without rospy or rclpy: the relay names (:func:`relay_name`), the alarm rule the
engine runs under (:func:`alarm_document`), what the node does about each violation once the
engine told which raised or belong to an alarm (:func:`reports`: warn, and act only on a
newly raised alarm), whether a blocked message or call is withheld (:func:`withheld`), which
actions a batch of alarms takes (:func:`select_actions`), the JSON warning published on
``/m/broken_inv`` (:func:`violation_json`), the graph as the invariants know it once the
monitor's own relays are folded back (:func:`logical_graph`), the unknown publishers to
unregister (:func:`to_unregister`), how a service call becomes the values the engine reads
(:func:`call_values`, :func:`flatten_json`), the invariants checked before a blocked service
call is forwarded (:func:`request_document`) and the fail-open watchdog's decision
(:func:`should_relay`). Filling an action's message is each middleware's (:mod:`.fill`
checks its values).

Python 3.8 syntax, the standard library and the runtime engine (imported as ``..runtime``,
which both backends copy beside this package): this module is copied into generated
packages.

>>> select_actions([_V("a?1"), _V("v"), _V("z")], {"a": ["f"], "v": ["f", "g"]})
['f', 'g']
>>> flatten_json({"request": {"task_id": 3, "names": ["x"]}})
{'request.task_id': 3, 'len(request.names)': 1}
"""

from __future__ import annotations

import gc
import json
import re
import threading
import time
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
    Set,
    Tuple,
)

from ..runtime import families
from ..runtime.violation import json_safe
from .files import ENGINE_ERRORS, InvariantsError, SpecDocument, unknown_family

WARM = 0.002
"""Default ``~warm`` (the launch file's ``warm``): seconds between rehearsals of the latest
blocked messages while the relay is idle (0: never)."""
IDLE = 1.0
"""Seconds without a blocked message after which a node stops rehearsing."""

Snapshot = Dict[str, Dict[str, FrozenSet[str]]]
SystemState = Sequence[Sequence[Sequence[Any]]]
"""The master's ``getSystemState``: ``[publishers, subscribers, services]``, each a list of
``[name, [node, ...]]``."""


class _V(NamedTuple):
    """A stand-in violation for the examples."""

    point: str


class _A(NamedTuple):
    """A stand-in alarm for the examples."""

    point: str
    rule: str
    violation: Any


def relay_name(namespace: str, name: str) -> str:
    """Where the monitor relays ``name``: ``/m`` + ``/a/t`` = ``/m/a/t``.

    >>> relay_name("/m/", "/a/t")
    '/m/a/t'
    """
    return namespace.rstrip("/") + name


def scope_id(point: str) -> str:
    """The scope id of a point key: ``a``, ``a?1`` and ``a?x==3`` all belong to ``a``."""
    return point.split("?", 1)[0]


def select_actions(
    violations: Iterable[Any], violation_map: Mapping[str, Sequence[str]]
) -> List[str]:
    """The action ids a batch of alarms (or violations: anything with a ``point``) takes,
    each once, in the order first named."""
    taken: List[str] = []
    for violation in violations:
        for action in violation_map.get(scope_id(violation.point), ()):
            if action not in taken:
                taken.append(action)
    return taken


def alarm_document(
    document: Mapping[str, Any], overrides: Optional[Mapping[str, Any]]
) -> Mapping[str, Any]:
    """The invariants document with its alarm rule (``alarms``) overridden by the
    ``<monitor>``'s ``alarm_*`` attributes (the spec's ``alarms``): an engine built from it
    runs under ``AlarmRule.from_json(document["alarms"]).overridden(**overrides)``.

    >>> alarm_document({"alarms": {"persist": 4, "distinct": 3}}, {"distinct": 0})["alarms"]
    {'persist': 4, 'distinct': 0}

    A ``persist`` or ``seconds`` given holds for every family (the file's per-family
    persistence and summed severities go):

    >>> rule = {"persist": 40, "families": {"mean": {"persist": 8}}, "strength": {"mean": 30}}
    >>> alarm_document({"alarms": rule}, {"persist": 3})["alarms"]
    {'persist': 3}

    ``severe`` 0 turns the severe alarms off (the families stay, the threshold goes):

    >>> rule = {"persist": 40, "severe": 1.0, "severe_families": ["step"]}
    >>> alarm_document({"alarms": rule}, {"severe": 0.0})["alarms"]["severe"]
    0.0
    """
    if not overrides:
        return document
    merged = dict(document)
    alarms = dict(document.get("alarms") or {}, **overrides)
    if "persist" in overrides or "seconds" in overrides:
        alarms.pop("families", None)
        alarms.pop("strength", None)
    merged["alarms"] = alarms
    return merged


class Report(NamedTuple):
    """What the node does about one violation: warn, as an alarm or as a violation alone."""

    violation: Any
    alarm: bool
    """Whether the violation belongs to an alarm (raised it, or is part of an alarmed
    episode or agreement)."""
    rule: Optional[str]
    """The rule of the alarm it raised (``persist``, ``agree``, ``event``); ``None`` when
    it raised none."""
    actions: List[str]
    """The actions taken for it: its point's, when it raised an alarm; else none."""


def reports(
    found: Sequence[Any],
    raised: Sequence[Any],
    alarmed: Sequence[Any],
    violation_map: Mapping[str, Sequence[str]],
) -> List[Report]:
    """A report per violation of ``found``, given the alarms the engine ``raised`` with them
    and those of ``found`` that belong to an alarm (``engine.alarms.alarmed``).

    >>> v, w = _V("a"), _V("a")
    >>> [r[1:] for r in reports([v, w], [_A("a", "persist", v)], [v], {"a": ["f"]})]
    [(True, 'persist', ['f']), (False, None, [])]
    """
    belongs = {id(v) for v in alarmed}
    rules: Dict[int, str] = {}
    for alarm in raised:
        rules.setdefault(id(alarm.violation), alarm.rule)
    out: List[Report] = []
    for violation in found:
        rule = rules.get(id(violation))
        actions = list(violation_map.get(scope_id(violation.point), ())) if rule else []
        out.append(Report(violation, rule is not None or id(violation) in belongs, rule, actions))
    return out


def take_alarms(engine: Any, found: Sequence[Any]) -> Tuple[List[Any], List[Any]]:
    """Right after the engine's calls that gave ``found`` (under the node's lock, so no
    other call slips in between): the alarms raised since the last take and those of
    ``found`` that belong to an alarm."""
    raised: List[Any] = engine.take_alarms()
    return raised, engine.alarms.alarmed(found, raised)


def withheld(caused: Iterable[Any], alarmed: Sequence[Any]) -> bool:
    """Whether a blocked message (or call) is withheld: one of the violations it ``caused``
    belongs to an alarm. A violation alone lets it through.

    >>> v = _V("a")
    >>> withheld([v], [v]), withheld([v], []), withheld([], [v])
    (True, False, False)
    """
    if not alarmed:  # the relay's usual path: nothing in alarm
        return False
    belongs = {id(v) for v in alarmed}
    return any(id(v) in belongs for v in caused)


def withheld_for(caused: Iterable[Any], alarmed: Sequence[Any]) -> str:
    """The invariants, comma separated, for which a blocked call is withheld (those of the
    violations it ``caused`` that belong to an alarm)."""
    belongs = {id(v) for v in alarmed}
    return ", ".join(sorted({v.invariant for v in caused if id(v) in belongs}))


def blocked_line(topic: str, caused: Iterable[Any], alarmed: Sequence[Any]) -> str:
    """The node's log warning (throttled) when it withholds a message on a blocked topic.

    >>> from types import SimpleNamespace
    >>> v = SimpleNamespace(invariant="i1b2c3")
    >>> blocked_line("/a/cmd", [v], [v])
    'imrosc: blocked a message on /a/cmd (alarm of i1b2c3)'
    """
    return f"imrosc: blocked a message on {topic} (alarm of {withheld_for(caused, alarmed)})"


def log_line(report: Report) -> str:
    """The node's log warning of a report: an alarm (and its rule) or a violation."""
    v = report.violation
    if not report.alarm:
        return f"imrosc: violation of {v.invariant} at {v.point}: {v.text}"
    why = f" ({report.rule})" if report.rule else ""
    return f"imrosc: alarm{why}: {v.invariant} broken at {v.point}: {v.text}"


def violation_json(
    violation: Any, actions: Sequence[str] = (), alarm: bool = True, rule: Optional[str] = None
) -> str:
    """The ``/m/broken_inv`` warning: one JSON object with the invariant id, its point,
    family and kind, its text, the observed value, what was expected, the time, whether it
    belongs to an alarm (``alarm``), the rule of the alarm it raised (``rule``: ``persist``,
    ``agree``, ``event``, or ``null`` when it raised none) and the actions the monitor takes
    for it."""
    document = {
        "invariant": violation.invariant,
        "point": violation.point,
        "family": violation.family,
        "kind": violation.kind,
        "text": violation.text,
        "observed": json_safe(violation.observed),
        "expected": violation.expected,
        "time": json_safe(float(violation.time)),
        "actions": list(actions),
        "alarm": bool(alarm),
        "rule": rule,
    }
    return json.dumps(document, sort_keys=True, allow_nan=False)


class Guard:
    """The fail policy of the node's checking: the first callback that raises stops it.

    A monitor that keeps running after its checks raised would check nothing while its
    heartbeat says it is alive (and a fail-open watchdog would never take over). So each
    callback that checks runs through :meth:`run`: the first exception is handed to
    ``stop`` (which reports it on ``/m/broken_inv`` and in the log, then shuts the node
    down: fail closed, or open through the watchdog once the heartbeat stops), and every
    callback from then on does nothing and returns ``None`` (a blocked message is not
    relayed, a relayed call is refused).

    >>> stopped = []
    >>> guard = Guard(lambda where, error: stopped.append((where, str(error))))
    >>> guard.run("message /a", lambda: 1 // 0), guard.failure
    (None, 'message /a: ZeroDivisionError: integer division or modulo by zero')
    >>> guard.run("tick", lambda: 1), stopped
    (None, [('message /a', 'integer division or modulo by zero')])
    """

    def __init__(self, stop: Callable[[str, BaseException], None]) -> None:
        self.stop = stop
        self.failure: Optional[str] = None
        """What failed first (``None`` while the checks run)."""

    def run(self, where: str, function: Callable[..., Any], *args: Any) -> Any:
        """``function(*args)``, or ``None`` once the checking stopped."""
        if self.failure is not None:
            return None
        try:
            return function(*args)
        except Exception as error:
            first = self.failure is None
            if first:
                self.failure = f"{where}: {type(error).__name__}: {error}"
                self.stop(where, error)
            return None


def checks_plan(compiler: Optional[str]) -> str:
    """What the node's start-up line says of its checks: compiled by numba ``compiler`` (its
    version) in the background, or numpy alone (``None``: no numba, or ``IMROSC_NUMBA=0``).

    >>> checks_plan(None)
    'numpy checks every sample (numba is not importable, or IMROSC_NUMBA=0)'
    """
    if compiler is None:
        return "numpy checks every sample (numba is not importable, or IMROSC_NUMBA=0)"
    return f"numba {compiler} compiles the checks in the background (numpy checks until then)"


def compile_engines(engines: Sequence[Any], compiler: Optional[str]) -> str:
    """Compile the checks of ``engines`` with numba (``Engine.compile``) and say what is in
    use, for the node's log. The node runs this in a thread of its own once it relays, so
    compiling (about 1 s from numba's cache, 2-4 s the first time) does not hold back the
    first messages: numpy checks them meanwhile, and each point's compiled checks take over
    once ready (the violations are the same either way). The collector is kept off while
    numba compiles (a full collection over its objects afterwards took 70-110 ms, a stall
    of the relay) and what the compilation left is frozen out of its sight, as the node
    froze the engine's objects.

    >>> class Stub:
    ...     def compile(self): return (1, 2)
    >>> compile_engines([Stub()], "0.68.1").split(", compiled in")[0]
    'imrosc: compiled checks in use (numba 0.68.1) on 1 of 2 points (numpy checks the others)'
    >>> Stub.compile = lambda self: (0, 0)  # the invariants are all frequencies, say
    >>> compile_engines([Stub()], "0.68.1")  # doctest: +NORMALIZE_WHITESPACE
    'imrosc: numba 0.68.1 has nothing to compile (none of the invariants is of a family it
    compiles): numpy checks every sample'
    """
    started = time.monotonic()
    enabled = gc.isenabled()
    gc.disable()
    try:
        counts = [engine.compile() for engine in engines]
    finally:
        gc.freeze()
        if enabled:
            gc.enable()
    seconds = time.monotonic() - started
    compiled = sum(done for done, _ in counts)
    total = sum(of for _, of in counts)
    if not total:
        return (
            f"imrosc: numba {compiler} has nothing to compile (none of the invariants is of a "
            "family it compiles): numpy checks every sample"
        )
    if not compiled:
        return (
            f"imrosc: numba {compiler} compiled none of the checks of {total} points: numpy "
            "checks every sample"
        )
    others = "" if compiled == total else " (numpy checks the others)"
    return (
        f"imrosc: compiled checks in use (numba {compiler}) on {compiled} of {total} "
        f"points{others}, compiled in {seconds:.1f} s"
    )


class Checking:
    """What both monitor nodes hold alike, without ROS (each node's ``Monitor`` builds on
    it): the relays and actions of the spec, the engine under the spec's alarm rule, the
    request check of the blocked services (``precheck``), the lock every call of the
    engines takes, the :class:`Guard` and the graph and parameters fed last.

    >>> class Engine:
    ...     def __init__(self, document, compile): self.cleared = []
    ...     def clear(self, ident): self.cleared.append(ident); return ident == "i1"
    >>> spec = {"topics": [{"name": "/t", "relay": True}], "services": [{"name": "/s"}],
    ...         "violations": {}, "actions": {}}
    >>> checking = Checking(spec, {}, Engine, "/m", print)
    >>> checking.topic_relays, checking.service_relays, checking.precheck
    ({'/t': '/m/t'}, {'/s': '/m/s'}, None)
    >>> checking.clear_invariant("i1"), checking.clear_invariant("i9")
    (True, False)
    """

    def __init__(
        self,
        spec: SpecDocument,
        document: Mapping[str, Any],
        engine_class: Callable[..., Any],
        namespace: str,
        stop: Callable[[str, BaseException], None],
    ) -> None:
        self.spec = spec
        self.namespace = namespace
        self.topic_relays = {
            t["name"]: relay_name(namespace, t["name"]) for t in spec["topics"] if t.get("relay")
        }
        self.service_relays = {
            s["name"]: relay_name(namespace, s["name"]) for s in spec["services"]
        }
        self.blocked_services = {s["name"] for s in spec["services"] if s.get("block")}
        self.violation_map: Mapping[str, Sequence[str]] = spec["violations"]
        self.actions: Mapping[str, Mapping[str, Any]] = spec["actions"]
        self.lock = threading.Lock()
        self.guard = Guard(stop)
        """Stops the node when a check raises (docs/monitor.md, "When the monitor fails")."""
        document = alarm_document(document, spec.get("alarms"))
        unknown = unknown_family(document.get("invariants", ()), families.NAMES)
        if unknown:  # the engine would skip it
            raise InvariantsError(f"malformed: {unknown}")
        try:
            # numba compiles the checks later, in a thread of its own (:meth:`compile_checks`)
            self.engine = engine_class(document, compile=False)
            self.precheck = (
                engine_class(request_document(document, self.blocked_services), compile=False)
                if self.blocked_services
                else None
            )
        except ENGINE_ERRORS as error:  # a file edited by hand: keys or values it lacks
            what = f"missing {error}" if isinstance(error, KeyError) else str(error)
            first = f"malformed: {type(error).__name__}: {what}".splitlines()[0]
            raise InvariantsError(first) from None
        self.graph: Optional[Snapshot] = None
        self.params: Optional[Dict[str, Any]] = None
        self.last_relayed = 0.0
        """Wall time of the last message on a blocked topic (:meth:`keep_warm`)."""

    def clear_invariant(self, ident: str) -> bool:
        """Stop checking invariant ``ident`` (``/m/clear_inv``); whether the engine knew it."""
        with self.lock:
            known = bool(self.engine.clear(ident))
            if self.precheck is not None:
                self.precheck.clear(ident)
        return known

    def poll_engine(
        self, now: float, graph: Optional[Snapshot], params: Optional[Dict[str, Any]]
    ) -> Tuple[List[Any], List[Any], List[Any]]:
        """The timer's checks, with :attr:`lock` held: the clock moved to ``now``, and the
        graph and the parameters (``None``: not read this time) where they changed; the
        violations found, the alarms raised and the violations that belong to an alarm."""
        found: List[Any] = self.engine.advance(now)
        if graph is not None and graph != self.graph:
            self.graph = graph
            found += self.engine.graph(now, graph)
        if params is not None and params != self.params:
            self.params = params
            found += self.engine.params(now, params)
            if self.precheck is not None:
                self.precheck.params(now, params)
        raised, alarmed = take_alarms(self.engine, found)
        return found, raised, alarmed

    def check_values(
        self, topic: str, now: float, values: Any, publisher: Optional[str] = None
    ) -> Tuple[List[Any], List[Any], List[Any], List[Any]]:
        """A message's checks, with :attr:`lock` held: the clock moved to ``now``, the
        message's flattened ``values`` checked (``None``: a message nothing checks) and
        told to the precheck of the conditions it feeds; the violations the clock found and
        those the message caused, the alarms raised and the violations that belong to an
        alarm. ``publisher``: the node that sent it, where the middleware tells it (``None``
        for the monitor's own messages): a publisher the architecture does not know breaks
        its ``max_pubs`` invariants and nothing else (``Engine.intruder``), so on a blocked
        topic its messages are withheld and the known publishers' go on."""
        found: List[Any] = self.engine.advance(now)
        caused: List[Any] = []
        if publisher is not None:
            caused = self.engine.intruder(topic, now, publisher)
        intruder = bool(caused)
        if values is not None and not intruder:
            caused = self.engine.message(topic, now, values)
        raised, alarmed = take_alarms(self.engine, found + caused)
        precheck = self.precheck
        if (
            precheck is not None
            and values is not None
            and not intruder
            and topic in precheck.condition_topics
        ):
            precheck.message(topic, now, values)
        return found, caused, raised, alarmed

    def keep_warm(self, warm: float, running: Callable[[], bool]) -> None:
        """Between sparse messages on the blocked topics, check the latest ones again every
        ``warm`` seconds, keeping nothing (:meth:`rehearse`), while ``running()`` and the
        checks run: other processes evict the checks' code and tables from the caches, and
        a message that meets them cold waits for the relay several times longer. Nothing
        is done while messages come faster than that, nor after :data:`IDLE` seconds
        without one (docs/monitor.md)."""
        relayed = sorted(self.topic_relays)
        while running() and self.guard.failure is None:
            time.sleep(warm)
            idle = time.time() - self.last_relayed
            if warm <= idle <= IDLE:
                self.guard.run("rehearsal", self.rehearse, relayed)

    def rehearse(self, relayed: Sequence[str]) -> None:
        """One rehearsal of the latest blocked messages (``Engine.rehearse``)."""
        with self.lock:
            self.engine.rehearse(relayed)

    def compile_checks(self, compiler: str) -> str:
        """Compile the engines' checks (:func:`compile_engines`); the line to log."""
        return compile_engines([e for e in (self.engine, self.precheck) if e is not None], compiler)


def failure_json(where: str, error: BaseException, time: float) -> str:
    """The ``/m/broken_inv`` report of a check that raised (the node stops checking): the
    keys of :func:`violation_json`, ``family`` ``"monitor"``, ``kind`` ``"failure"``, an alarm
    with the rule ``"failure"``, and ``error`` the exception's type and message."""
    document = {
        "invariant": None,
        "point": None,
        "family": "monitor",
        "kind": "failure",
        "text": failure_text(where, error),
        "observed": None,
        "expected": None,
        "time": json_safe(float(time)),
        "actions": [],
        "alarm": True,
        "rule": "failure",
        "error": {"where": where, "type": type(error).__name__, "message": str(error)},
    }
    return json.dumps(document, sort_keys=True, allow_nan=False)


def failure_text(where: str, error: BaseException) -> str:
    """The log line of a check that raised."""
    return (
        f"imrosc: checking failed ({where}: {type(error).__name__}: {error}); the monitor "
        f"stops checking and shuts down"
    )


def report_json(report: Report) -> str:
    """The ``/m/broken_inv`` warning of a report (:func:`violation_json`)."""
    return violation_json(report.violation, report.actions, report.alarm, report.rule)


def _frozen(found: Mapping[str, Set[str]]) -> Dict[str, FrozenSet[str]]:
    return {name: frozenset(nodes) for name, nodes in sorted(found.items()) if nodes}


PLAYBACK = re.compile(r"^(/play_\d{10,}|/rosbag2_player)$")
"""The node ``rosbag play`` registers (``/play_<time>``, an anonymous name), and ROS 2's
``ros2 bag play`` (``/rosbag2_player``): it publishes what a bag recorded, on behalf of the
nodes that published it then."""

RECORDING = re.compile(
    r"^/(record_\d{10,}|imrosc_rosbag_\d+|imrosc_recorder_\d+|rosbag2_recorder)$"
)
"""The nodes of recording tools: ``rosbag record`` (``/record_<time>``), ``imrosc record``'s
rosbag and recording node (``/imrosc_rosbag_<pid>``, ``/imrosc_recorder_<pid>``) and ROS 2's
``ros2 bag record``. They subscribe to what they record (and imrosc's recorder serves the
services it relays): recording machinery, not the robot, so not intruders."""


def bounds_publishers(family: object, kind: object) -> bool:
    """Whether an invariant of ``family`` and ``kind`` (or a violation of one) bounds who
    publishes on a topic: the architecture invariant ``max_pubs``, whose unknown publisher a
    ROS 1 node unregisters.

    >>> bounds_publishers("architecture", "max_pubs"), bounds_publishers("bounds", "max_pubs")
    (True, False)
    """
    return family == families.ARCHITECTURE and kind == "max_pubs"


def learnt_publishers(invariants: Iterable[Mapping[str, Any]]) -> Dict[str, FrozenSet[str]]:
    """Per topic, the publishers its architecture invariants name (``max_pubs``)."""
    found: Dict[str, Set[str]] = {}
    for inv in invariants:
        if not bounds_publishers(inv.get("family"), inv.get("kind")):
            continue
        params = inv.get("params", {})
        resource, nodes = params.get("resource"), params.get("nodes")
        if isinstance(resource, str) and isinstance(nodes, list):
            found.setdefault(resource, set()).update(str(n) for n in nodes)
    return {topic: frozenset(nodes) for topic, nodes in found.items()}


def logical_graph(
    state: SystemState,
    own: Iterable[str],
    topic_relays: Mapping[str, str],
    service_relays: Mapping[str, str],
    stand_ins: Optional[Mapping[str, FrozenSet[str]]] = None,
) -> Snapshot:
    """The graph the invariants were learnt on, from the master's ``getSystemState``.

    The monitor's own nodes (``own``) are left out; a node on a relay topic ``/m/<t>`` is a
    node on ``<t>`` (the launch file remapped it there), and so is a server of a relayed
    service's ``/m/<s>`` other than the monitor. ``rosbag play`` (:data:`PLAYBACK`)
    publishing a topic stands for the publishers ``stand_ins`` learnt for it (a recording
    replayed into the monitor is not an intruder); on a topic nobody learnt it stays itself.
    Recording tools (:data:`RECORDING`) are left out, as the monitor's own nodes are.

    >>> state = [[["/t", ["/a", "/mon"]], ["/m/t", ["/mon"]]],
    ...          [["/t", ["/mon"]], ["/m/t", ["/b"]]], []]
    >>> logical_graph(state, {"/mon"}, {"/t": "/m/t"}, {})["sub"]
    {'/t': frozenset({'/b'})}
    >>> played = [[["/t", ["/play_1553088502272947227"]]], [], []]
    >>> logical_graph(played, set(), {}, {}, {"/t": frozenset({"/a"})})["pub"]
    {'/t': frozenset({'/a'})}
    >>> played2 = [[["/t", ["/rosbag2_player"]], ["/u", ["/rosbag2_player"]]], [], []]
    >>> logical_graph(played2, set(), {}, {}, {"/t": frozenset({"/a"})})["pub"]
    {'/t': frozenset({'/a'}), '/u': frozenset({'/rosbag2_player'})}
    >>> recorded = [[], [["/t", ["/b", "/record_1553088502272947227"]]], []]
    >>> logical_graph(recorded, set(), {}, {})["sub"]
    {'/t': frozenset({'/b'})}
    """
    mine = set(own)
    topics = {relay: name for name, relay in topic_relays.items()}
    services = {relay: name for name, relay in service_relays.items()}
    snapshot: Dict[str, Dict[str, Set[str]]] = {"pub": {}, "sub": {}, "srv": {}}
    for kind, entries in zip(("pub", "sub", "srv"), state):
        renames = services if kind == "srv" else topics
        for entry in entries:
            name: str = entry[0]
            nodes = entry[1]
            kept = {node for node in nodes if node not in mine and not RECORDING.match(node)}
            logical = renames.get(name, name)
            if kind == "pub" and stand_ins is not None and logical in stand_ins:
                played = {node for node in kept if PLAYBACK.match(node)}
                if played:
                    kept = (kept - played) | set(stand_ins[logical])
            if kept:
                snapshot[kind].setdefault(logical, set()).update(kept)
    return {kind: _frozen(found) for kind, found in snapshot.items()}


def to_unregister(
    violations: Iterable[Any],
    invariants: Mapping[str, Mapping[str, Any]],
    state: SystemState,
    own: Iterable[str],
    topic_relays: Mapping[str, str],
) -> List[Tuple[str, str]]:
    """``(node, topic)`` registrations to remove: the unknown publishers that broke a
    ``max_pubs`` invariant, on the topic they are registered on (the topic or its relay).

    >>> inv = {"i1": {"kind": "max_pubs", "params": {"resource": "/t", "nodes": ["/a"]}}}
    >>> v = type("V", (), {"invariant": "i1", "family": "architecture", "kind": "max_pubs",
    ...                    "observed": ["/x", "/mon"]})()
    >>> to_unregister([v], inv, [[["/t", ["/a", "/x", "/mon"]]], [], []], {"/mon"}, {})
    [('/x', '/t')]
    """
    mine = set(own)
    publishers: Dict[str, Set[str]] = {}
    for entry in state[0] if state else ():
        publishers.setdefault(entry[0], set()).update(entry[1])
    found: List[Tuple[str, str]] = []
    for violation in violations:
        if not bounds_publishers(violation.family, violation.kind):
            continue
        invariant = invariants.get(violation.invariant)
        if invariant is None:
            continue
        resource = invariant.get("params", {}).get("resource")
        if not isinstance(resource, str):
            continue
        places = [resource] + ([topic_relays[resource]] if resource in topic_relays else [])
        observed = violation.observed
        nodes = [observed] if isinstance(observed, str) else list(observed or ())
        for node in nodes:
            if node in mine:
                continue
            for topic in places:
                pair = (node, topic)
                if node in publishers.get(topic, ()) and pair not in found:
                    found.append(pair)
    return found


def flatten_json(value: Any, prefix: str = "") -> Dict[str, Any]:
    """Scalars of JSON-like data by dotted path; a list gives its length as ``len(path)``
    (as the translator flattens recorded calls and parameters)."""
    if isinstance(value, dict):
        out: Dict[str, Any] = {}
        for key, item in value.items():
            out.update(flatten_json(item, f"{prefix}.{key}" if prefix else str(key)))
        return out
    if isinstance(value, (list, tuple, bytes, bytearray)):
        return {f"len({prefix})": len(value)}
    if value is None:
        return {}
    return {prefix: value}


def call_values(
    data_of: Callable[[Any], Any], request: Any, response: Any, delay: float
) -> Dict[str, Any]:
    """The values of a service call as the engine reads them: ``request.*``,
    ``response.*`` and ``delay``; ``data_of`` gives a message as JSON-like data (each
    middleware's ``message_data``).

    >>> call_values(dict, {"task_id": 3}, {"ok": True}, 0.25)
    {'request.task_id': 3, 'response.ok': True, 'delay': 0.25}
    """
    values = flatten_json({"request": data_of(request), "response": data_of(response)})
    values["delay"] = delay
    return values


def request_values(data_of: Callable[[Any], Any], request: Any) -> Dict[str, Any]:
    """The values of a request alone (checked before a blocked call is forwarded)."""
    return flatten_json({"request": data_of(request)})


def request_document(document: Mapping[str, Any], services: Iterable[str]) -> Dict[str, Any]:
    """The invariants document reduced to the invariants of call points of ``services``
    that read the request alone (no response, no delay, no window or sequence): an engine
    built from it checks a request before the node forwards it."""
    wanted = set(services)
    points = document.get("points", {})
    kept: List[Any] = []
    for invariant in document.get("invariants", ()):
        info = points.get(invariant.get("point"), {})
        if info.get("kind") != "call" or info.get("trigger") not in wanted:
            continue
        if invariant.get("family") in families.WINDOW | families.EVENT:
            continue
        paths = {v.get("name"): v.get("path", "") for v in info.get("variables", ())}
        names = invariant.get("variables") or ()
        if names and all(str(paths.get(name, "")).startswith("request.") for name in names):
            kept.append(invariant)
    reduced = dict(document)
    reduced["invariants"] = kept
    return reduced


def param_values(read: Callable[[str], Any], names: Iterable[str]) -> Dict[str, Any]:
    """The parameters in force, flattened (``/node/gains.p``); ``read`` raises ``KeyError``
    for a parameter that is not set, which is left out."""
    values: Dict[str, Any] = {}
    for name in names:
        try:
            value = read(name)
        except KeyError:
            continue
        values.update(flatten_json(value, name))
    return values


STARTUP = 5.0
"""Least default ``startup`` of a watchdog: seconds it waits for the monitor's first beat
before it fails open (a monitor imports numpy and loads its invariants before it beats,
which took over a second on a loaded machine)."""


def should_relay(
    last_beat: Optional[float], now: float, timeout: float, started: float, startup: float
) -> bool:
    """The fail-open watchdog's decision: relay while the monitor's heartbeat has been
    silent for more than ``timeout`` seconds; stop as soon as it beats again. Before the
    first beat (``last_beat`` ``None``) relay once ``startup`` seconds passed since the
    watchdog ``started``: a monitor starting slowly is not a monitor that died, and a
    watchdog that failed open meanwhile would relay beside it until it noticed the beat.

    >>> should_relay(10.0, 12.0, 3.0, 0.0, 5.0), should_relay(10.0, 13.5, 3.0, 0.0, 5.0)
    (False, True)
    >>> should_relay(None, 4.0, 1.0, 0.0, 5.0), should_relay(None, 5.5, 1.0, 0.0, 5.0)
    (False, True)
    """
    if last_beat is None:
        return now - started > startup
    return now - last_beat > timeout
