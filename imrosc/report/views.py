"""Documents read into prepared views: sorted, grouped, every value already spelled.

The text renderer and the HTML templates both read these views, so the two say the same
thing; neither decides anything. Charts are prepared separately (``imrosc.report.svg``)
from the raw plot data each run view carries along.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

from imrosc.report.values import (
    UNDEFINED,
    finite,
    fraction,
    number,
    percent,
    plural,
    seconds,
    value,
)

# ---------------------------------------------------------------------------------- replay


@dataclass(frozen=True)
class Episode:
    """One violation episode of a run: an invariant broken from ``first`` to ``last``."""

    time: str
    until: str
    offset: float
    end_offset: float
    point: str
    invariant: str
    family: str
    kind: str
    text: str
    observed: str | None
    expected: str | None
    count: int

    @property
    def category(self) -> str:
        """Family and kind, as ``bounds/range``."""
        return f"{self.family}/{self.kind}" if self.kind else self.family

    @property
    def comparison(self) -> str:
        """``observed 4.1, expected [-2.1, 3.7]``, or what of it the episode tells."""
        parts = []
        if self.observed is not None:
            parts.append(f"observed {self.observed}")
        if self.expected is not None:
            parts.append(f"expected {self.expected}")
        return ", ".join(parts)

    @property
    def repeat(self) -> str:
        """``(37x until 14.100 s)`` for an episode of more than one violation, else empty."""
        return f"({self.count}x until {self.until})" if self.count > 1 else ""


@dataclass(frozen=True)
class RaisedAlarm:
    """An alarm of a run: when (from the run's start), where, by which rule, and the
    violation that raised it."""

    time: str
    offset: float
    point: str
    rule: str
    invariants: int
    invariant: str
    text: str


def raised_alarm(data: Mapping[str, Any], start: float) -> RaisedAlarm:
    """An alarm of a replay document's run."""
    at = _float(data.get("time"), start)
    violation = data.get("violation") or {}
    return RaisedAlarm(
        time=seconds(at - start),
        offset=at - start,
        point=_text(data.get("point")),
        rule=_text(data.get("rule")),
        invariants=len(data.get("invariants") or ()),
        invariant=_text(violation.get("invariant")),
        text=_text(violation.get("text")),
    )


@dataclass(frozen=True)
class Run:
    """One replayed bag."""

    bag: str
    start: float
    end: float
    messages: int
    skipped: int
    error: str | None
    violations: int
    episodes: list[Episode]
    alarms: list[RaisedAlarm] = field(default_factory=list)
    polygons: list[Mapping[str, Any]] = field(default_factory=list)
    frequencies: list[Mapping[str, Any]] = field(default_factory=list)
    warnings: list[str] = field(default_factory=list)
    """What the run could not check (topics of the invariants missing from the bag)."""
    checked: dict[str, int] = field(default_factory=dict)
    """Per value point, the samples it checked."""

    @property
    def duration(self) -> float:
        """Seconds from the first to the last message (0 for an empty or unreadable bag)."""
        span = self.end - self.start
        return span if math.isfinite(span) and span > 0 else 0.0

    @property
    def violated(self) -> bool:
        """Whether the run broke any invariant."""
        return self.violations > 0 or bool(self.episodes)

    @property
    def summary(self) -> str:
        """Messages, duration, violations and episodes; or why the bag could not be read."""
        if self.error is not None:
            return f"unreadable: {self.error}"
        parts = [f"{plural(self.messages, 'message')} over {seconds(self.duration)}"]
        if self.skipped:
            parts.append(f"{self.skipped} skipped")
        if self.violated:
            parts.append(
                f"{plural(self.violations, 'violation')} in {plural(len(self.episodes), 'episode')}"
            )
        else:
            parts.append("no violations")
        if self.alarms:
            parts.append(f"{plural(len(self.alarms), 'alarm')}, the first at {self.alarms[0].time}")
        else:
            parts.append("no alarm")
        return ", ".join(parts)


@dataclass(frozen=True)
class Replay:
    """A replay document."""

    invariants: str
    project: str | None
    runs: list[Run]

    @property
    def summary(self) -> str:
        """``3 runs, 1 with violations, 1 unreadable``."""
        violated = sum(1 for r in self.runs if r.violated)
        alarmed = sum(1 for r in self.runs if r.alarms)
        parts = [
            plural(len(self.runs), "run"),
            f"{violated} with violations",
            f"{alarmed} with alarms",
        ]
        unreadable = sum(1 for r in self.runs if r.error is not None)
        if unreadable:
            parts.append(f"{unreadable} unreadable")
        return ", ".join(parts)


def _float(item: Any, default: float = 0.0) -> float:
    return float(item) if finite(item) else default


def _text(item: Any) -> str:
    return "" if item is None else str(item)


def episode(data: Mapping[str, Any], start: float) -> Episode:
    """An episode of a run that started at ``start``."""
    first = _float(data["first"], start)
    last = _float(data.get("last"), first)
    return Episode(
        time=seconds(first - start),
        until=seconds(last - start),
        offset=first - start,
        end_offset=max(last, first) - start,
        point=_text(data.get("point")),
        invariant=_text(data["invariant"]),
        family=_text(data.get("family")),
        kind=_text(data.get("kind")),
        text=_text(data.get("text")),
        observed=value(data["observed"]) if data.get("observed") is not None else None,
        expected=value(data["expected"]) if data.get("expected") is not None else None,
        count=int(data.get("count") or 1),
    )


def run(data: Mapping[str, Any]) -> Run:
    """A run of a replay document, its episodes in time order."""
    start = _float(data.get("start"))
    episodes = sorted(
        (episode(e, start) for e in data.get("episodes") or []),
        key=lambda e: (e.offset, e.invariant, e.point, e.end_offset),
    )
    plots = data.get("plots") or {}
    error = data.get("error")
    return Run(
        bag=_text(data["bag"]),
        start=start,
        end=_float(data.get("end"), start),
        messages=int(data.get("messages") or 0),
        skipped=int(data.get("skipped") or 0),
        error=None if error is None else str(error),
        violations=int(data.get("violations") or 0),
        episodes=episodes,
        alarms=[raised_alarm(a, start) for a in data.get("alarms") or []],
        polygons=list(plots.get("polygons") or []),
        frequencies=list(plots.get("frequencies") or []),
        warnings=[_text(w) for w in data.get("warnings") or []],
        checked={_text(k): int(v) for k, v in (data.get("checked") or {}).items()},
    )


def replay(document: Mapping[str, Any]) -> Replay:
    """A replay document (``"format": "imrosc-replay"``) read."""
    project = document.get("project")
    return Replay(
        invariants=_text(document["invariants"]),
        project=None if project is None else str(project),
        runs=[run(r) for r in document["runs"]],
    )


# -------------------------------------------------------------------------------- classify


@dataclass(frozen=True)
class Family:
    """A row of the per-family table: classify counts kept, compare counts broken."""

    name: str
    total: int
    kept: int = 0
    broken: int = 0
    unbroken: int = 0

    @property
    def dropped(self) -> int:
        """Invariants of the family below the threshold."""
        return self.total - self.kept

    @property
    def broken_share(self) -> str:
        """Percentage of the family's invariants the reference runs broke."""
        return percent(self.broken, self.total)

    @property
    def kept_share(self) -> str:
        """Percentage of the family's invariants kept."""
        return percent(self.kept, self.total)


@dataclass(frozen=True)
class Score:
    """One invariant's score."""

    id: str
    point: str
    family: str
    kind: str
    text: str
    violated_success: int
    violated_fail: int
    tp: str
    fp: str
    tn: str
    fn: str
    precision: str
    recall: str
    fscore: str
    rank: float
    kept: bool
    broken: bool
    runs_broken: int


@dataclass(frozen=True)
class BagError:
    """A bag that could not be read."""

    bag: str
    error: str


@dataclass(frozen=True)
class ClassifiedRun:
    """A run of a classify document at the run level: its alarms against its fault's onset
    (times from the run's start)."""

    bag: str
    kind: str
    onset: str
    first_alarm: str
    detection: str
    delay: str
    alarms: int
    before_onset: int
    false_alarm: bool
    detected: bool
    checked: str = ""
    """Per point, the samples it checked: ``a 1,204, b 37``."""

    @property
    def verdict(self) -> str:
        """``detected``, ``missed``, ``false alarm``, ``detected, false alarm`` or ``quiet``."""
        if self.kind == "success":
            return "false alarm" if self.false_alarm else "quiet"
        parts = ["detected" if self.detected else "missed"]
        if self.false_alarm:
            parts.append("false alarm")
        return ", ".join(parts)


@dataclass(frozen=True)
class Detection:
    """The run-level summary: recall over failed runs, false alarms, delays."""

    fail_runs: int
    success_runs: int
    with_onset: int
    detected: int
    recall: str
    false_alarm_success: int
    false_alarm_fail: int
    false_alarm_rate: str
    delay_mean: str
    delay_max: str

    @property
    def summary(self) -> str:
        """The summary in one line."""
        return (
            f"{self.detected} of {plural(self.fail_runs, 'fail run')} detected "
            f"(recall {self.recall}; {self.with_onset} with an onset); false alarms in "
            f"{self.false_alarm_success} of {self.success_runs} success and "
            f"{self.false_alarm_fail} of {self.fail_runs} fail runs "
            f"(rate {self.false_alarm_rate}); delay mean {self.delay_mean}, max {self.delay_max}"
        )


@dataclass(frozen=True)
class Classify:
    """A classify or compare document."""

    mode: str
    config: str
    invariants: str
    output: str | None
    beta: str
    threshold: str
    success: list[str]
    fail: list[str]
    reference: list[str]
    errors: list[BagError]
    families: list[Family]
    all: Family
    scores: list[Score]
    runs: list[ClassifiedRun] = field(default_factory=list)
    detection: Detection | None = None
    success_in_detect: list[str] = field(default_factory=list)
    cross_validation: str | None = None
    select: str = "fscore"
    """How the kept invariants were chosen (``cover`` or ``fscore``; reports written before
    ``select`` existed filtered by F-score)."""
    cover: str | None = None
    """With ``select="cover"``: what the chosen set is worth, in one line."""

    @property
    def success_warning(self) -> str | None:
        """What a reader must know when success runs trained the invariants."""
        if not self.success_in_detect:
            return None
        line = (
            f"{len(self.success_in_detect)} of {plural(len(self.success), 'success run')} "
            f"trained the invariants (<detect>): their false positives are 0 by construction"
        )
        if self.cross_validation:
            return f"{line}; {self.cross_validation}"
        return f"{line}; imrosc classify --cross-validate K scores them honestly"

    @property
    def compare(self) -> bool:
        """Whether this is a compare document (reference runs only)."""
        return self.mode == "compare"

    @property
    def kept(self) -> list[Score]:
        """Kept invariants, best F-score first."""
        return [s for s in self.scores if s.kept]

    @property
    def dropped(self) -> list[Score]:
        """Dropped invariants, best F-score first."""
        return [s for s in self.scores if not s.kept]

    @property
    def broken(self) -> list[Score]:
        """Broken invariants by family (in table order), most runs broken first."""
        order = {f.name: i for i, f in enumerate(self.families)}
        return sorted(
            (s for s in self.scores if s.broken),
            key=lambda s: (order.get(s.family, len(order)), s.family, -s.runs_broken, s.id),
        )

    @property
    def dropped_line(self) -> str:
        """``N invariants dropped (F below threshold T)``, or (cover) not in the chosen set."""
        if self.select == "cover":
            return f"{plural(len(self.dropped), 'invariant')} dropped (not in the chosen set)"
        return (
            f"{plural(len(self.dropped), 'invariant')} dropped (F below threshold {self.threshold})"
        )

    @property
    def summary(self) -> str:
        """What was compared or classified, in one line."""
        if self.compare:
            return (
                f"{self.all.broken} of {plural(self.all.total, 'invariant')} broken "
                f"by {plural(len(self.reference), 'reference run')}"
            )
        how = (
            "select cover"
            if self.select == "cover"
            else f"beta {self.beta}, threshold {self.threshold}"
        )
        return (
            f"{self.all.kept} of {plural(self.all.total, 'invariant')} kept ({how}) from "
            f"{len(self.success)} success and {len(self.fail)} fail runs"
        )


def _count(item: Any) -> str:
    return UNDEFINED if item is None else value(item)


def _rank(item: Any) -> float:
    return float(item) if finite(item) else -math.inf


def score(data: Mapping[str, Any]) -> Score:
    """One entry of a document's ``scores``."""
    return Score(
        id=_text(data["id"]),
        point=_text(data.get("point")),
        family=_text(data.get("family")),
        kind=_text(data.get("kind")),
        text=_text(data.get("text")),
        violated_success=int(data.get("violated_success") or 0),
        violated_fail=int(data.get("violated_fail") or 0),
        tp=_count(data.get("tp")),
        fp=_count(data.get("fp")),
        tn=_count(data.get("tn")),
        fn=_count(data.get("fn")),
        precision=fraction(data.get("precision")),
        recall=fraction(data.get("recall")),
        fscore=fraction(data.get("fscore")),
        rank=_rank(data.get("fscore")),
        kept=bool(data.get("kept")),
        broken=bool(data.get("broken")),
        runs_broken=int(data.get("runs_broken") or 0),
    )


def _families(data: Mapping[str, Any], scores: Sequence[Score]) -> list[Family]:
    names = list(data)
    names += sorted({s.family for s in scores} - set(names))
    rows = []
    for name in names:
        counts = data.get(name) or {}
        mine = [s for s in scores if s.family == name]
        total = int(counts.get("total", len(mine)))
        broken = int(counts.get("broken", sum(s.broken for s in mine)))
        rows.append(
            Family(
                name=name,
                total=total,
                kept=int(counts.get("kept", sum(s.kept for s in mine))),
                broken=broken,
                unbroken=int(counts.get("unbroken", total - broken)),
            )
        )
    return rows


def _at(item: Any) -> str:
    return seconds(float(item)) if finite(item) else UNDEFINED


def classified_run(data: Mapping[str, Any]) -> ClassifiedRun:
    """One entry of a classify document's ``runs``."""
    return ClassifiedRun(
        bag=_text(data.get("bag")),
        kind=_text(data.get("kind")),
        onset=_at(data.get("onset")),
        first_alarm=_at(data.get("first_alarm")),
        detection=_at(data.get("detection")),
        delay=_at(data.get("delay")),
        alarms=int(data.get("alarms") or 0),
        before_onset=int(data.get("alarms_before_onset") or 0),
        false_alarm=bool(data.get("false_alarm")),
        detected=bool(data.get("detected")),
        checked=", ".join(
            f"{point} {int(count):,}" for point, count in (data.get("checked") or {}).items()
        ),
    )


def detection(data: Mapping[str, Any]) -> Detection:
    """A classify document's ``detection`` summary."""
    return Detection(
        fail_runs=int(data.get("fail_runs") or 0),
        success_runs=int(data.get("success_runs") or 0),
        with_onset=int(data.get("with_onset") or 0),
        detected=int(data.get("detected") or 0),
        recall=fraction(data.get("recall")),
        false_alarm_success=int(data.get("false_alarm_success") or 0),
        false_alarm_fail=int(data.get("false_alarm_fail") or 0),
        false_alarm_rate=fraction(data.get("false_alarm_rate")),
        delay_mean=_at(data.get("delay_mean")),
        delay_max=_at(data.get("delay_max")),
    )


def _cross_validation(data: Any) -> str | None:
    if not isinstance(data, Mapping):
        return None
    scored = len(data.get("scored") or [])
    return (
        f"{scored} of them scored at the run level by "
        f"{_count(data.get('folds'))}-fold cross-validation"
    )


def classify(document: Mapping[str, Any]) -> Classify:
    """A classify document (``"format": "imrosc-classify"``, either mode) read."""
    scores = sorted(
        (score(s) for s in document.get("scores") or []),
        key=lambda s: (-s.rank, s.family, s.id, s.point),
    )
    families = _families(document.get("families") or {}, scores)
    output = document.get("output")
    return Classify(
        mode=_text(document.get("mode") or "classify"),
        config=_text(document.get("config")),
        invariants=_text(document["invariants"]),
        output=None if output is None else str(output),
        beta=_count(document.get("beta")),
        threshold=_count(document.get("threshold")),
        success=[str(b) for b in document.get("success") or []],
        fail=[str(b) for b in document.get("fail") or []],
        reference=[str(b) for b in document.get("reference") or []],
        errors=[
            BagError(bag=_text(e.get("bag")), error=_text(e.get("error")))
            for e in document.get("errors") or []
        ],
        families=families,
        all=Family(
            name="all",
            total=sum(f.total for f in families),
            kept=sum(f.kept for f in families),
            broken=sum(f.broken for f in families),
            unbroken=sum(f.unbroken for f in families),
        ),
        scores=scores,
        runs=[classified_run(r) for r in document.get("runs") or []],
        detection=(
            detection(document["detection"])
            if isinstance(document.get("detection"), Mapping)
            else None
        ),
        success_in_detect=[str(b) for b in document.get("success_in_detect") or []],
        cross_validation=_cross_validation(document.get("cross_validation")),
        select=_text(document.get("select") or "fscore"),
        cover=_cover(document.get("cover")),
    )


def _cover(data: Any) -> str | None:
    """The chosen set's worth (a classify document's ``cover``), in one line."""
    if not isinstance(data, Mapping):
        return None
    chosen = data.get("chosen") or []
    line = (
        f"the chosen set of {plural(len(chosen), 'invariant')} detects "
        f"{_count(data.get('detected'))} fail runs; estimated false-alarm probability per "
        f"nominal run {_count(data.get('false_alarm'))}"
    )
    held = [w for w in data.get("held_out") or () if isinstance(w, Mapping)]
    if held:  # learnt detectors competed (<check detector>): which monitor, and why
        worths = ", ".join(
            f"{_text(w.get('monitor'))} {_count(w.get('value'))} ({_count(w.get('detected'))} "
            f"detected, {_count(w.get('early'))} early)"
            for w in held
        )
        line += f"; monitor kept: {_text(data.get('monitor'))} (held-out worth: {worths})"
    return line


# ------------------------------------------------------------------------------- stability


@dataclass(frozen=True)
class Cell:
    """One round's violated and total invariants of one family."""

    violated: int | None
    total: int | None

    @property
    def text(self) -> str:
        """``3/40``, or undefined when the round had no such family."""
        if self.violated is None and self.total is None:
            return UNDEFINED
        return f"{_count(self.violated)}/{_count(self.total)}"

    @property
    def share(self) -> float | None:
        """Violated over total, or None when there is no total."""
        if self.violated is None or not self.total:
            return None
        return self.violated / self.total


@dataclass(frozen=True)
class StabilityRow:
    """A family across rounds: each round's cell, then the means and the ratio."""

    family: str
    cells: list[Cell]
    violated_mean: str
    total_mean: str
    ratio: str


@dataclass(frozen=True)
class Round:
    """One fold: the bags held out and what the invariants inferred from the rest did."""

    number: int
    held_out: list[str]
    trained_on: int
    invariants: int
    errors: list[BagError]
    alarmed: list[str] = field(default_factory=list)

    @property
    def label(self) -> str:
        """``round 1``."""
        return f"round {self.number}"

    @property
    def summary(self) -> str:
        """``held out a.bag; 130 invariants from 6 bags``."""
        held = ", ".join(self.held_out) or "nothing"
        alarmed = f"{len(self.alarmed)} of {len(self.held_out)} held out with an alarm"
        return (
            f"held out {held}; {plural(self.invariants, 'invariant')} "
            f"from {plural(self.trained_on, 'bag')}; {alarmed}"
        )


@dataclass(frozen=True)
class Stability:
    """A stability document: k-fold cross-validation of inference."""

    config: str
    folds: int
    bags: list[str]
    rounds: list[Round]
    rows: list[StabilityRow]
    checked: int | None = None
    """The held-out runs checked (``held_out_runs``: not those that could not be read, nor
    those of a round that trained on nothing); ``None``: every held-out run."""

    @property
    def summary(self) -> str:
        """``4-fold cross-validation over 8 bags; 1 of 8 held-out runs raised an alarm``."""
        alarmed = sum(len(r.alarmed) for r in self.rounds)
        held = sum(len(r.held_out) for r in self.rounds) if self.checked is None else self.checked
        return (
            f"{self.folds}-fold cross-validation over {plural(len(self.bags), 'bag')}; "
            f"{alarmed} of {held} held-out runs raised an alarm"
        )


def _mean(item: Any) -> str:
    return number(float(item), 3) if finite(item) else UNDEFINED


def _optional_int(item: Any) -> int | None:
    return int(item) if finite(item) else None


def stability(document: Mapping[str, Any]) -> Stability:
    """A stability document (``"format": "imrosc-stability"``) read."""
    rounds_data = list(document.get("rounds") or [])
    families: Mapping[str, Any] = document.get("families") or {}
    names = list(families)
    seen = {
        name for r in rounds_data for name in [*(r.get("violated") or {}), *(r.get("total") or {})]
    }
    names += sorted(seen - set(names))
    rows = []
    for name in names:
        cells = [
            Cell(
                violated=_optional_int((r.get("violated") or {}).get(name)),
                total=_optional_int((r.get("total") or {}).get(name)),
            )
            for r in rounds_data
        ]
        summary = families.get(name) or {}
        ratio: Any = summary.get("violated_ratio")
        rows.append(
            StabilityRow(
                family=name,
                cells=cells,
                violated_mean=_mean(summary.get("violated_mean")),
                total_mean=_mean(summary.get("total_mean")),
                ratio=f"{100.0 * ratio:.2f}%" if finite(ratio) else UNDEFINED,
            )
        )
    rounds = [
        Round(
            number=i,
            held_out=[str(b) for b in r.get("held_out") or []],
            trained_on=len(r.get("trained_on") or []),
            invariants=int(r.get("invariants") or 0),
            errors=[
                BagError(bag=_text(e.get("bag")), error=_text(e.get("error")))
                if isinstance(e, Mapping)
                else BagError(bag="", error=str(e))
                for e in r.get("errors") or []
            ],
            alarmed=[str(b) for b in r.get("alarmed") or []],
        )
        for i, r in enumerate(rounds_data, start=1)
    ]
    return Stability(
        config=_text(document.get("config")),
        folds=int(document.get("folds") or len(rounds)),
        bags=[str(b) for b in document.get("bags") or []],
        rounds=rounds,
        rows=rows,
        checked=_optional_int(document.get("held_out_runs")),
    )
