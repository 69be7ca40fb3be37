"""Held-out replays: which invariants a new run keeps, and the alarm rule.

Each fold's units are replayed (the very engine the monitor runs) against the document
learnt from the other folds, every alarm held back but events. The engine keeps every
violating sample with the length of its invariant's episode so far. From those:

1. **Stability.** An invariant that more held-out units break, even with its tolerance,
   than a break probability of ``alpha`` per run explains (:func:`.tolerance.too_many`) is
   dropped: no tolerance within the budget stabilises it.
2. **The alarm rule.** A unit would raise a persistence alarm under ``persist = K`` iff its
   longest episode reaches ``K`` samples, under ``seconds = T`` iff one lasts ``T``, an
   agreement alarm under ``distinct = D`` iff its largest agreement (distinct invariants
   of a point within the window) reaches ``D``. Each threshold lies just past the conformal
   ``1 - alpha/3`` rank of those per-unit maxima (:func:`.tolerance.conformal`; one more
   sample, one more invariant, one more millisecond), so a new nominal run raises any of
   the three alarms with probability at most ``alpha``; with too few units for that rank,
   past the normal prediction bound of one more unit's (:func:`threshold`). Samples and
   seconds both count: points run at different rates. The maxima of a fold's units are
   taken without the invariants that the *other* folds' units would drop: dropping what a
   unit itself broke would make its figures 0 by construction, and a new run is not so
   kind.

Event alarms (a silent topic, an ordering past its time, an unexpected node) cannot be
held back by a rule: an invariant whose events more than ``alpha`` of the held-out units
raise is dropped in step 1 (with fewer than ``1/alpha`` units, any).
"""

from __future__ import annotations

import math
import multiprocessing
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from types import MappingProxyType
from typing import Any, NamedTuple

from imrosc.calibrate.envelope import FoldDocument
from imrosc.calibrate.tolerance import conformal, exponential_bound, skewed_bound, too_many
from imrosc.infer.engine import Unit
from imrosc.remote import bag_path
from imrosc.runtime import Engine
from imrosc.runtime.alarms import AlarmRule, Fed
from imrosc.runtime.families import MEAN
from imrosc.runtime.families import WINDOW as WINDOW_FAMILIES

WINDOW = 1.0
"""Seconds of the agreement rule's window."""
HELD_BACK = AlarmRule(persist=1 << 30, distinct=0, window=WINDOW)
"""The rule of the held-out replays: nothing alarms but events."""
SUMMED = frozenset({MEAN})
"""The families whose episodes' severities are summed (a CUSUM of a level shift): the window
mean, the one family whose statistic estimates a level (a variance is a spread, a rate a
slope, a step one sample; ``docs/calibration.md`` section 3)."""


def trace_of(fed: Sequence[Fed], events: Sequence[str], window: float) -> dict[str, Any]:
    """What the rule of any subset of the invariants needs from a unit's violating samples
    (:attr:`imrosc.runtime.alarms.AlarmTracker.fed`) and event alarms, compactly: per
    invariant its point, family, longest episode (samples, seconds) and the times its counted
    violations cover, each violation's time widened by ``window`` and overlapping ones
    merged; and, for an invariant with margins, the largest severity of its violations
    (``severity``, absent when 0)."""
    found: dict[str, dict[str, Any]] = {}
    summed: dict[str, float] = {}
    for time, point, ident, n, counted, lasted, family, severity in fed:
        entry = found.setdefault(
            ident,
            {"point": point, "family": family, "persist": 0, "lasting": 0.0, "evidence": []},
        )
        entry["persist"] = max(entry["persist"], n)
        entry["lasting"] = max(entry["lasting"], lasted)
        if severity > entry.get("severity", 0.0):
            entry["severity"] = severity
        summed[ident] = severity + (summed.get(ident, 0.0) if n > 1 else 0.0)
        if summed[ident] > entry.get("strength", 0.0):
            entry["strength"] = summed[ident]
        if counted:
            spans = entry["evidence"]
            if spans and time <= spans[-1][1]:
                spans[-1][1] = max(spans[-1][1], time + window)
            else:
                spans.append([time, time + window])
    for ident in events:
        found.setdefault(ident, {"point": "", "persist": 0, "evidence": []})["event"] = True
    return found


@dataclass
class HeldOut:
    """One held-out unit: what it broke (its :func:`trace_of`), and (after
    :func:`calibrate_rule`) its longest episode (samples, seconds), largest agreement
    (invariants) and event alarms without the dropped invariants."""

    bag: str
    span: tuple[float, float] | None
    fold: int
    trace: dict[str, Any] = field(default_factory=dict, repr=False)
    events: list[str] = field(default_factory=list, repr=False)
    violations: int = 0
    persist: int = 0
    lasting: float = 0.0
    distinct: int = 0
    families: dict[str, tuple[int, float]] = field(default_factory=dict, repr=False)
    """Per family, its longest episode (samples, seconds)."""
    strength: dict[str, float] = field(default_factory=dict, repr=False)
    """Per family of :data:`SUMMED`, its largest summed severity of one episode."""
    event_alarms: int = 0
    absent: list[str] = field(default_factory=list, repr=False)
    """The file's invariants this unit says nothing about: its fold's document held them
    only as learnt from every unit, itself included (relations; invariants no training unit
    of the fold holds)."""
    set_breaks: list[str] = field(default_factory=list, repr=False)
    """The file's sets (one-of values, nodes) it breaks when they are learnt from its
    fold's training units alone (its replay cannot: the fold's document keeps every value)."""
    severe: list[str] = field(default_factory=list, repr=False)
    """The families in which it reached severity 1 against margins the *other* folds' units
    alone widened (:func:`.severe.check_severe`, step 2)."""

    @property
    def broken(self) -> set[str]:
        """The invariants this unit violated."""
        return set(self.trace)

    def settle(self, dropped: set[str]) -> None:
        """Its figures without the ``dropped`` invariants."""
        figures = covered(self.trace, self.broken - dropped)
        self.persist, self.lasting, self.distinct = figures[:3]
        self.families = dict(figures.families)
        self.strength = dict(figures.strength)
        self.event_alarms = sum(1 for ident in self.events if ident not in dropped)

    def as_json(self) -> dict[str, Any]:
        return {
            "bag": self.bag,
            "span": None if self.span is None else list(self.span),
            "violations": self.violations,
            "persist": self.persist,
            "lasting": self.lasting,
            "distinct": self.distinct,
            "events": self.event_alarms,
            "trace": self.trace,
            "absent": self.absent,
            "set_breaks": self.set_breaks,
            "fold": self.fold,
            "severe": self.severe,
        }


class Figures(NamedTuple):
    """A held-out unit's longest episode (samples, seconds), largest agreement, whether an
    event alarm came, and per family its longest episode (samples, seconds)."""

    persist: int
    lasting: float
    distinct: int
    event: bool
    families: Mapping[str, tuple[int, float]] = MappingProxyType({})
    strength: Mapping[str, float] = MappingProxyType({})
    """Per family of :data:`SUMMED`, the largest summed severity of one episode of its
    invariants."""


def covered(traces: Mapping[str, Mapping[str, Any]], kept: set[str]) -> Figures:
    """From one held-out unit's trace (:func:`trace_of`), with only the ``kept``
    invariants: its longest episode (samples, seconds), its largest agreement (distinct
    invariants of a point whose violations fall within one window), whether an event
    alarm came, and each family's longest episode (a trace without families: none).

    >>> trace = {"a": {"point": "p", "persist": 3, "lasting": 0.1, "evidence": [[0.0, 1.0]]},
    ...          "b": {"point": "p", "persist": 1, "evidence": [[0.5, 1.5]]},
    ...          "c": {"point": "p", "persist": 9, "lasting": 0.4, "evidence": [[5.0, 6.0]],
    ...                "event": True, "family": "mean"}}
    >>> covered(trace, {"a", "b"})[:4], covered(trace, {"a", "c"})
    ((3, 0.1, 2, False), Figures(persist=9, lasting=0.4, distinct=1, event=True, \
families={'mean': (9, 0.4)}, strength={}))
    """
    persist, lasting, event = 0, 0.0, False
    families: dict[str, tuple[int, float]] = {}
    strength: dict[str, float] = {}
    edges: dict[str, list[tuple[float, int]]] = {}
    for ident, entry in traces.items():
        if ident not in kept:
            continue
        own = int(entry.get("persist", 0)), float(entry.get("lasting", 0.0))
        persist, lasting = max(persist, own[0]), max(lasting, own[1])
        family = entry.get("family")
        if family:
            before = families.get(family, (0, 0.0))
            families[family] = (max(before[0], own[0]), max(before[1], own[1]))
            summed = float(entry.get("strength", 0.0))
            if summed > 0 and family in SUMMED:
                strength[family] = max(strength.get(family, 0.0), summed)
        event = event or bool(entry.get("event"))
        for start, end in entry.get("evidence", ()):
            edges.setdefault(str(entry.get("point", "")), []).extend(
                [(float(start), 1), (float(end), -1)]
            )
    distinct = 0
    for found in edges.values():
        open_ = 0
        for _, step in sorted(found, key=lambda e: (e[0], -e[1])):
            open_ += step
            distinct = max(distinct, open_)
    return Figures(persist, lasting, distinct, event, families, strength)


def _seconds(lasting: float) -> float:
    """Just past ``lasting`` seconds: one more millisecond."""
    return (math.floor(lasting * 1000) + 1) / 1000


def threshold(values: Sequence[float], alpha: float, resolution: float) -> tuple[float, bool]:
    """The conformal ``1 - alpha`` rank of held-out units' ``values`` when they are enough
    to certify it; with fewer, the larger of their largest value and the prediction bound
    of one more unit's, normal or log-normal whichever reaches further (the maxima are
    non-negative and right-skewed; :func:`.tolerance.skewed_bound`): whether certified.

    >>> threshold([1, 5, 2, 2, 8, 12], 0.05 / 3, 1.0)[1]
    False
    >>> round(threshold([1, 5, 2, 2, 8, 12], 0.05 / 3, 1.0)[0], 1)
    46.6
    >>> threshold(list(range(1, 70)), 0.05 / 3, 1.0)
    (69, True)
    """
    ranked, sure = conformal(values, alpha)
    if sure:
        return ranked, True
    bound = skewed_bound(values, alpha, resolution)
    return (ranked if bound is None else max(ranked, bound)), False


def summed_threshold(values: Sequence[float], alpha: float) -> float:
    """Just past one more unit's largest summed severity of ``values`` (held-out units'):
    the conformal ``1 - alpha`` rank when the units certify it, else the larger of their
    largest value and the exponential prediction bound (:func:`.tolerance.exponential_bound`:
    an episode's sum is a sum of a geometric-like number of positive terms, whose law tends
    to the exponential, and the maximum of a CUSUM has an exponential tail).

    >>> round(summed_threshold([0.0, 0.0, 11.22, 0.0, 5.87, 5.41], 0.05 / 4 / 2), 1)
    29.9
    >>> summed_threshold(list(range(69)), 0.05 / 3)
    68
    """
    ranked, sure = conformal(values, alpha)
    if sure:
        return ranked
    bound = exponential_bound(values, alpha)
    return ranked if bound is None else max(ranked, bound)


def rule_from(figures: Sequence[Figures], budget: float, parts: int = 3) -> tuple[AlarmRule, bool]:
    """The rule just past the conformal ``1 - budget/3`` rank of held-out units' longest
    episodes (samples, seconds) and largest agreements; whether they certify it. With
    ``parts=4`` the budget is split four ways: the fourth is the severe alarms'
    (:mod:`.severe`), and each of the three ranks is at ``budget/4``.

    Each window family (:data:`imrosc.runtime.families.WINDOW`: frequency, variance, rate,
    mean) whose invariants some unit broke has its own persistence, past the rank of
    the units' longest episodes of that family at ``budget / 3`` shared among those
    families, **when the units certify that rank** (``n >= 3F / budget - 1`` for ``F``
    such families). A window statistic's nominal violation lasts about as long as the
    windows that hold the odd samples, whereas a value family's (a bound, a polygon, a
    relation) lasts as long as the robot stays somewhere the training runs never went: a
    held-out landing that broke a polygon over position for 12 s makes a scaled
    accelerometer, whose window mean stays out from the onset on, wait 12 s too. But with
    fewer units each family's own threshold would be its largest held-out episode, which a
    new run exceeds with probability up to ``1/(n+1)`` per family instead of once for the
    pooled rule: the value families, a window family no unit broke, and every family
    while the units are too few, share the pooled persistence.

    When units summed the severities of an episode of a window mean (:attr:`Figures.strength`,
    with margins; :data:`SUMMED`), the rule gets that family's summed severity
    (:attr:`~imrosc.runtime.alarms.AlarmRule.strength`), past :func:`summed_threshold` of
    the units' largest sums; the persistence part of the budget is then shared between it
    and the pooled persistence.

    >>> few = [Figures(3, 0.2, 1, False, {"mean": (3, 0.2)}),
    ...        Figures(40, 2.0, 2, False, {"polygon": (40, 2.0)})]
    >>> rule_from(few, 0.05)[0].families
    ()
    >>> many = few + [Figures(0, 0.0, 0, False)] * 57
    >>> rule, sure = rule_from(many, 0.05)
    >>> rule.persistence("mean"), rule.persistence("polygon"), sure
    ((4, 0.201), (41, 2.001), True)
    """
    part = budget / parts
    strong = sorted({name for f in figures for name in f.strength})
    share = part / (1 + len(strong))
    strength = []
    for name in strong:
        summed = summed_threshold([f.strength.get(name, 0.0) for f in figures], share)
        if math.isfinite(summed) and summed > 0:
            strength.append((name, summed))
    persist, sure_persist = threshold([f.persist + 1 for f in figures], share, 1.0)
    lasting, sure_lasting = threshold([f.lasting for f in figures], share, 0.0)
    distinct, sure_distinct = threshold([f.distinct + 1 for f in figures], part, 1.0)
    names = sorted({name for f in figures for name in f.families if name in WINDOW_FAMILIES})
    share = share / max(1, len(names))
    families = []
    sure = sure_persist and sure_lasting and sure_distinct
    for name in names:
        own = [f.families.get(name, (0, 0.0)) for f in figures]
        own_persist, sure_own = conformal([p + 1 for p, _ in own], share)
        own_lasting, sure_seconds = conformal([s for _, s in own], share)
        if sure_own and sure_seconds:
            families.append((name, max(1, int(own_persist)), _seconds(own_lasting)))
    rule = AlarmRule(
        persist=max(1, int(persist)),
        seconds=_seconds(lasting),
        distinct=max(1, int(distinct)),
        window=WINDOW,
        families=tuple(families),
        strength=tuple(strength),
    )
    return rule, sure


def rule_for(document: Mapping[str, Any], kept: set[str]) -> AlarmRule | None:
    """The alarm rule of a subset of a calibrated file's invariants, from the held-out
    units' traces the file keeps (``None``: the file has none), as :func:`calibrate_rule`
    sets it."""
    calibration = document.get("calibration") or {}
    units = [u for u in calibration.get("held_out", ()) if "trace" in u]
    if not units:
        return None
    budget = float(calibration.get("budget", 0.05))
    severe = calibration.get("severe")
    parts = 3 if severe is None else 4
    rule, _ = rule_from([covered(u["trace"], kept) for u in units], budget, parts)
    if severe is not None:
        own = AlarmRule.from_json(document.get("alarms"))
        rule = rule._replace(severe=own.severe, severe_families=own.severe_families)
    return rule


def unseen_alarms(document: Mapping[str, Any], kept: set[str]) -> list[bool] | None:
    """Per held-out unit of a calibrated file (those with a trace), whether it raises an
    alarm under the rule and the severe alarms its fold's units did not set: the rule
    :func:`rule_from` gives the *other* folds' units' traces with only ``kept``, and a
    severe violation of a family the file alarms at once on, against margins the other
    folds' units alone widened (``severe``). The file's own rule was set just past every
    unit's figures, itself included, so under it a unit alarms only by chance of the
    bound; under the others' rule, as a run of a new session would (``None``: the file
    does not say which fold held each unit out).

    >>> trace = {"a": {"point": "p", "persist": 40, "lasting": 2.0, "evidence": [[0.0, 1.0]]}}
    >>> units = [{"trace": {}, "fold": 0}, {"trace": {}, "fold": 1}, {"trace": trace, "fold": 2},
    ...          {"trace": {}, "fold": 0, "severe": ["bounds"]}]
    >>> doc = {"alarms": {"persist": 41, "severe": 1.0, "severe_families": ["bounds"]},
    ...        "calibration": {"budget": 0.05, "held_out": units, "severe": {}}}
    >>> unseen_alarms(doc, {"a"})
    [False, False, True, True]
    >>> unseen_alarms({"calibration": {"held_out": [{"trace": {}}]}}, set()) is None
    True
    """
    calibration = document.get("calibration") or {}
    units = [u for u in calibration.get("held_out", ()) if "trace" in u]
    if any("fold" not in u for u in units):
        return None
    budget = float(calibration.get("budget", 0.05))
    parts = 3 if calibration.get("severe") is None else 4
    own = AlarmRule.from_json(document.get("alarms"))
    severe = set(own.severe_families) if own.severe > 0 else set()
    figures = [covered(u["trace"], kept) for u in units]
    rules: dict[Any, AlarmRule | None] = {}
    found = []
    for unit, seen in zip(units, figures, strict=True):
        fold = unit["fold"]
        if fold not in rules:
            others = [f for f, u in zip(figures, units, strict=True) if u["fold"] != fold]
            rules[fold] = rule_from(others, budget, parts)[0] if others else None
        rule = rules[fold]
        far = bool(severe & set(unit.get("severe", ())))
        found.append(far or (rule is not None and alarms_under(seen, rule)))
    return found


def alarms_under(figures: Figures, rule: AlarmRule) -> bool:
    """Whether a held-out unit with these :func:`covered` figures raises an alarm under
    ``rule`` (each family's episodes under its own persistence, when the rule and the
    figures have families).

    >>> rule = AlarmRule(persist=5, seconds=1.0, distinct=3)
    >>> [alarms_under(Figures(*f), rule) for f in [(4, 0.9, 2, False), (5, 0.2, 0, False),
    ...                                            (1, 1.0, 0, False), (1, 0.0, 3, False),
    ...                                            (0, 0.0, 0, True)]]
    [False, True, True, True, True]
    >>> own = AlarmRule(persist=50, seconds=9.0, families=(("mean", 5, 1.0),))
    >>> alarms_under(Figures(6, 0.5, 0, False, {"mean": (6, 0.5)}), own)
    True
    """
    if figures.event or (rule.distinct > 0 and figures.distinct >= rule.distinct):
        return True
    strength = dict(rule.strength)
    if any(summed >= strength.get(name, math.inf) for name, summed in figures.strength.items()):
        return True
    if not (rule.families and figures.families):
        return figures.persist >= rule.persist or (
            rule.seconds is not None and figures.lasting >= rule.seconds
        )
    for family, (persist, lasting) in figures.families.items():
        most, seconds = rule.persistence(family)
        if persist >= most or (seconds is not None and lasting >= seconds):
            return True
    return False


@dataclass(frozen=True)
class HeldOutRun:
    """A training run as calibration's held-out replays saw it: the invariants it broke
    when it was held out, and its units' traces (one per time segment, or one)."""

    broken: frozenset[str]
    traces: tuple[Mapping[str, Any], ...]
    untested: frozenset[str] = frozenset()
    """The invariants none of its units was replayed against (absent from their folds'
    documents): the run is no evidence about them."""

    def alarmed(self, kept: set[str], rule: AlarmRule) -> bool:
        """Whether any of its units raises an alarm under ``rule`` with ``kept`` only."""
        return any(alarms_under(covered(trace, kept), rule) for trace in self.traces)


def held_out_runs(document: Mapping[str, Any], base: Path) -> dict[Path, HeldOutRun]:
    """Per training bag (resolved path) of a calibrated file, what its held-out replays
    saw. A unit's bag is read as written and, when relative, also from ``base`` (the
    folder of the configuration it was inferred from)."""
    calibration = document.get("calibration") or {}
    found: dict[Path, tuple[set[str], list[Mapping[str, Any]], list[set[str]]]] = {}
    for unit in calibration.get("held_out", ()):
        trace = unit.get("trace")
        if not isinstance(trace, Mapping) or not isinstance(unit.get("bag"), str):
            continue
        written = bag_path(unit["bag"])
        places = {written.resolve()}
        if not written.is_absolute():
            places.add((base / written).resolve())
        for place in places:
            broken, traces, absent = found.setdefault(place, (set(), [], []))
            broken.update(trace)
            broken.update(str(ident) for ident in unit.get("set_breaks", ()))
            traces.append(trace)
            absent.append({str(ident) for ident in unit.get("absent", ())})
    return {
        place: HeldOutRun(frozenset(broken), tuple(traces), frozenset(set.intersection(*absent)))
        for place, (broken, traces, absent) in found.items()
    }


def _within(time: float, span: tuple[float, float] | None) -> bool:
    return span is None or span[0] <= time <= span[1]


Learnt = Mapping[str, Any] | FoldDocument
"""A fold's document, or how to build it (:class:`~.envelope.FoldDocument`)."""
Job = tuple[Learnt, dict[Path, list[tuple[float, float] | None]], int]
"""A fold's replays: the document learnt without its units, their bags and spans, the fold."""
Replays = Callable[[Sequence[Job]], list[list[HeldOut]]]
"""Replays the folds' jobs elsewhere (a cluster, :mod:`imrosc.fleet`), each fold's units in
the order of its bags."""


def built(learnt: Learnt) -> Mapping[str, Any]:
    """A fold's document (built, when it is a :class:`~.envelope.FoldDocument`)."""
    return learnt.build() if isinstance(learnt, FoldDocument) else learnt


def held_out_replayer(learnt: Learnt) -> Any:
    """The replayer of a fold's document (its engine built once; it replays bag after bag)."""
    from imrosc.replay import Replayer

    document = built(learnt)
    engine = Engine(document, rule=HELD_BACK)
    engine.alarms.record = True
    return Replayer(document, engine)


def _replay(job: Job) -> list[HeldOut]:
    """Replay a fold's bags against its document; one :class:`HeldOut` per unit span."""
    document, bags, fold = job
    replayer = held_out_replayer(document)
    found = []
    for bag, spans in bags.items():
        found += held_out(replayer, bag, spans, fold)
    return found


_JOBS: list[Job] = []
"""The jobs of :func:`calibrate_rule`'s process pool, set before it forks."""


def _replay_at(index: int) -> list[HeldOut]:
    """:func:`_replay` of the pool's job ``index`` (the jobs inherited through the fork)."""
    return _replay(_JOBS[index])


def held_out(
    replayer: Any, bag: Path, spans: list[tuple[float, float] | None], fold: int
) -> list[HeldOut]:
    """A bag's held-out units (``spans``) of ``fold``, replayed with the fold's replayer."""
    result = replayer.run(bag)
    fed = replayer.engine.alarms.fed
    found = []
    for span in spans:
        events = [
            a.violation.invariant
            for a in result.alarms
            if a.rule == "event" and _within(a.time, span)
        ]
        trace = trace_of([f for f in fed if _within(f[0], span)], events, WINDOW)
        violations = sum(1 for v in result.violations if _within(v.time, span))
        found.append(HeldOut(str(bag), span, fold, trace, events, violations))
    return found


def unstable(held_out: Sequence[HeldOut], budget: float) -> set[str]:
    """The invariants broken by more held-out units than ``budget`` explains; for an
    invariant whose violations are events (each an alarm at once), by more than ``budget``
    of them: every such break is a false alarm no rule holds back."""
    breaks: dict[str, int] = {}
    events: dict[str, int] = {}
    for unit in held_out:
        for ident in unit.broken:
            breaks[ident] = breaks.get(ident, 0) + 1
        for ident in set(unit.events):
            events[ident] = events.get(ident, 0) + 1
    found = {ident for ident, n in breaks.items() if too_many(n, len(held_out), budget)}
    return found | {ident for ident, n in events.items() if n > budget * len(held_out)}


@dataclass
class RuleResult:
    """The alarm rule, whether the units certify the budget, the invariants dropped as
    unstable, and what each held-out unit gave."""

    rule: AlarmRule
    certified: bool
    dropped: set[str]
    held_out: list[HeldOut]


def calibrate_rule(
    held: Sequence[tuple[Learnt, list[int]]],
    units: Sequence[Unit],
    budget: float,
    *,
    workers: int = 1,
    replays: Replays | None = None,
    parts: int = 3,
) -> RuleResult:
    """Replay the folds ``held`` (a document learnt without the fold's units, and their
    indexes into ``units``) in ``workers`` processes, or with ``replays`` when given, and set
    the rule for ``budget`` (split ``parts`` ways, :func:`rule_from`)."""
    jobs: list[Job] = []
    for fold, (document, indexes) in enumerate(held):
        by_bag: dict[Path, list[tuple[float, float] | None]] = {}
        for index in indexes:
            by_bag.setdefault(units[index].bag, []).append(units[index].span)
        jobs.append((document, by_bag, fold))
    if replays is not None:
        answers = replays(jobs)
    elif workers > 1 and len(jobs) > 1:
        _JOBS[:] = jobs  # inherited by the forked processes: nothing pickled to them
        try:
            with multiprocessing.get_context("fork").Pool(min(workers, len(jobs))) as pool:
                answers = pool.map(_replay_at, range(len(jobs)))
        finally:
            _JOBS.clear()
    else:
        answers = [_replay(job) for job in jobs]
    held_out = [h for answer in answers for h in answer]
    dropped = unstable(held_out, budget)
    for fold in range(len(held)):
        others = unstable([h for h in held_out if h.fold != fold], budget)
        for unit in held_out:
            if unit.fold == fold:
                unit.settle(others)
    rule, certified = rule_from(
        [
            Figures(h.persist, h.lasting, h.distinct, False, h.families, h.strength)
            for h in held_out
        ],
        budget,
        parts,
    )
    return RuleResult(rule, certified, dropped, held_out)
