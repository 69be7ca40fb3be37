"""The engine: program points rebuilt online from what happens, checked as it happens.

A publish point's sample is its topic's message paired with the latest message of each
input topic and the latest parameter values (Algorithm 1, online); a sample whose inputs
have not all been seen yet is not checked, as inference did not learn from it. A call
point's sample is a service call (request, response, delay), a parameter point's a
parameter value, an architecture point's a graph snapshot (at every change and every
second), a temporal point's an event. Conditional points check only the samples their
conditions accept: a declared ``<condition>`` on its topic's latest message, a discovered
``variable == value`` on the sample itself.
"""

from __future__ import annotations

import math
import operator
from typing import (
    Any,
    Callable,
    Dict,
    FrozenSet,
    List,
    Mapping,
    Optional,
    Sequence,
    Tuple,
    Union,
)

import numpy as np

from .alarms import Alarm, AlarmRule, AlarmTracker, margins_of, shapes_of
from .arch import ArchChecks, Snapshot
from .checks import Checks, WindowChecks
from .compiled import numba_module
from .conditions import holds
from .detector import Detector
from .families import DETECTOR, INTERVAL, MEAN, PATTERN, RATE, STEP, VARIANCE
from .points import Pairing
from .temporal import IntervalMachine, PatternMachine
from .violation import Violation
from .windows import Windows

_FLOAT64 = np.dtype(np.float64)
ARCH_PERIOD = 1.0
"""Seconds between two checks of the architecture in force (inference samples it so)."""
PARAMS = "@params"

Found = List[Violation]
Trace = Callable[[str, float, Any, Optional[float]], None]
"""``trace(point, time, sample, frequency)``: called for every sample a point checks."""

NUMERIC_TYPES = ("float", "int", "uint", "bool", "time")
"""The variable types a point's sample vector holds (the others are strings or sets)."""


WINDOW_VALUES: Dict[str, Callable[[Windows], Any]] = {
    VARIANCE: Windows.variance,
    RATE: Windows.rate,
    MEAN: Windows.mean,
    STEP: Windows.step,
}
"""Each window family's values of the current window, per tracked variable."""


def _number(value: Any) -> float:
    try:
        return float(value)
    except (TypeError, ValueError):
        return math.nan


def _picker(positions: Sequence[int]) -> Callable[[Sequence[Any]], Sequence[Any]]:
    """A function picking ``positions`` of a sequence, as a list or tuple."""
    if len(positions) == 1:
        only = positions[0]
        return lambda values: (values[only],)
    if not positions:
        return lambda values: ()
    return operator.itemgetter(*positions)


class _Point:
    """One program point: where its values come from, its checks and its windows."""

    def __init__(
        self,
        key: str,
        info: Mapping[str, Any],
        invariants: List[Mapping[str, Any]],
        compile: bool = True,
        lazy: bool = False,
    ):
        self.key = key
        self.kind: str = info["kind"]
        self.trigger: str = info.get("trigger", "")
        pairing = Pairing.from_json(info)
        self.inputs = pairing.inputs
        self.params = pairing.params
        self.filters = pairing.filters
        variables = info["variables"]
        self.variables = variables
        numeric = [v for v in variables if v["type"] in NUMERIC_TYPES]
        strings = [v for v in variables if v["type"] == "string"]
        self.numeric_names = [v["name"] for v in numeric]
        self.string_names = [v["name"] for v in strings]
        index = {name: k for k, name in enumerate(self.numeric_names)}
        self.numeric_index = index
        self.direct = False
        """A publish point whose row is its one source's values as they are (the engine sets
        it)."""
        self.plain = False
        """A direct point with no condition, no strings and no windows: checking a sample is
        checking the row (the engine sets it)."""
        string_index = {name: k for k, name in enumerate(self.string_names)}
        stats = [v["name"] for v in numeric if v.get("derived") in ("avg", "std")]
        self.invariants = invariants
        self.checks = Checks(invariants, index, string_index, stats, compile, lazy)
        tracked = [
            v["name"] for v in numeric if v.get("trigger", True) and v.get("derived") is None
        ]
        self.tracked_at = np.asarray([index[n] for n in tracked], dtype=np.int64)
        self.window_checks = WindowChecks(invariants, tracked)
        self.windows: Optional[Windows] = None
        if self.window_checks.active:
            self.windows = Windows(self.window_checks.window, len(tracked))
        # a conditional point is silent whenever its condition does not hold: no timer
        self.min_frequency = (
            min([float(i["params"]["min"]) for i in self.window_checks.frequency] + [math.inf])
            if not self.filters
            else 0.0
        )
        self.silent = False
        """The timer reported a silence that the frequency has not recovered from yet (its
        lower bounds are not reported again meanwhile)."""
        self.gap = False
        """A conditional point's condition did not hold at its last sample: its windows
        restart at the next sample it accepts (an episode of the condition begins)."""
        self.detectors = [
            Detector(inv, index)
            for inv in invariants
            if inv["family"] == DETECTOR and all(n in index for n in inv["variables"])
        ]
        """The learnt fault detectors of the point (``imrosc classify``)."""
        self.arch = ArchChecks(invariants, key) if self.kind == "arch" else None
        self.intervals: List[IntervalMachine] = []
        self.patterns: List[PatternMachine] = []
        for inv in invariants:
            if inv["family"] == INTERVAL:
                self.intervals.append(IntervalMachine(inv, key))
            elif inv["family"] == PATTERN:
                self.patterns.append(PatternMachine(inv, key))
        self.events: Dict[Tuple[str, str], str] = {
            (kind, name): ident for ident, kind, name in pairing.events
        }

    def reset(self) -> None:
        self.checked = 0
        """Samples checked in this run (conditions accepted, inputs all seen)."""
        if self.windows is not None:
            self.windows.reset()
        for detector in self.detectors:
            detector.reset()
        self.silent = False
        self.gap = False
        if self.arch is not None:
            self.arch.reset()
        for machine in self.intervals:
            machine.reset()
        for pattern in self.patterns:
            pattern.reset()

    def accepts(self, row: Any, latest: Mapping[str, Any], texts: Sequence[Any] = ()) -> bool:
        """Whether every condition of the point holds for this sample (``texts``: its
        string values, in ``string_names`` order)."""
        for condition in self.filters:
            if condition.variable is not None:
                if condition.variable in self.numeric_index:
                    value = row[self.numeric_index[condition.variable]]
                elif condition.variable in self.string_names and texts:
                    # a discovered condition may be on a discrete string (``mode=='land'``)
                    value = texts[self.string_names.index(condition.variable)]
                else:
                    return False
                if value != condition.value:
                    return False
            else:
                message = latest.get(condition.topic or "")
                if message is None:
                    return False
                fields = {path: message.get(name, math.nan) for path, name in condition.fields}
                if not holds(condition.expression, fields):
                    return False
        return True

    def sample(
        self, time: float, row: Any, strings: Sequence[Any], trace: Optional[Trace]
    ) -> Found:
        """Check one sample that passed the point's conditions."""
        found = self.checks.check(time, self.key, row, strings)
        frequency: Optional[float] = None
        if self.windows is not None:
            defined = self.windows.add(time, row[self.tracked_at])
            windows = self.windows
            frequency = windows.frequency()
            if defined:
                # a silence reported by the timer lasts until the frequency is back up
                self.silent = self.silent and frequency < self.window_checks.recovered

                def derived(family: str) -> Any:
                    return WINDOW_VALUES[family](windows)

                found += self.window_checks.check(
                    time, self.key, frequency, derived, self.checks.cleared, self.silent
                )
            else:
                frequency = None
        for detector in self.detectors:
            broken = detector.sample(time, row, self.key)
            if broken is not None and broken.invariant not in self.checks.cleared:
                found.append(broken)
        if trace is not None:
            trace(self.key, time, row, frequency)
        return found

    def silence(self, now: float, size: int, last: float) -> Found:
        """The violations of a silence found at ``now``: ``size`` messages in the window,
        the last at ``last`` (the frequency lower bounds even one more message misses)."""
        windows = self.windows
        assert windows is not None
        expected_at_most = (size + 1) / windows.window
        found: Found = []
        for inv in self.window_checks.frequency:
            lo = float(inv["params"]["min"])
            if inv["id"] in self.checks.cleared or expected_at_most >= lo:
                continue
            found.append(
                Violation(
                    now,
                    self.key,
                    inv["id"],
                    inv["family"],
                    inv["kind"],
                    inv["text"],
                    size / windows.window,
                    f"at least {lo} Hz (no message for {now - last:.3g} s)",
                )
            )
        return found

    def tick(self, now: float) -> Found:
        """Timers: a silent topic (frequency lower bound), intervals past their maximum."""
        found: Found = []
        windows = self.windows
        if (
            windows is not None
            and not self.silent
            and self.min_frequency > 0
            and windows.defined_at(now)
            and (windows.size_at(now) + 1) / windows.window < self.min_frequency
        ):
            self.silent = True
            found += self.silence(now, windows.size_at(now), windows.last_time())
        for machine in self.intervals:
            found += machine.tick(now)
        return found


class Engine:
    """Checks the invariants of an invariants document against what happens.

    ``document`` is the parsed invariants file. ``trace`` (optional) sees every checked
    sample (reports draw trajectories and frequencies with it). Every method returns the
    violations it found; the alarms they raise under the file's rule (``alarms``, or
    ``rule`` when given) are collected by :meth:`take_alarms`. ``compile=False`` leaves
    the compiling of the checks by numba to :meth:`compile` (a monitor node does it in a
    thread of its own once it relays; numpy checks every sample until then). ``lazy=True``
    builds each point's polygon lookup tables at their first use instead of here (a replay,
    which checks most samples over column chunks without them; a monitor has them ready
    before its first message).
    """

    def __init__(
        self,
        document: Mapping[str, Any],
        trace: Optional[Trace] = None,
        rule: Optional[AlarmRule] = None,
        compile: bool = True,
        lazy: bool = False,
    ) -> None:
        self.document = document
        self.trace = trace
        self.alarm_rule = rule if rule is not None else AlarmRule.from_json(document.get("alarms"))
        self.alarms = AlarmTracker(
            self.alarm_rule,
            shapes=shapes_of(document["invariants"]),
            margins=margins_of(document["invariants"]),
        )
        self.layouts: Dict[str, List[Mapping[str, Any]]] = {
            topic: list(info["variables"]) for topic, info in document["topics"].items()
        }
        by_point: Dict[str, List[Mapping[str, Any]]] = {}
        for inv in document["invariants"]:
            by_point.setdefault(inv["point"], []).append(inv)
        self.points: Dict[str, _Point] = {
            key: _Point(key, info, by_point.get(key, []), compile, lazy)
            for key, info in sorted(document["points"].items())
        }
        self.by_id: Dict[str, Tuple[_Point, Mapping[str, Any]]] = {
            inv["id"]: (self.points[inv["point"]], inv)
            for inv in document["invariants"]
            if inv["point"] in self.points
        }
        # where each point's values come from, per source (a topic or the parameters)
        self._numeric_at: Dict[str, Dict[str, int]] = {}
        self._string_at: Dict[str, Dict[str, int]] = {}
        for topic, variables in self.layouts.items():
            numeric = [v["name"] for v in variables if v["type"] in NUMERIC_TYPES]
            strings = [v["name"] for v in variables if v["type"] == "string"]
            self._numeric_at[topic] = {name: k for k, name in enumerate(numeric)}
            self._string_at[topic] = {name: k for k, name in enumerate(strings)}
        self._publish: Dict[str, List[_Point]] = {}
        self._calls: Dict[str, List[_Point]] = {}
        self._param_points: List[_Point] = []
        self._arch_points: List[_Point] = []
        self._events: Dict[Tuple[str, str], List[_Point]] = {}
        self._gather: Dict[str, Tuple[List[str], Any, Any]] = {}
        self.condition_topics = set()
        for point in self.points.values():
            for condition in point.filters:
                if condition.topic:
                    self.condition_topics.add(condition.topic)
            if point.kind == "publish":
                self._publish.setdefault(point.trigger, []).append(point)
                self._gather[point.key] = self._plan_gather(point)
            elif point.kind == "call":
                self._calls.setdefault(point.trigger, []).append(point)
            elif point.kind == "param":
                self._param_points.append(point)
            elif point.kind == "arch":
                self._arch_points.append(point)
            for source in point.events:
                self._events.setdefault(source, []).append(point)
        self._split: Dict[str, Tuple[Any, Any]] = {}
        for topic, variables in self.layouts.items():
            numeric = [k for k, v in enumerate(variables) if v["type"] in NUMERIC_TYPES]
            strings = [k for k, v in enumerate(variables) if v["type"] == "string"]
            self._split[topic] = (
                None if numeric == list(range(len(variables))) else _picker(numeric),
                _picker(strings) if strings else None,
            )
        for key, (sources, gather, _) in self._gather.items():
            # one source whose numeric values are the row as they are
            self.points[key].direct = (
                len(sources) == 1
                and not self.points[key].params
                and gather.tolist() == list(range(len(self._numeric_at.get(sources[0], {}))))
            )
        for point in self.points.values():
            point.plain = (
                point.direct
                and not point.filters
                and not point.string_names
                and not point.windows
                and not point.detectors
            )
        self._publish_events = {
            name: points for (kind, name), points in self._events.items() if kind == "publish"
        }
        self._timed = [
            p for p in self.points.values() if p.intervals or (p.windows and p.min_frequency > 0)
        ]
        self._guard_publishers()
        self.reset()

    def _guard_publishers(self) -> None:
        """Per topic that a ``max_pubs`` invariant bounds, the architecture points that bound
        it (:attr:`guarded`) and the publishers every one of them allows (:attr:`known`: the
        common case, told apart by a set lookup)."""
        self.guarded: Dict[str, List[_Point]] = {}
        bounds: Dict[str, List[FrozenSet[str]]] = {}
        for point in self._arch_points:
            assert point.arch is not None
            for topic in sorted({item[1] for item in point.arch.items}):
                nodes = point.arch.publisher_bounds(topic)
                if nodes:
                    self.guarded.setdefault(topic, []).append(point)
                    bounds.setdefault(topic, []).extend(nodes)
        self.known: Dict[str, FrozenSet[str]] = {
            topic: frozenset.intersection(*sets) for topic, sets in bounds.items()
        }

    def compile(self) -> Tuple[int, int]:
        """Compile every point's value checks with numba where it can (:mod:`.compiled`),
        unless done already: how many points with value invariants now have them compiled,
        of how many. Safe while another thread checks samples (:meth:`Checks.compile`)."""
        compiled = total = 0
        for point in self.points.values():
            done = point.checks.compile()
            if point.checks.numeric_families():
                total += 1
                compiled += done
        return compiled, total

    @staticmethod
    def compiler() -> Optional[str]:
        """numba's version where the checks can be compiled; ``None`` without numba (not
        importable, or ``IMROSC_NUMBA=0``)."""
        numba = numba_module()
        return None if numba is None else str(getattr(numba, "__version__", "?"))

    def _plan_gather(self, point: _Point) -> Tuple[List[str], Any, Any]:
        """Sources of a publish point, and where each of its values sits in them."""
        sources = [point.trigger] + [t for t in point.inputs if t != point.trigger]
        offsets: Dict[str, int] = {}
        size = 0
        for source in sources:
            offsets[source] = size
            size += len(self._numeric_at.get(source, {}))
        params_at = size
        numeric: List[int] = []
        for name in point.numeric_names:
            for source in sources:
                found = self._numeric_at.get(source, {}).get(name)
                if found is not None:
                    numeric.append(offsets[source] + found)
                    break
            else:  # a parameter (or a value the layout lacks): from the parameters, or NaN
                numeric.append(params_at + point.params.index(name) if name in point.params else -1)
        strings: List[Tuple[str, int]] = []
        for name in point.string_names:
            for source in sources:
                found = self._string_at.get(source, {}).get(name)
                if found is not None:
                    strings.append((source, found))
                    break
            else:
                strings.append((PARAMS if name in point.params else "", -1))
        return sources, np.asarray(numeric, dtype=np.int64), strings

    # -- what happens ------------------------------------------------------------------------

    def reset(self) -> None:
        """A new run (bag): forget the latest values, windows and machines."""
        self.latest_numeric: Dict[str, Any] = {}
        self.latest_strings: Dict[str, List[str]] = {}
        self.latest_named: Dict[str, Dict[str, Any]] = {}
        self.latest_params: Dict[str, Any] = {}
        self.params_seen = False
        self.snapshot: Optional[Snapshot] = None
        self.snapshot_kinds: Sequence[str] = ("pub", "sub", "srv")
        self.next_arch: Optional[float] = None
        for point in self.points.values():
            point.reset()
        self.alarms.reset()

    def checked(self) -> Dict[str, int]:
        """Per value point (publish, call, parameter), the samples it checked in this run."""
        return {
            key: point.checked
            for key, point in self.points.items()
            if point.kind in ("publish", "call", "param")
        }

    def take_alarms(self) -> List[Alarm]:
        """The alarms raised since the last call (or the last :meth:`reset`)."""
        return self.alarms.take()

    def end_run(self) -> Found:
        """A recorded run ends: the violations of ordered-pair intervals still open and still
        within their maximum time, which the caller should withdraw (inference neither
        records nor checks an interval its run did not close); an interval whose maximum
        time ran out before the end stays reported. A live monitor never calls this."""
        found: Found = []
        for point in self.points.values():
            for machine in point.intervals:
                found += machine.unfinished()
        return found

    def rehearse(self, topics: Sequence[str]) -> None:
        """Check the latest message of each topic again and keep nothing: no state changes,
        no violations returned. A monitor calls it between sparse messages so that the next
        one meets the checks' code and tables in the caches (points whose sample is the
        message alone; the others keep state, and are left out)."""
        for topic in topics:
            row = self.latest_numeric.get(topic)
            if row is None:
                continue
            for point in self._publish.get(topic, ()):
                if point.plain:
                    point.checks.rehearse(row)

    def clear(self, invariant: str) -> bool:
        """Stop checking one invariant (``/m/clear_inv``); whether it was known."""
        found = self.by_id.get(invariant)
        if found is None:
            return False
        point, _ = found
        point.checks.cleared.add(invariant)
        point.invariants = [i for i in point.invariants if i["id"] != invariant]
        point.intervals = [m for m in point.intervals if m.invariant["id"] != invariant]
        point.patterns = [m for m in point.patterns if m.invariant["id"] != invariant]
        point.detectors = [d for d in point.detectors if d.invariant["id"] != invariant]
        if point.arch is not None:
            point.arch.items = [item for item in point.arch.items if item[4]["id"] != invariant]
            self._guard_publishers()
        return True

    def hand_over(self, keys: Sequence[str]) -> None:
        """Stop checking the publish points ``keys`` here: another checker takes their
        samples (``imrosc.checking`` checks a bag's points over column chunks); their
        messages still update the latest values and feed the events."""
        gone = set(keys)
        for topic, points in self._publish.items():
            self._publish[topic] = [p for p in points if p.key not in gone]
        self._timed = [p for p in self._timed if p.key not in gone]

    def next_due(self) -> float:
        """A time before which :meth:`advance` reports nothing (a little early: the timers
        decide exactly); ``-inf`` when a window's silence timer may report at any time.
        It changes with every call that feeds the engine."""
        due = math.inf
        for point in self._timed:
            if point.windows is not None and point.min_frequency > 0:
                return -math.inf
            for machine in point.intervals:
                if machine.opened is not None and not machine.timed_out:
                    late = machine.opened + machine.max_time
                    due = min(due, late - 1e-6 * max(1.0, abs(late)))
        if self.next_arch is not None:
            due = min(due, self.next_arch)
        return due

    def published(self, topic: str, time: float) -> Found:
        """A message on ``topic`` as an event only (the temporal points that hear of it),
        for a topic whose values no point here reads."""
        found: Found = []
        for point in self._publish_events.get(topic, ()):
            found += self._event(point, time, point.events[("publish", topic)])
        return found

    def intruder(self, topic: str, time: float, publisher: str) -> Found:
        """Whether a message on ``topic`` from ``publisher`` (its node) comes from a
        publisher the architecture does not know: the violations of the ``max_pubs``
        invariants of ``topic`` in force (their point's condition holds) that do not allow
        it, each an alarm at the publisher's first message and every message of it in that
        alarm (:meth:`AlarmTracker.intruder`); empty when the publisher is allowed or no
        invariant in force bounds the topic. Such a message is not the system's data: its
        values are checked by no other invariant (:meth:`message` refuses it)."""
        points = self.guarded.get(topic)
        if points is None or publisher in self.known[topic]:
            return []
        found: Found = []
        for point in points:
            assert point.arch is not None
            if point.filters and not point.accepts(np.empty(0), self.latest_named):
                continue
            found += point.arch.intruder(time, topic, publisher)
        if found:
            self.alarms.intruder(found)
        return found

    def message(
        self,
        topic: str,
        time: float,
        values: Union[Sequence[Any], np.ndarray],
        publisher: Optional[str] = None,
    ) -> Found:
        """A message on ``topic`` flattened in the order of its layout (the file's
        ``topics[topic].variables``): a sequence of values, or a float64 array of them (kept
        as the latest values, not copied; it must not change afterwards). ``publisher``
        (its node, where the source tells it): a message of a publisher the architecture
        does not know (:meth:`intruder`) gives the architecture's violations only and is
        otherwise ignored: no other invariant checks it, it is no topic's latest value and
        no event, so the data invariants check what the known publishers send."""
        found = self.advance(time) if self._timed else []
        if publisher is not None and topic in self.guarded:
            refused = self.intruder(topic, time, publisher)
            if refused:
                return found + refused
        split = self._split.get(topic)
        if split is not None:
            numeric_of, strings_of = split
            numeric = values if numeric_of is None else numeric_of(values)
            if type(numeric) is np.ndarray and numeric.dtype == _FLOAT64:
                array = numeric  # a monitor's reader gave the values as they lie in the bytes
            else:
                try:
                    # fromiter with a count: a third quicker than np.array over a list
                    array = np.fromiter(numeric, np.float64, len(numeric))
                except (TypeError, ValueError):
                    array = np.array([_number(v) for v in numeric], dtype=np.float64)
            self.latest_numeric[topic] = array
            if strings_of is not None:
                self.latest_strings[topic] = [str(v) for v in strings_of(values)]
            if topic in self.condition_topics:
                layout = self.layouts[topic]
                self.latest_named[topic] = {v["name"]: values[k] for k, v in enumerate(layout)}
            for point in self._publish.get(topic, ()):
                if point.plain and self.trace is None:
                    # the common case: the message is the row, nothing else to do
                    point.checked += 1
                    broken = point.checks.check(time, point.key, array)
                    if broken or self.alarms.busy(point.key):
                        self.alarms.sample(point.key, time, broken)
                        found += broken
                else:
                    found += self._publish_sample(point, time)
        events = self._publish_events.get(topic)
        if events is not None:
            for point in events:
                found += self._event(point, time, point.events[("publish", topic)])
        return found

    def _publish_sample(self, point: _Point, time: float) -> Found:
        sources, gather, strings = self._gather[point.key]
        if point.direct:
            row = self.latest_numeric[point.trigger]
        else:
            parts = []
            for source in sources:
                part = self.latest_numeric.get(source)
                if part is None:
                    return []
                parts.append(part)
            if point.params:
                if not self.params_seen:
                    return []
                params = [_number(self.latest_params.get(p)) for p in point.params]
                parts.append(np.asarray(params, np.float64))
            parts.append(np.full(1, np.nan))  # index -1: a value no source has
            row = np.concatenate(parts)[gather] if len(gather) else np.empty(0)
        if not strings:
            return self._check(point, time, row, ())
        texts = [
            self.latest_strings[source][at]
            if source not in ("", PARAMS)
            else str(self.latest_params.get(point.string_names[k], ""))
            for k, (source, at) in enumerate(strings)
        ]
        return self._check(point, time, row, texts)

    def _check(self, point: _Point, time: float, row: Any, texts: Sequence[Any]) -> Found:
        if point.filters:
            if not point.accepts(row, self.latest_named, texts):
                point.gap = True
                return []
            if point.gap:  # an episode of its condition begins: so do its windows
                point.gap = False
                if point.windows is not None:
                    point.windows.reset()
        point.checked += 1
        broken = point.sample(time, row, texts, self.trace)
        if broken or self.alarms.busy(point.key):
            self.alarms.sample(point.key, time, broken)
        return broken

    def call(self, service: str, time: float, values: Mapping[str, Any]) -> Found:
        """A service call: ``values`` by field path (``request.a``, ``response.b``,
        ``delay``)."""
        found = self.advance(time)
        for point in self._calls.get(service, ()):
            if point.params and not self.params_seen:
                continue
            by_path = {v["name"]: values.get(v["path"]) for v in point.variables}
            for name in point.params:
                by_path[name] = self.latest_params.get(name)
            row = np.asarray([_number(by_path.get(n)) for n in point.numeric_names], np.float64)
            texts = ["" if by_path.get(n) is None else str(by_path[n]) for n in point.string_names]
            found += self._check(point, time, row, texts)
        for point in self._events.get(("call", service), ()):
            found += self._event(point, time, point.events[("call", service)])
        return found

    def params(self, time: float, values: Mapping[str, Any]) -> Found:
        """Parameter values (flattened: ``/node/gain``), the whole set in force."""
        found = self.advance(time)
        self.latest_params = dict(values)
        self.params_seen = True
        for point in self._param_points:
            if point.trigger not in values:
                continue
            value = values[point.trigger]
            if point.numeric_names:
                row = np.asarray([_number(value)], np.float64)
                found += self._check(point, time, row, [])
            else:
                found += self._check(point, time, np.empty(0), [str(value)])
        return found

    def graph(
        self, time: float, snapshot: Snapshot, kinds: Sequence[str] = ("pub", "sub", "srv")
    ) -> Found:
        """The graph changed: ``snapshot`` maps ``pub``/``sub``/``srv`` to resource to
        node names; ``kinds`` says which of them the source can tell."""
        found = self.advance(time)
        self.snapshot = snapshot
        self.snapshot_kinds = tuple(kinds)
        if self.next_arch is None:
            self.next_arch = time + ARCH_PERIOD
        return found + self._arch(time)

    def _arch(self, time: float) -> Found:
        found: Found = []
        if self.snapshot is None:
            return found
        for point in self._arch_points:
            assert point.arch is not None
            if point.filters and not point.accepts(np.empty(0), self.latest_named):
                continue
            found += point.arch.check(time, self.snapshot, self.snapshot_kinds)
        self.alarms.event(found)
        return found

    def _event(self, point: _Point, time: float, event: str) -> Found:
        found: Found = []
        for machine in point.intervals:
            found += machine.event(time, event)
        for pattern in point.patterns:
            found += pattern.event(time, event)
        self.alarms.event(found)
        return found

    def advance(self, now: float) -> Found:
        """The clock reached ``now``: run the timers that are due."""
        found: Found = []
        for point in self._timed:
            found += point.tick(now)
        if found:
            self.alarms.event(found)
        while self.next_arch is not None and self.next_arch <= now:
            found += self._arch(self.next_arch)
            self.next_arch += ARCH_PERIOD
        return found
