"""Alarms: when violations are worth acting on.

A violation is one invariant broken by one sample or one event; an alarm is the engine's
decision that the system is in trouble. A point's violations raise an alarm when

* **persistence**: one invariant is violated by ``persist`` consecutive samples of its point
  (or, when ``seconds`` is set, by consecutive samples spanning at least that long; a
  family the rule gives its own, :attr:`AlarmRule.families`, by its own), or
* **agreement**: ``distinct`` different invariants of the point are violated within
  ``window`` seconds,

and an *event* violation (a silent topic, an ordered pair past its maximum time, an
unexpected or missing node, an event sequence outside its pattern) raises one at once: it
is already the outcome of a timer or of a whole sequence. So does, at the first sample of
its episode, a violation that is no matter of degree (:func:`at_once`): a learnt
detector's (its threshold is the calibrated decision already) and a **frozen variable**'s,
a variance of exactly 0 over the window where every training window varied (a stuck sensor
repeats its value bit for bit; noise never does). The samples of such an episode are in
alarm until the invariant holds again.

A **severe** violation alarms at once too: a range of one scalar (bounds, array elements,
window variance, rate, mean) whose file gives it a *margin* per limit
(``params.margin``: ``{"max": [centre, limit], "min": [centre, limit]}``, set by
calibration) has a *severity*, how far the observed value lies beyond the centre in
margins (the distance from the centre to the limit; in the logarithm for a variance).
When the rule's ``severe`` threshold is set and the invariant's family is one of the
rule's ``severe_families``, a violation of severity at least the threshold raises an alarm
at the first sample of its episode (calibration sets the limit where one more normal run's
extreme lies with probability at most its share of the budget; ``docs/calibration.md``).

Agreement counts evidence, not consequences: a violation of an invariant of several
variables (a polygon, a relation) whose sample also breaks a range of one of those variables
(bounds, array elements) is not counted, since the range's violation already says it (one
variable out of its range breaks every polygon it is in). An alarm is raised once per
episode: persistence again only after the invariant held on a sample of its point,
agreement again only after fewer than ``distinct`` invariants were violated in the window.
An agreement of invariants each already in alarm (by its own persistence, or at once) raises
none: it would say again what their alarms said (under ``persist`` 1 and ``distinct`` 1 a
violation raises one alarm, not two).

``imrosc infer`` calibrates the rule on the training runs (``docs/calibration.md``) and
writes it into the invariants file as ``alarms``; a file without it gets
:data:`EVERY_VIOLATION`, under which every violation is an alarm.

>>> rule = AlarmRule(persist=3, distinct=2, window=1.0)
>>> tracker = AlarmTracker(rule)
>>> v = Violation(0.0, "a", "i1", "bounds", "upper", "x <= 1", 2.0, "<= 1")
>>> [len(tracker.sample("a", t, [v._replace(time=t)])) for t in (0.0, 0.1, 0.2, 0.3)]
[0, 0, 1, 0]
>>> tracker.sample("a", 0.4, [v._replace(time=0.4, invariant="i2")])[0].rule
'agree'
"""

from __future__ import annotations

import math
from collections import deque
from typing import Any, Deque, Dict, List, Mapping, NamedTuple, Optional, Sequence, Set, Tuple

from .families import DETECTOR, RANGED, VARIANCE
from .violation import Violation, json_safe

_IDLE = (0.0, 0.0, 0.0, 0.0)
"""The episode of an invariant not violated now: not in alarm."""
Fed = Tuple[float, str, str, int, bool, float, str, float]
"""A violating sample as calibration keeps it (:attr:`AlarmTracker.fed`)."""
RANGES = RANGED
"""Families whose invariants are the range of one variable."""
Margins = Dict[str, Tuple[Tuple[float, float, bool, bool], ...]]
"""Per invariant id, its margins: ``(centre, limit, upper, logarithmic)`` per limit."""


def margins_of(invariants: Sequence[Mapping[str, Any]]) -> Margins:
    """Per invariant id, the margins its ``params.margin`` gives (see the module's
    docstring): those whose limit lies beyond the centre (in the logarithm for a variance,
    positive values only).

    >>> inv = {"id": "i1", "family": "bounds", "params": {"margin": {"max": [1.0, 3.0]}}}
    >>> margins_of([inv])
    {'i1': ((1.0, 3.0, True, False),)}
    """
    found: Margins = {}
    for inv in invariants:
        given = inv.get("params", {}).get("margin")
        if not isinstance(given, Mapping):
            continue
        logarithmic = inv["family"] == VARIANCE
        own = []
        for side in ("max", "min"):
            pair = given.get(side)
            if not isinstance(pair, (list, tuple)) or len(pair) != 2:
                continue
            centre, limit = float(pair[0]), float(pair[1])
            if logarithmic:
                if centre <= 0 or limit <= 0:
                    continue
                centre, limit = math.log(centre), math.log(limit)
            upper = side == "max"
            if (limit > centre) if upper else (limit < centre):
                own.append((centre, limit, upper, logarithmic))
        if own:
            found[inv["id"]] = tuple(own)
    return found


def severity(margins: Tuple[Tuple[float, float, bool, bool], ...], observed: Any) -> float:
    """How far ``observed`` lies beyond the centre, in margins (the largest over the
    limits; 0 when it is not a number or lies inside every centre).

    >>> severity(((1.0, 3.0, True, False), (1.0, -1.0, False, False)), 6.0)
    2.5
    >>> severity(((1.0, 3.0, True, False),), 0.5), severity(((0.0, 1.0, False, True),), 0.0)
    (0.0, inf)
    """
    try:
        value = float(observed)
    except (TypeError, ValueError):
        return 0.0
    if math.isnan(value):
        return 0.0
    worst = 0.0
    for centre, limit, upper, logarithmic in margins:
        if logarithmic:
            if value <= 0:
                if not upper:
                    return math.inf
                continue
            value_at = math.log(value)
        else:
            value_at = value
        beyond = (value_at - centre) / (limit - centre)
        worst = max(worst, beyond)
    return worst


def shapes_of(invariants: Sequence[Mapping[str, Any]]) -> Dict[str, Tuple[bool, Tuple[str, ...]]]:
    """Per invariant id: whether it is the range of one variable, and its variables."""
    return {
        inv["id"]: (
            inv["family"] in RANGES and len(inv["variables"]) == 1,
            tuple(inv["variables"]),
        )
        for inv in invariants
    }


def at_once(violation: Violation) -> bool:
    """Whether ``violation`` raises an alarm at the first sample of its episode, whatever
    the rule: a learnt detector's, or a frozen variable's (variance exactly 0 against a
    positive minimum; see the module's docstring)."""
    family = violation.family
    return family == DETECTOR or (family == VARIANCE and violation.observed == 0.0)


class AlarmRule(NamedTuple):
    """When violations raise an alarm (see the module's docstring)."""

    persist: int = 1
    """Consecutive violating samples of one invariant (1: every violation alarms)."""
    seconds: Optional[float] = None
    """Or consecutive violating samples spanning at least this long (None: not used)."""
    distinct: int = 0
    """Distinct invariants of a point violated within ``window`` (0: not used)."""
    window: float = 1.0
    """Seconds of the agreement rule."""
    families: Tuple[Tuple[str, int, Optional[float]], ...] = ()
    """Per family, its own ``(family, persist, seconds)``: the families whose invariants
    broke in calibration's held-out runs have the persistence those showed; the others
    (and every family of a rule without them) ``persist`` and ``seconds``."""
    severe: float = 0.0
    """A violation of at least this severity (margins beyond its centre) of an invariant of
    ``severe_families`` raises an alarm at once (0: off)."""
    severe_families: Tuple[str, ...] = ()
    """The families whose severe violations alarm at once."""
    strength: Tuple[Tuple[str, float], ...] = ()
    """Per family, ``(family, summed)``: an episode of one of its invariants raises an
    alarm once the severities of its samples sum to ``summed`` (a moderate violation
    that persists)."""

    def is_severe(self, family: str, value: float) -> bool:
        """Whether a violation of ``family`` of severity ``value`` alarms at once.

        >>> rule = AlarmRule(severe=1.0, severe_families=("mean",))
        >>> rule.is_severe("mean", 1.2), rule.is_severe("mean", 0.9), rule.is_severe("bounds", 9)
        (True, False, False)
        """
        return 0 < self.severe <= value and family in self.severe_families

    def persistence(self, family: str) -> Tuple[int, Optional[float]]:
        """The ``persist`` and ``seconds`` of a family's invariants.

        >>> rule = AlarmRule(persist=50, seconds=2.0, families=(("mean", 8, 0.1),))
        >>> rule.persistence("mean"), rule.persistence("bounds")
        ((8, 0.1), (50, 2.0))
        """
        for name, persist, seconds in self.families:
            if name == family:
                return persist, seconds
        return self.persist, self.seconds

    def as_json(self) -> Dict[str, Any]:
        found: Dict[str, Any] = {
            "persist": self.persist,
            "seconds": self.seconds,
            "distinct": self.distinct,
            "window": self.window,
        }
        if self.families:
            found["families"] = {
                name: {"persist": persist, "seconds": seconds}
                for name, persist, seconds in self.families
            }
        if self.severe_families:
            found["severe"] = self.severe
            found["severe_families"] = list(self.severe_families)
        if self.strength:
            found["strength"] = {name: summed for name, summed in self.strength}
        return found

    @classmethod
    def from_json(cls, data: Optional[Mapping[str, Any]]) -> AlarmRule:
        """The rule of an invariants file's ``alarms`` (every violation alarms without it).

        >>> AlarmRule.from_json({"persist": 9, "families": {"mean": {"persist": 3}}})[:5]
        (9, None, 0, 1.0, (('mean', 3, None),))
        >>> AlarmRule.from_json({"severe": 2, "severe_families": ["rate"]})[5:7]
        (2.0, ('rate',))
        """
        if not data:
            return EVERY_VIOLATION
        seconds = data.get("seconds")
        families = []
        for name, own in sorted((data.get("families") or {}).items()):
            own_seconds = own.get("seconds")
            families.append(
                (
                    str(name),
                    max(1, int(own.get("persist", 1))),
                    None if own_seconds is None else float(own_seconds),
                )
            )
        return cls(
            max(1, int(data.get("persist", 1))),
            None if seconds is None else float(seconds),
            max(0, int(data.get("distinct", 0))),
            float(data.get("window", 1.0)),
            tuple(families),
            max(0.0, float(data.get("severe") or 0.0)),
            tuple(str(name) for name in data.get("severe_families") or ()),
            tuple(
                (str(name), float(summed))
                for name, summed in sorted((data.get("strength") or {}).items())
            ),
        )

    def overridden(self, **changes: Any) -> AlarmRule:
        """The rule with the given fields replaced (``None`` values keep the field); a
        ``persist`` or ``seconds`` given holds for every family."""
        given = {k: v for k, v in changes.items() if v is not None}
        if "persist" in given or "seconds" in given:
            given.setdefault("families", ())
            given.setdefault("strength", ())
        return self._replace(**given)


EVERY_VIOLATION = AlarmRule()


class Alarm(NamedTuple):
    """An alarm: the violation that raised it, the rule (``persist``, ``summed``, ``agree``,
    ``event``, ``severe``) and the invariants that took part."""

    time: float
    point: str
    rule: str
    invariants: Tuple[str, ...]
    violation: Violation

    def as_json(self) -> Dict[str, Any]:
        return {
            "time": self.time,
            "point": self.point,
            "rule": self.rule,
            "invariants": list(self.invariants),
            "violation": self.violation.as_json(),
        }

    def describe(self) -> str:
        """One line: why the alarm was raised."""
        v = self.violation
        if self.rule == "agree":
            why = f"{len(self.invariants)} invariants broken together"
        elif self.rule == "persist":
            why = "a violation that persists"
        elif self.rule == "summed":
            why = "a lasting shift (its severities summed)"
        elif self.rule == "severe":
            why = "a severe violation"
        elif v.family == VARIANCE:
            why = "a frozen variable"
        elif v.family == DETECTOR:
            why = "a fault detector"
        else:
            why = "an event"
        return f"alarm at {self.time:.3f} s, {self.point}: {why}; {v.invariant} {v.text}"


class AlarmTracker:
    """Turns a run's violations into alarms under one rule (one tracker per run)."""

    def __init__(
        self,
        rule: AlarmRule = EVERY_VIOLATION,
        record: bool = False,
        shapes: Optional[Mapping[str, Tuple[bool, Tuple[str, ...]]]] = None,
        margins: Optional[Margins] = None,
    ) -> None:
        self.rule = rule
        self.shapes = shapes or {}
        """Per invariant id: whether it is a range of one variable, and its variables."""
        self.margins = margins or {}
        """Per invariant id, its margins (:func:`margins_of`)."""
        self.record = record
        """Keep, for calibration, every violating sample with its episode's length."""
        self.strength = dict(rule.strength)
        """Per family, the summed severity of an episode that alarms."""
        self.reset()

    def reset(self) -> None:
        """A new run: no episode is open."""
        self._episodes: Dict[str, Dict[str, List[float]]] = {}
        """Point to invariant to ``[first time, samples, alarmed, summed severity]`` of its open
        episode."""
        self._recent: Dict[str, Deque[Tuple[float, str]]] = {}
        self._counts: Dict[str, Dict[str, int]] = {}
        """Per point: how many of ``_recent``'s entries each invariant has."""
        self._agreeing: Set[str] = set()
        self._intruders: Set[Tuple[str, str]] = set()
        """``(invariant, publisher)`` of the unknown publishers heard in this run."""
        self.raised: List[Alarm] = []
        self.fed: List[Fed] = []
        """``(time, point, invariant, samples of its episode so far, counted by agreement,
        seconds since the episode began, family, severity)`` of every violating sample
        (``record``)."""

    def severity(self, violation: Violation) -> float:
        """The violation's severity (0 for an invariant without margins)."""
        margins = self.margins.get(violation.invariant)
        return 0.0 if margins is None else severity(margins, violation.observed)

    def _at_once(self, violation: Violation) -> bool:
        """:func:`at_once`, or a severe violation under the rule."""
        if at_once(violation):
            return True
        rule = self.rule
        return (
            rule.severe > 0
            and violation.family in rule.severe_families
            and violation.invariant in self.margins
            and rule.is_severe(violation.family, self.severity(violation))
        )

    def busy(self, point: str) -> bool:
        """Whether ``point`` has an open episode (a clean sample must then be told)."""
        return bool(self._episodes.get(point))

    def sample(self, point: str, time: float, found: Sequence[Violation]) -> List[Alarm]:
        """A checked sample of ``point`` and the violations it gave (maybe none)."""
        rule = self.rule
        episodes = self._episodes.setdefault(point, {})
        now_broken = {v.invariant for v in found}
        for ident in [i for i in episodes if i not in now_broken]:
            del episodes[ident]
        raised: List[Alarm] = []
        instant = [v for v in found if self._at_once(v)] if found else []
        if instant:
            for v in instant:
                episode = episodes.get(v.invariant)
                if episode is None:  # (or a variance that fell below its minimum first)
                    episode = episodes[v.invariant] = [time, 0.0, 0.0, 0.0]
                episode[1] += 1
                if not episode[2]:
                    episode[2] = 1.0
                    why = "event" if at_once(v) else "severe"
                    raised.append(Alarm(time, point, why, (v.invariant,), v))
            ids = {id(v) for v in instant}
            found = [v for v in found if id(v) not in ids]  # nor persistence nor agreement
        counted = self.evidence(found) if found else found
        persistence = (rule.persist, rule.seconds)
        counted_ids = {id(v) for v in counted} if self.record else set()
        strength = self.strength
        for v in found:
            episode = episodes.get(v.invariant)
            if episode is None:
                episode = episodes[v.invariant] = [time, 0.0, 0.0, 0.0]
            episode[1] += 1
            summed = strength.get(v.family)
            level = self.severity(v) if summed is not None or self.record else 0.0
            if summed is not None:
                episode[3] += level
            if self.record:
                lasted = time - episode[0]
                self.fed.append(
                    (
                        time,
                        point,
                        v.invariant,
                        int(episode[1]),
                        id(v) in counted_ids,
                        lasted,
                        v.family,
                        level,
                    )
                )
            if episode[2]:
                continue
            persist, seconds = rule.persistence(v.family) if rule.families else persistence
            persisted = episode[1] >= persist or (
                seconds is not None and time - episode[0] >= seconds
            )
            if persisted or (summed is not None and episode[3] >= summed):
                episode[2] = 1.0
                why = "persist" if persisted else "summed"
                raised.append(Alarm(time, point, why, (v.invariant,), v))
        if rule.distinct > 0:
            raised += self._agree(point, time, counted)
        self.raised += raised
        return raised

    def evidence(self, found: Sequence[Violation]) -> List[Violation]:
        """The violations of one sample that agreement counts: not those of invariants of
        several variables one of which is out of its own range in the same sample."""
        shapes = self.shapes
        out: Set[str] = set()
        for v in found:
            single, names = shapes.get(v.invariant, (False, ()))
            if single:
                out.update(names)
        if not out:
            return list(found)
        kept = []
        for v in found:
            single, names = shapes.get(v.invariant, (False, ()))
            if single or not out.intersection(names):
                kept.append(v)
        return kept

    def _agree(self, point: str, time: float, found: Sequence[Violation]) -> List[Alarm]:
        recent = self._recent.setdefault(point, deque())
        distinct = self._counts.setdefault(point, {})
        for v in found:
            recent.append((time, v.invariant))
            distinct[v.invariant] = distinct.get(v.invariant, 0) + 1
        while recent and recent[0][0] < time - self.rule.window:
            ident = recent.popleft()[1]
            left = distinct[ident] - 1
            if left:
                distinct[ident] = left
            else:
                del distinct[ident]
        if len(distinct) < self.rule.distinct:
            self._agreeing.discard(point)
            return []
        if point in self._agreeing or not found:
            return []
        episodes = self._episodes.get(point, {})
        if all(episodes.get(i, _IDLE)[2] for i in distinct):
            return []  # each in alarm already: nothing new to say (until one that is not joins)
        self._agreeing.add(point)
        return [Alarm(time, point, "agree", tuple(sorted(distinct)), found[0])]

    def event(self, found: Sequence[Violation]) -> List[Alarm]:
        """Event violations (timers, graph, orderings): each raises an alarm."""
        raised = [Alarm(v.time, v.point, "event", (v.invariant,), v) for v in found]
        self.raised += raised
        return raised

    def intruder(self, found: Sequence[Violation]) -> List[Alarm]:
        """The violations of one message from a publisher its topic's ``max_pubs``
        invariants do not allow (:meth:`.arch.ArchChecks.intruder`, observed: the
        publisher): the first message of each unknown publisher raises an alarm at once (an
        event), and every message of it belongs to that alarm for the rest of the run.

        >>> tracker = AlarmTracker(AlarmRule(persist=5))
        >>> v = Violation(1.0, "d", "i1", "architecture", "max_pubs", "", ["/x"], "")
        >>> len(tracker.intruder([v])), len(tracker.intruder([v._replace(time=2.0)]))
        (1, 0)
        >>> len(tracker.alarmed([v._replace(time=2.0)], []))
        1
        """
        raised: List[Alarm] = []
        for v in found:
            key = (v.invariant, _publisher(v.observed))
            if key not in self._intruders:
                self._intruders.add(key)
                raised.append(Alarm(v.time, v.point, "event", (v.invariant,), v))
        self.raised += raised
        return raised

    def alarmed(self, found: Sequence[Violation], raised: Sequence[Alarm]) -> List[Violation]:
        """Those of ``found`` that belong to an alarm: one that ``raised`` it, or one whose
        invariant's episode or point's agreement is in alarm. A monitor withholds a blocked
        message for these, and lets the others through."""
        ids = {id(a.violation) for a in raised}
        out: List[Violation] = []
        intruders = self._intruders
        for v in found:
            episode = self._episodes.get(v.point, {}).get(v.invariant)
            if (
                id(v) in ids
                or (episode is not None and episode[2])
                or v.point in self._agreeing
                or (intruders and (v.invariant, _publisher(v.observed)) in intruders)
            ):
                out.append(v)
        return out

    def take(self) -> List[Alarm]:
        """The alarms raised since the last call."""
        raised, self.raised = self.raised, []
        return raised


def _publisher(observed: Any) -> str:
    """The publisher an intruder's violation observed (a list of one name)."""
    if isinstance(observed, (list, tuple)) and len(observed) == 1:
        return str(observed[0])
    return repr(observed)


def alarms_json(alarms: Sequence[Alarm]) -> List[Dict[str, Any]]:
    """JSON data of alarms."""
    return [json_safe(a.as_json()) for a in alarms]
