"""The check stage (``imrosc classify``): invariants scored on good and bad runs, or compared.

Classification (thesis 4.2): every invariant is replayed on the ``<success>`` and ``<fail>``
runs. Over the successful runs it has true negatives (not violated) and false positives
(violated); over the failed runs true positives (violated) and false negatives. Equations
4.1-4.4 make these fractions of the runs, 4.5-4.7 give precision, recall and the F-score.
When no success run violates it and no fail run either, precision is undefined (0/0) and
the F-score is 0: an invariant that never fires detects nothing. The refined file keeps
what ``<check select>`` chooses (:mod:`imrosc.selection`): the set whose union detects the
most failed runs minus its expected false alarms (``cover``, the default), or the
invariants whose F-score reaches the threshold (``fscore``, the thesis' filter).

A ``<fail>`` entry may give its fault's onset (seconds after each bag's start, a label
topic whose first non-zero message is the onset, or a JSON file of onsets per bag). A failed
run with an onset is then two observations: the part before the onset is a nominal run (an
invariant it violates counts as a false positive, as on a successful run) and the rest is the
failed run (an invariant violated at or after the onset is a true positive, else a false
negative). The equations are unchanged. At the run level the engine's alarms are scored:
per failed run, the first alarm at or after the onset and its delay, and whether an alarm came
before it (a false alarm); per successful run, whether any alarm came.

Comparison (thesis 5.2): the invariants of one data set replayed on another; an invariant
violated in some run of the other set is broken there.
"""

from __future__ import annotations

import json
import math
import multiprocessing
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from imrosc.bags import BagError, MessageError, discover_bags, open_bag
from imrosc.calibrate.rule import (
    HeldOutRun,
    alarms_under,
    covered,
    held_out_runs,
    unseen_alarms,
)
from imrosc.detectors import (
    FOLDS,
    Choice,
    Learnt,
    Refused,
    Sampled,
    learn,
    learnable,
    run_of,
    variables_of,
)
from imrosc.diagnostics import Diagnostic, finalize, has_errors, make
from imrosc.folds import blocked
from imrosc.frontend import lowered
from imrosc.infer.engine import default_workers
from imrosc.infer.registry import group_of
from imrosc.invariants import InvariantsFileError, load
from imrosc.ir import Check, Onset, Project
from imrosc.outputs import INVARIANTS, REPORT, mark
from imrosc.progress import Progress, ProgressFactory, bag_done
from imrosc.remote import bag_path
from imrosc.replay import Replayer
from imrosc.runtime import Engine
from imrosc.runtime.alarms import AlarmRule
from imrosc.runtime.engine import NUMERIC_TYPES
from imrosc.schema.names import resolve_name
from imrosc.selection import (
    SELECTIONS,
    Cover,
    Nominal,
    Whole,
    Worth,
    cover,
    detected_by,
    held_out_outcomes,
    union_false_alarm,
    within_noise,
)

if TYPE_CHECKING:
    from imrosc.fleet import Fleet


class CheckStageError(Exception):
    """A configuration or file the check stage cannot use (the message says why)."""


@dataclass(frozen=True)
class Score:
    """One invariant as a classifier of failed runs (Equations 4.1-4.7)."""

    violated_success: int
    success: int
    violated_fail: int
    fail: int
    beta: float = 1.0

    @property
    def rates(self) -> tuple[float, float, float, float]:
        """``(true negative, false positive, true positive, false negative)`` fractions."""
        tn = (self.success - self.violated_success) / self.success if self.success else 0.0
        fp = self.violated_success / self.success if self.success else 0.0
        tp = self.violated_fail / self.fail if self.fail else 0.0
        fn = (self.fail - self.violated_fail) / self.fail if self.fail else 0.0
        return tn, fp, tp, fn

    @property
    def precision(self) -> float | None:
        """Equation 4.5 (``None`` when nothing was violated: 0/0)."""
        _, fp, tp, _ = self.rates
        return tp / (tp + fp) if tp + fp > 0 else None

    @property
    def recall(self) -> float | None:
        """Equation 4.6 (``None`` without failed runs)."""
        _, _, tp, fn = self.rates
        return tp / (tp + fn) if tp + fn > 0 else None

    @property
    def fscore(self) -> float | None:
        """Equation 4.7; 0 when precision or recall is 0 or undefined by 0/0 violations.

        >>> [round(Score(1, 10, 9, 10, beta).fscore or 0, 3) for beta in (0.5, 1.0, 2.0)]
        [0.9, 0.9, 0.9]
        >>> round(Score(5, 10, 9, 10, 0.5).fscore or 0, 3)
        0.682
        """
        if self.recall is None:
            return None
        precision, recall = self.precision or 0.0, self.recall
        if precision == 0 or recall == 0:
            return 0.0
        b2 = self.beta * self.beta
        return (1 + b2) * precision * recall / (b2 * precision + recall)


# -- configuration and bags -----------------------------------------------------------------


def load_project(config_path: Path) -> tuple[Project | None, list[Diagnostic]]:
    """Read, check and lower a configuration (:func:`imrosc.frontend.lowered`), its
    diagnostics finalized."""
    project, problems = lowered(config_path)
    return project, finalize(problems)


def bags_of(base: Path, entries: Sequence[str]) -> tuple[list[Path], list[Diagnostic]]:
    """The bags ``entries`` name (paths relative to ``base``, globs, URLs), and diagnostics
    for the rest."""
    bags: list[Path] = []
    problems: list[Diagnostic] = []
    for entry in entries:
        found, bad = discover_bags(bag_path(entry, base))
        bags += found
        problems += bad
    return bags, problems


def read_invariants(path: Path) -> dict[str, Any]:
    """The invariants document, or :class:`CheckStageError`."""
    try:
        return load(path)
    except InvariantsFileError as error:
        raise CheckStageError(str(error)) from None


# -- onsets ------------------------------------------------------------------------------------


class OnsetFileError(CheckStageError):
    """An onsets file that cannot be read or is not a mapping of bags to onsets."""


def onsets_file(path: Path) -> dict[Path, float | None]:
    """The onsets a JSON file gives, by resolved bag path (keys are relative to the
    file, or URLs).

    A value is seconds after the bag's start, an object with ``onset_s`` (the ALFA data
    set's form), or null (no fault).
    """
    try:
        data = json.loads(path.read_text(encoding="utf-8"))
    except OSError as error:
        raise OnsetFileError(f"{path}: cannot read the onsets file: {error.strerror}") from None
    except (UnicodeDecodeError, json.JSONDecodeError) as error:
        raise OnsetFileError(f"{path}: the onsets file is not JSON: {error}") from None
    if not isinstance(data, dict):
        raise OnsetFileError(f"{path}: the onsets file must map bag paths to onsets")
    out: dict[Path, float | None] = {}
    for key, item in data.items():
        value = item.get("onset_s") if isinstance(item, dict) else item
        number = value is None or (
            isinstance(value, int | float) and not isinstance(value, bool) and value >= 0
        )
        if not number or (value is not None and not math.isfinite(value)):
            raise OnsetFileError(
                f"{path}: the onset of {key!r} is {value!r}; expected seconds >= 0 or null"
            )
        out[bag_path(key, path.parent).resolve()] = None if value is None else float(value)
    return out


def _numeric(value: Any) -> float | None:
    if isinstance(value, bool | int | float):
        return float(value)
    return None


def label_value(message: Any) -> float | None:
    """A label message's value: its ``data``, else its only numeric field (None: neither)."""
    if hasattr(message, "data"):
        return _numeric(message.data)
    fields = getattr(message, "__dataclass_fields__", None) or {}
    numbers = [_numeric(getattr(message, name)) for name in fields]
    found = [n for n in numbers if n is not None]
    return found[0] if len(found) == 1 else None


def label_onset(bag: Path, topic: str) -> tuple[float | None, str | None]:
    """Seconds from the bag's start to the first non-zero message on ``topic``, or why not.

    NaN values are skipped (no label); an unreadable bag gives its error.
    """
    try:
        with open_bag(bag) as reader:
            start = reader.start_time / 1e9
            connections = [c for c in reader.connections if c.topic == topic]
            if not connections:
                return None, f"{bag} has no topic {topic} to read the fault's onset from"
            for connection, stamp, raw in reader.messages(connections=connections):
                try:
                    message = reader.deserialize(raw, connection.msgtype)
                except MessageError:
                    continue
                value = label_value(message)
                if value is None:
                    return None, (
                        f"{bag}: {topic} ({connection.msgtype}) has no data field or single "
                        f"numeric field to read the fault's onset from"
                    )
                if value != 0 and not math.isnan(value):
                    return stamp / 1e9 - start, None
    except BagError as error:
        return None, str(error)
    return None, f"{bag}: {topic} never turns non-zero, so the fault's onset is unknown"


@dataclass(frozen=True)
class OnsetSpec:
    """How a failed run's onset is found: given seconds, or a label topic to read."""

    seconds: float | None = None
    topic: str | None = None
    problem: str | None = None
    """Why an onset was asked for but none can be given (the file does not list the bag)."""


# -- replay in worker processes --------------------------------------------------------------


@dataclass
class RunOutcome:
    """What replaying one run gave, as classification needs it (times from the bag's start)."""

    bag: Path
    error: str | None = None
    start: float = 0.0
    end: float = 0.0
    onset: float | None = None
    """Seconds after the start when the fault begins (None: unknown or a successful run)."""
    onset_problem: str | None = None
    """Why an onset that was asked for cannot be used."""
    first: dict[str, float] = field(default_factory=dict)
    """Per violated invariant, its first violation."""
    after: dict[str, float] = field(default_factory=dict)
    """Per invariant violated at or after the onset, its first violation there."""
    alarms: list[dict[str, Any]] = field(default_factory=list)
    """The alarms: ``time`` (from the start), ``point``, ``rule``, ``invariant``."""
    warnings: list[str] = field(default_factory=list)
    """What the replay warned of (topics missing, or of another type than learnt)."""
    unchecked: list[str] = field(default_factory=list)
    """The unconditional publish points that checked no sample in this run."""
    checked: dict[str, int] = field(default_factory=dict)
    """Per value point, the samples it checked in this run."""
    messages: int = 0
    samples: dict[str, Sampled] = field(default_factory=dict, repr=False)
    """Per point a detector may weigh (``<check detector>``), its checked samples: their
    times and the values of :func:`imrosc.detectors.variables_of`."""

    @property
    def violated(self) -> set[str]:
        """Ids of the invariants the run broke."""
        return set(self.first)

    @property
    def before(self) -> set[str]:
        """Ids of the invariants broken before the onset (none without an onset)."""
        if self.onset is None:
            return set()
        return {ident for ident, time in self.first.items() if time < self.onset}

    @property
    def detected(self) -> set[str]:
        """Ids of the invariants that detect the fault: broken at or after the onset, or
        anywhere in a run without one."""
        return set(self.after) if self.onset is not None else self.violated


_WORKER: Replayer | None = None
_SAMPLES: Sampler | None = None


class Sampler:
    """The engine's trace (:data:`imrosc.runtime.engine.Trace`) keeping, per point a
    detector may weigh, each checked sample's time and values."""

    def __init__(self, document: Mapping[str, Any]) -> None:
        self.places: dict[str, Any] = {}
        for key, info in document["points"].items():
            numeric = [v["name"] for v in info["variables"] if v["type"] in NUMERIC_TYPES]
            weighed = variables_of(info)
            if weighed:
                self.places[key] = np.asarray([numeric.index(n) for n in weighed], np.int64)
        self.times: dict[str, list[float]] = {}
        self.rows: dict[str, list[Any]] = {}

    def trace(self, point: str, time: float, row: Any, frequency: float | None) -> None:
        places = self.places.get(point)
        if places is not None:
            if point not in self.times:
                self.times[point], self.rows[point] = [], []
            self.times[point].append(time)
            self.rows[point].append(row.take(places))

    def trace_rows(
        self, point: str, times: Sequence[float], rows: Any, frequencies: Sequence[float | None]
    ) -> None:
        """A chunk of samples at once (``rows``: a matrix, ``imrosc.checking``)."""
        places = self.places.get(point)
        if places is not None:
            if point not in self.times:
                self.times[point], self.rows[point] = [], []
            self.times[point].extend(times)
            self.rows[point].extend(rows[:, places])

    def take(self) -> dict[str, Sampled]:
        """The samples of the run traced since the last call, as arrays."""
        taken = {
            point: Sampled(
                np.asarray(times, dtype=np.float64),
                np.asarray(self.rows[point], dtype=np.float64).reshape(
                    len(times), len(self.places[point])
                ),
            )
            for point, times in self.times.items()
        }
        self.times, self.rows = {}, {}
        return taken


def replayer_of(document: Mapping[str, Any], collect: bool) -> tuple[Replayer, Sampler | None]:
    """The replayer of classification's runs and, with ``collect``, the :class:`Sampler`
    tracing its engine (learnt detectors need the runs' samples)."""
    if not collect:
        return Replayer(document), None
    sampler = Sampler(document)
    return Replayer(document, Engine(document, trace=sampler.trace, lazy=True)), sampler


def _start_worker(document: Mapping[str, Any], collect: bool = False) -> None:
    global _WORKER, _SAMPLES
    _WORKER, _SAMPLES = replayer_of(document, collect)


RunTask = tuple[Path, OnsetSpec | None]
"""A run to observe: its bag and, for a failed run with an onset, how to find it."""


def _observe(task: RunTask) -> RunOutcome:
    assert _WORKER is not None
    return observe(_WORKER, task, _SAMPLES)


def observe(replayer: Replayer, task: RunTask, sampler: Sampler | None = None) -> RunOutcome:
    """Replay one run with ``replayer`` and keep what classification needs (with
    ``sampler``, the trace of the replayer's engine: the run's samples too)."""
    bag, spec = task
    result = replayer.run(bag)
    samples = sampler.take() if sampler is not None else {}
    out = RunOutcome(
        bag,
        result.error,
        result.start,
        result.end,
        warnings=result.warnings,
        unchecked=result.unchecked,
        checked=dict(result.checked),
        messages=result.messages,
        samples=samples,
    )
    if result.error is not None:
        return out
    if spec is not None:
        onset, problem = spec.seconds, spec.problem
        if spec.topic is not None:
            onset, problem = label_onset(bag, spec.topic)
        duration = max(result.end - result.start, 0.0)
        if onset is not None and onset > duration:
            onset, problem = (
                None,
                (f"{bag}: the onset {onset:g} s is past the end of the bag ({duration:.3f} s)"),
            )
        out.onset, out.onset_problem = onset, problem
    for v in result.violations:
        at = v.time - result.start
        if at < out.first.get(v.invariant, math.inf):
            out.first[v.invariant] = at
        if out.onset is not None and at >= out.onset and at < out.after.get(v.invariant, math.inf):
            out.after[v.invariant] = at
    out.alarms = [
        {
            "time": a.time - result.start,
            "point": a.point,
            "rule": a.rule,
            "invariant": a.violation.invariant,
        }
        for a in sorted(result.alarms, key=lambda a: a.time)
    ]
    return out


def observe_runs(
    document: Mapping[str, Any],
    bags: Sequence[Path],
    workers: int | None = None,
    onsets: Mapping[Path, OnsetSpec] | None = None,
    progress: Progress | None = None,
    collect: bool = False,
    cluster: Fleet | None = None,
) -> dict[Path, RunOutcome]:
    """Replay each bag (in worker processes, or as tasks on ``cluster``) and keep what
    classification needs; a bag in ``onsets`` also gets its fault's onset; ``progress``
    hears of each bag done; ``collect``: each run's samples too (:attr:`RunOutcome.samples`)."""
    tasks: list[RunTask] = [(bag, (onsets or {}).get(bag)) for bag in bags]
    workers = min(workers or default_workers(), max(len(bags), 1))
    found: list[RunOutcome] = []
    if cluster is not None:
        found = cluster.observe_runs(document, tasks, progress, collect)
    elif workers <= 1:
        _start_worker(document, collect)
        for task in tasks:
            found.append(_observe(task))
            bag_done(progress, found[-1].bag, found[-1].messages, found[-1].error)
    else:
        context = multiprocessing.get_context("fork")
        with context.Pool(workers, _start_worker, (document, collect)) as pool:
            for outcome in pool.imap(_observe, tasks, chunksize=1):
                found.append(outcome)
                bag_done(progress, outcome.bag, outcome.messages, outcome.error)
    return {outcome.bag: outcome for outcome in found}


def violated_per_bag(
    document: Mapping[str, Any], bags: Sequence[Path], workers: int | None = None
) -> dict[Path, tuple[set[str], str | None]]:
    """Per bag, the ids of the invariants it violates (or the error that stopped it)."""
    found = observe_runs(document, bags, workers)
    return {bag: (outcome.violated, outcome.error) for bag, outcome in found.items()}


# -- the two modes ------------------------------------------------------------------------------


def _number(value: float | None) -> float | None:
    return None if value is None else round(value, 6)


def classify(
    document: Mapping[str, Any],
    success: Mapping[Path, set[str]],
    fail: Mapping[Path, set[str]],
    *,
    beta: float,
    threshold: float,
    before: Mapping[Path, set[str]] | None = None,
    delays: Mapping[str, Sequence[float]] | None = None,
    untested: Mapping[Path, frozenset[str]] | None = None,
    select: str = SELECTIONS[0],
    detectors: Mapping[str, Nominal] | None = None,
    folds: Sequence[Sequence[Path]] = (),
    whole: Whole | None = None,
) -> tuple[list[dict[str, Any]], dict[str, dict[str, int]], Cover | None]:
    """Scores per invariant, counts per family, and the chosen set (``select="cover"``;
    :mod:`imrosc.selection`).

    ``fail`` holds, per failed run, the invariants that detect its fault (violated at or
    after its onset, or anywhere without one); ``before``, per failed run with an onset,
    the invariants violated before it: that part is a nominal run, its violations false
    positives. ``delays``: per invariant, its detection delays (s) on runs with an onset.
    ``untested``: per successful run scored from its held-out replays, the invariants it was
    not replayed against (no evidence either way: not counted among its runs).
    ``detectors``: the learnt detectors among the invariants, each with what the held-out
    nominal runs its threshold was set on say of it (:func:`detector_nominal`); with
    ``select="cover"`` the monitor is then the best of the cover, the detectors, or both,
    as held-out failed runs (``folds``) show (:func:`monitor_choice`); ``whole``: the
    inferred monitor as calibrated is a candidate too (:func:`whole_monitor`).
    """
    scores: list[dict[str, Any]] = []
    families: dict[str, dict[str, int]] = {}
    before = before or {}
    untested = untested or {}
    nominal: dict[str, Nominal] = {}
    for inv in document["invariants"]:
        ident = inv["id"]
        early = sum(ident in ids for ids in before.values())
        tested_in = [ids for run, ids in success.items() if ident not in untested.get(run, ())]
        tested = len(tested_in)
        broken = sum(ident in ids for ids in tested_in)
        score = Score(
            broken + early,
            tested + len(before),
            sum(ident in ids for ids in fail.values()),
            len(fail),
            beta,
        )
        nominal[ident] = Nominal(tested, broken)
        waits = (delays or {}).get(ident) or ()
        fscore = score.fscore
        kept = fscore >= threshold if fscore is not None else score.violated_success == 0
        scores.append(
            {
                "id": ident,
                "point": inv["point"],
                "family": inv["family"],
                "kind": inv["kind"],
                "text": inv["text"],
                "violated_success": score.violated_success,
                "violated_fail": score.violated_fail,
                "tp": score.violated_fail,
                "fp": score.violated_success,
                "tn": score.success - score.violated_success,
                "fn": score.fail - score.violated_fail,
                "precision": _number(score.precision),
                "recall": _number(score.recall),
                "fscore": _number(fscore),
                "kept": kept,
            }
        )
        if delays is not None:
            scores[-1]["fp_before_onset"] = early
            scores[-1]["delay_mean"] = _number(sum(waits) / len(waits)) if waits else None
    chosen = None
    if select == "cover":
        unknown = math.inf  # no measured delay: after every invariant that has one
        by_delay = sorted(
            scores,
            key=lambda s: unknown if s.get("delay_mean") is None else s["delay_mean"],
        )
        order = [s["id"] for s in by_delay]
        runs = len(success) + len(fail)
        if detectors or whole is not None:
            nominal.update(detectors or {})
            chosen = monitor_choice(
                nominal, fail, before, runs, folds, order, set(detectors or {}), whole
            )
        else:
            chosen = cover(nominal, fail, before, runs, order=order)
        picked = {ident: rank for rank, ident in enumerate(chosen.chosen)}
        for entry in scores:
            entry["kept"] = entry["id"] in picked
            entry["false_alarm"] = _number(nominal[entry["id"]].false_alarm)
            if entry["kept"]:
                entry["chosen"] = picked[entry["id"]] + 1
    for inv, entry in zip(document["invariants"], scores, strict=True):
        counts = families.setdefault(inv["family"], {"total": 0, "kept": 0})
        counts["total"] += 1
        counts["kept"] += int(entry["kept"])
    return scores, dict(sorted(families.items())), chosen


def monitor_choice(
    nominal: Mapping[str, Nominal],
    fail: Mapping[Path, set[str]],
    before: Mapping[Path, set[str]],
    runs: int,
    folds: Sequence[Sequence[Path]],
    order: Sequence[str],
    detectors: set[str],
    whole: Whole | None = None,
) -> Cover:
    """The monitor of the invariants ``cover`` chooses, of the learnt ``detectors``, of
    both, of the inferred monitor as calibrated (``whole``: every invariant under the file's
    alarm rule), or of that and the detectors: whichever held-out failed runs show worth the
    most (failed runs detected, less those alarmed on before their onset, less the false
    alarms expected on ``runs`` new nominal runs). The cover is chosen without each fold of
    failed runs in turn and judged on it (:func:`imrosc.selection.held_out_outcomes`); the
    detectors' detections are cross-fitted already, their thresholds above every held-out
    nominal run; nothing of the whole monitor was chosen on the failed runs. Of those whose
    worth lies within a standard error of the best's (of the paired difference of their
    held-out outcomes over the failed runs, :func:`imrosc.selection.within_noise`), the one
    with the fewest invariants is kept (the one-standard-error rule: a difference chance
    explains is no reason for more invariants, each of which can alarm on a new run); ties
    keep the cover, then the detectors alone, then both. When no candidate is worth more
    than 0, no monitor is kept (:data:`NONE`: it detects nothing and raises no false alarm;
    a monitor expected to raise as many false alarms as it detects faults is worth no more),
    and a cover of no invariant kept is named so."""
    invariants = {i: n for i, n in nominal.items() if i not in detectors}
    plain = {run: ids - detectors for run, ids in fail.items()}
    found = cover(invariants, plain, before, runs, order=order)
    by_detector = {run: bool(ids & detectors) for run, ids in fail.items()}
    p_cover = union_false_alarm(nominal, found.chosen)
    p_detector = union_false_alarm(nominal, sorted(detectors))
    p_both = 1.0 - (1.0 - p_cover) * (1.0 - p_detector)
    named = tuple(sorted(detectors))
    # per candidate: its held-out worth, its invariants, what it detects of the failed runs
    # and its false-alarm probability as the report gives them, and per failed run its
    # held-out outcome (1 detected, -1 alarmed on before the onset, 0 neither)
    candidates: list[tuple[Worth, tuple[str, ...], int, float, dict[Path, int]]] = []
    held = held_out_outcomes(invariants, plain, before, runs, folds, order)
    candidates.append(
        (
            Worth.of("cover", held, runs * p_cover),
            found.chosen,
            detected_by(set(found.chosen), fail, before),
            p_cover,
            held,
        )
    )
    if detectors:
        joined = held_out_outcomes(invariants, plain, before, runs, folds, order, by_detector)
        alone = {run: int(hit) for run, hit in by_detector.items()}
        candidates += [
            (
                Worth.of("detector", alone, runs * p_detector),
                named,
                sum(alone.values()),
                p_detector,
                alone,
            ),
            (
                Worth.of("both", joined, runs * p_both),
                found.chosen + named,
                detected_by(set(found.chosen) | detectors, fail, before),
                p_both,
                joined,
            ),
        ]
    if whole is not None:
        outcomes = {run: -1 if run in whole.early else int(run in whole.detected) for run in fail}
        candidates.append(
            (
                Worth.of("inferred", outcomes, runs * whole.false_alarm),
                whole.chosen,
                len(whole.detected),
                whole.false_alarm,
                outcomes,
            )
        )
        if detectors:
            joint = {
                run: -1 if run in whole.early else int(run in whole.detected or by_detector[run])
                for run in fail
            }
            p_joint = 1.0 - (1.0 - whole.false_alarm) * (1.0 - p_detector)
            worth = Worth.of("inferred+detector", joint, runs * p_joint)
            candidates.append(
                (
                    worth,
                    whole.chosen + named,
                    worth.detected,
                    p_joint,
                    joint,
                )
            )
    best = max(candidates, key=lambda c: c[0].value)  # first of equals
    # the smallest monitor whose worth is within a standard error of the best's (the
    # one-standard-error rule): a difference chance explains buys no more invariants
    near = [c for c in candidates if c[0].value >= best[0].value - within_noise(best[4], c[4])]
    worth, chosen, detected, p_chosen, _ = min(near, key=lambda c: len(c[1]))  # first of equals
    # no monitor at all detects nothing and raises no false alarm: worth 0, kept when no
    # candidate is worth more (and named so when the cover kept holds no invariant)
    nothing = Worth(NONE, 0, 0, 0.0)
    candidates.append((nothing, (), 0, 0.0, {}))
    if best[0].value <= 0.0 or not chosen:
        worth, chosen, detected, p_chosen = nothing, (), 0, 0.0
    return Cover(
        chosen,
        detected,
        p_chosen,
        detected - runs * p_chosen,
        worth,
        tuple(c[0] for c in candidates),
    )


WHOLE = ("inferred", "inferred+detector")
"""The candidate monitors that keep every inferred invariant (:func:`monitor_choice`)."""

NONE = "none"
"""The candidate monitor of no invariants (:func:`monitor_choice`)."""


def whole_monitor(
    document: Mapping[str, Any],
    fail: Mapping[Path, RunOutcome],
    nominal: Sequence[RunOutcome],
    units: bool = True,
) -> Whole | None:
    """The inferred monitor as a candidate (:class:`imrosc.selection.Whole`): its failed
    runs' alarms, and its false alarms over calibration's held-out units (with ``units``)
    and the ``nominal`` runs that did not train it (``None``: the file is not calibrated and
    no such run saw it, so nothing says what it costs). A held-out unit alarms as it would
    under the rule and margins the other folds' units set
    (:func:`imrosc.calibrate.rule.unseen_alarms`): the file's own were set past every
    unit's figures, its own included; a file that does not say which fold held each unit
    out is judged under its own rule."""
    rule = AlarmRule.from_json(document.get("alarms"))
    ids = tuple(inv["id"] for inv in document["invariants"])
    kept = set(ids)
    held = [u for u in (document.get("calibration") or {}).get("held_out", ()) if "trace" in u]
    held = held if units else []
    unseen = unseen_alarms(document, kept) if held else None
    if unseen is not None:
        alarmed = sum(unseen)
    else:
        alarmed = sum(alarms_under(covered(u["trace"], kept), rule) for u in held)
    alarmed += sum(bool(o.alarms) for o in nominal)
    tested = len(held) + len(nominal)
    if not tested:
        return None
    detected, early = set(), set()
    for bag, outcome in fail.items():
        times = [a["time"] for a in outcome.alarms]
        if not times:
            continue
        if outcome.onset is not None and min(times) < outcome.onset:
            early.add(bag)
        else:
            detected.add(bag)
    return Whole(ids, frozenset(detected), frozenset(early), tested, alarmed)


def compare(
    document: Mapping[str, Any], runs: Mapping[Path, set[str]]
) -> tuple[list[dict[str, Any]], dict[str, dict[str, int]]]:
    """Broken and unbroken invariants, one by one and per family (Table 5.4)."""
    scores: list[dict[str, Any]] = []
    families: dict[str, dict[str, int]] = {}
    for inv in document["invariants"]:
        broken_in = sum(inv["id"] in ids for ids in runs.values())
        scores.append(
            {
                "id": inv["id"],
                "point": inv["point"],
                "family": inv["family"],
                "kind": inv["kind"],
                "text": inv["text"],
                "broken": broken_in > 0,
                "runs_broken": broken_in,
            }
        )
        counts = families.setdefault(inv["family"], {"total": 0, "broken": 0, "unbroken": 0})
        counts["total"] += 1
        counts["broken" if broken_in else "unbroken"] += 1
    return scores, dict(sorted(families.items()))


def refined(
    document: Mapping[str, Any], scores: Sequence[Mapping[str, Any]], report: Mapping[str, Any]
) -> dict[str, Any]:
    """The input invariants file with the dropped invariants left out (same format)."""
    by_id = {s["id"]: s for s in scores}
    out = dict(document)
    out["$comment"] = (
        f"{mark(INVARIANTS)} (imrosc classify) from {report['config']}, "
        f"refining {report['invariants']}"
    )
    out["invariants"] = [
        {**inv, "score": {k: by_id[inv["id"]][k] for k in ("precision", "recall", "fscore")}}
        for inv in document["invariants"]
        if by_id[inv["id"]]["kept"]
    ]
    out["classified"] = {
        "select": report["select"],
        "beta": report["beta"],
        "threshold": report["threshold"],
        "success": report["success"],
        "fail": report["fail"],
        "dropped": len(scores) - len(out["invariants"]),
    }
    return out


def refined_rule(
    document: Mapping[str, Any],
    success: Sequence[Path],
    workers: int | None,
    cluster: Fleet | None = None,
) -> dict[str, Any]:
    """The alarm rule of the kept invariants: the rule of the whole file asks more of an
    alarm than fewer invariants can give. It is set as calibration sets it (the conformal
    rank of the longest episode and the largest agreement, :mod:`imrosc.calibrate.rule`),
    from the held-out runs of calibration when the file keeps their traces, else on the
    successful runs (optimistic when they are <detect> runs: the warning says so)."""
    from imrosc.calibrate import DEFAULT_BUDGET
    from imrosc.calibrate.rule import calibrate_rule, rule_for
    from imrosc.infer.engine import Unit

    held = rule_for(document, {inv["id"] for inv in document["invariants"]})
    if held is not None:
        return held.as_json()

    budget = float((document.get("calibration") or {}).get("budget", DEFAULT_BUDGET))
    units = [Unit(bag, []) for bag in success]
    found = calibrate_rule(
        [(document, list(range(len(units))))],
        units,
        budget,
        workers=workers or 1,
        replays=cluster.replay_held_out if cluster is not None else None,
    )
    return found.rule.as_json()


@dataclass
class CheckResult:
    """What ``imrosc classify`` reports and writes."""

    report: dict[str, Any] = field(default_factory=dict)
    refined: dict[str, Any] | None = None
    output: Path | None = None
    diagnostics: list[Diagnostic] = field(default_factory=list)
    inputs: list[Path] = field(default_factory=list)
    """The files the stage read: the invariants file and the bags (no output may be one)."""


def group_counts(document: Mapping[str, Any]) -> dict[str, int]:
    """Invariants per summary group (default, time-related, polygon, ...)."""
    found: dict[str, int] = {}
    for inv in document["invariants"]:
        group = group_of(inv["family"])
        found[group] = found.get(group, 0) + 1
    return found


def none_kept_message(chosen: Cover) -> str:
    """The ``no-monitor-kept`` warning: what every candidate was worth, and whether none
    was kept for being worth the most or for a lead within a standard error."""
    others = [w for w in chosen.candidates if w.name != NONE]
    worths = ", ".join(f"{w.name} {w.value:.2f}" for w in others)
    lead = "" if max(w.value for w in others) <= 0.0 else " by more than a standard error"
    return (
        f"no candidate monitor is worth more than none{lead} on the held-out failed runs "
        f"({worths}; none 0): the refined file keeps no invariants; record more normal and "
        f"failed runs, or monitor with the invariants file itself"
    )


def _diagnostic(config_path: Path, span: Any, code: str, message: str) -> Diagnostic:
    return make(str(config_path), span.line, span.column, code, message)


def fail_onsets(
    config_path: Path, check: Check, bags: Mapping[str, Sequence[Path]]
) -> tuple[dict[Path, OnsetSpec], dict[Path, Onset]]:
    """Per failed run whose ``<fail>`` gives an onset: how to find it, and that ``<fail>``.

    ``bags``: the bags each ``<fail>`` entry names. An unreadable onsets file raises
    :class:`OnsetFileError`.
    """
    base = config_path.parent
    onsets = check.onsets or tuple(Onset(check.span) for _ in check.fail)
    specs: dict[Path, OnsetSpec] = {}
    where: dict[Path, Onset] = {}
    files: dict[str, dict[Path, float | None]] = {}
    for entry, onset in zip(check.fail, onsets, strict=False):
        if not onset.given:
            continue
        if onset.file is not None and onset.file not in files:
            files[onset.file] = onsets_file(base / onset.file)
        for bag in bags.get(entry, ()):
            where[bag] = onset
            if onset.seconds is not None:
                specs[bag] = OnsetSpec(seconds=onset.seconds)
            elif onset.topic is not None:
                specs[bag] = OnsetSpec(topic=resolve_name(onset.topic))
            elif onset.file is not None:
                table = files[onset.file]
                key = bag.resolve()
                if key not in table:
                    problem = f"{bag} is not in the onsets file {onset.file}"
                    specs[bag] = OnsetSpec(problem=problem)
                elif table[key] is None:
                    problem = f"the onsets file {onset.file} gives {bag} no onset (null)"
                    specs[bag] = OnsetSpec(problem=problem)
                else:
                    specs[bag] = OnsetSpec(seconds=table[key])
    return specs, where


def _seconds(value: float | None) -> float | None:
    return None if value is None else round(value, 6)


def run_entry(outcome: RunOutcome, kind: str) -> dict[str, Any]:
    """One run of the report: its alarms against its onset (times from the bag's start)."""
    times = [a["time"] for a in outcome.alarms]
    entry: dict[str, Any] = {
        "bag": str(outcome.bag),
        "kind": kind,
        "duration": _seconds(max(outcome.end - outcome.start, 0.0)),
        "violated": len(outcome.first),
        "alarms": len(times),
        "first_alarm": _seconds(times[0]) if times else None,
    }
    if outcome.warnings:
        entry["warnings"] = list(outcome.warnings)
    if outcome.unchecked:
        entry["unchecked"] = list(outcome.unchecked)
    if outcome.checked:
        entry["checked"] = dict(sorted(outcome.checked.items()))
    if kind == "success":
        entry["false_alarm"] = bool(times)
        return entry
    onset = outcome.onset
    early = [t for t in times if onset is not None and t < onset]
    late = [t for t in times if onset is None or t >= onset]
    entry.update(
        {
            "onset": _seconds(onset),
            "alarms_before_onset": len(early),
            "false_alarm": bool(early),
            "detected": bool(late),
            "detection": _seconds(late[0]) if late else None,
            "delay": _seconds(late[0] - onset) if late and onset is not None else None,
        }
    )
    return entry


def held_out_entry(
    entry: dict[str, Any], seen: HeldOutRun, kept: set[str], rule: AlarmRule
) -> dict[str, Any]:
    """A successful run that trained the invariants, as its held-out replays saw it: the
    invariants it broke when held out, and whether the refined file's rule alarms on them
    (alarm times are not kept: ``first_alarm`` is unknown)."""
    alarmed = seen.alarmed(kept, rule)
    return {
        **entry,
        "held_out": True,
        "violated": len(seen.broken & kept),
        "alarms": int(alarmed),
        "first_alarm": None,
        "false_alarm": alarmed,
    }


def detection(runs: Sequence[Mapping[str, Any]]) -> dict[str, Any]:
    """The run-level summary of the report's ``runs``: recall over failed runs (an alarm at
    or after the onset), runs with a false alarm, detection delays."""
    success = [r for r in runs if r["kind"] == "success"]
    fail = [r for r in runs if r["kind"] == "fail"]
    delays = [r["delay"] for r in fail if r.get("delay") is not None]
    detected = sum(r["detected"] for r in fail)
    nominal = len(success) + sum(1 for r in fail if r.get("onset"))
    false_alarms = sum(r["false_alarm"] for r in runs)
    return {
        "success_runs": len(success),
        "fail_runs": len(fail),
        "with_onset": sum(1 for r in fail if r.get("onset") is not None),
        "detected": detected,
        "recall": _number(detected / len(fail)) if fail else None,
        "false_alarm_success": sum(r["false_alarm"] for r in success),
        "false_alarm_fail": sum(r["false_alarm"] for r in fail),
        "false_alarm_rate": _number(false_alarms / nominal) if nominal else None,
        "delay_mean": _number(sum(delays) / len(delays)) if delays else None,
        "delay_max": _number(max(delays)) if delays else None,
    }


def run_check(
    config_path: Path,
    *,
    inv: Path | None = None,
    output: Path | None = None,
    workers: int | None = None,
    cross_validate: int | None = None,
    before_work: Callable[[Path | None, Path], None] | None = None,
    progress_factory: ProgressFactory | None = None,
    cluster: Fleet | None = None,
) -> CheckResult:
    """The check stage of ``config_path``: classification or comparison.

    ``before_work`` is called with the refined invariants file the stage will write (``None``
    when it compares data sets) and the invariants file it reads, before any bag is read (the
    command line refuses an output there, before minutes of work).

    ``cross_validate`` K: the successful runs that are also ``<detect>`` runs are scored at
    the run level against invariants inferred from the other K-1 folds of the detect bags.
    ``cluster``: the runs are replayed (and inferred, for cross-validation) as tasks on a
    Dask cluster (:mod:`imrosc.fleet`) instead of ``workers`` local processes.
    """
    out = CheckResult()
    project, out.diagnostics = load_project(config_path)
    if project is None:
        return out
    check = project.check
    if check is None:
        raise CheckStageError(f"{config_path}: the configuration has no <check> element")
    if cross_validate is not None and check.mode != "classify":
        raise CheckStageError(
            f"{config_path}: --cross-validate scores <success> runs; this <check> compares <bag>s"
        )
    base = config_path.parent
    inv_path = inv or base / check.inv
    document = read_invariants(inv_path)
    learnt_for = document.get("project")
    if learnt_for is not None and learnt_for != project.name:
        message = f"{inv_path} was inferred for project {learnt_for!r}, not {project.name!r}"
        out.diagnostics.append(_diagnostic(config_path, check.span, "project-mismatch", message))
    refined_path = output or inv_path.with_name(inv_path.stem + ".refined.inv")
    if before_work is not None:
        before_work(refined_path if check.mode == "classify" else None, inv_path)
    report: dict[str, Any] = {
        "$comment": f"{mark(REPORT)} (imrosc classify)",
        "format": "imrosc-classify",
        "version": 1,
        "config": str(config_path),
        "invariants": str(inv_path),
        "mode": check.mode,
        "select": check.select,
        "beta": check.beta,
        "threshold": check.threshold,
    }
    groups = (
        {"success": check.success, "fail": check.fail}
        if check.mode == "classify"
        else {"reference": check.bags}
    )
    found: dict[str, list[Path]] = {}
    per_entry: dict[str, list[Path]] = {}
    for name, entries in groups.items():
        found[name] = []
        for entry in entries:
            bags, problems = bags_of(base, [entry])
            out.diagnostics += problems
            found[name] += bags
            if name == "fail":
                per_entry[entry] = bags
        report[name] = [str(b) for b in found[name]]
    specs, where = (
        fail_onsets(config_path, check, per_entry) if check.mode == "classify" else ({}, {})
    )
    everything = [b for bags in found.values() for b in bags]
    out.inputs = [inv_path, *everything]
    progress = progress_factory(len(everything)) if progress_factory is not None else None
    # detectors learn from failed runs with an onset: without one, no samples are kept
    logistic = check.mode == "classify" and check.detector == "logistic" and bool(specs)
    observed = observe_runs(
        document, everything, workers, specs, progress, collect=logistic, cluster=cluster
    )
    report["errors"] = [
        {"bag": str(bag), "error": o.error} for bag, o in observed.items() if o.error is not None
    ]
    runs = {
        name: {b: observed[b] for b in bags if observed[b].error is None}
        for name, bags in found.items()
    }
    if check.mode == "classify":
        for bag, outcome in runs["fail"].items():
            if outcome.onset_problem is not None:
                message = f"{outcome.onset_problem}; the run is scored whole"
                span = where[bag].span
                out.diagnostics.append(_diagnostic(config_path, span, "onset-unusable", message))
        overlap = success_in_detect(project, base, found["success"])
        report["success_in_detect"] = [str(b) for b in overlap]
        if cross_validate is not None and not overlap:
            message = (
                f"--cross-validate {cross_validate}: none of the {len(found['success'])} "
                f"<success> bags is a <detect> bag: each is scored against invariants it did "
                f"not teach already, as without the option, and no fold is inferred"
            )
            out.diagnostics.append(
                _diagnostic(config_path, check.span, "cross-validation-unneeded", message)
            )
            cross_validate = None
        success_runs = dict(runs["success"])
        success_broken = {b: o.violated for b, o in runs["success"].items()}
        held: dict[Path, HeldOutRun] = {}
        if cross_validate is not None:
            report["cross_validation"], replaced, problems = cross_validated(
                config_path, project, found["success"], cross_validate, workers, cluster
            )
            out.diagnostics += problems
            success_runs.update({b: o for b, o in replaced.items() if o.error is None})
            success_broken.update({b: o.violated for b, o in replaced.items() if o.error is None})
        else:
            runs_seen = held_out_runs(document, base)
            held = {
                b: runs_seen[b.resolve()]
                for b in overlap
                if b in success_broken and b.resolve() in runs_seen
            }
            success_broken.update({b: set(seen.broken) for b, seen in held.items()})
            report["held_out_scored"] = [str(b) for b in held]
        unscored = [b for b in overlap if cross_validate is None and b not in held]
        if unscored:
            shown = ", ".join(str(b) for b in unscored[:3]) + (", ..." if len(unscored) > 3 else "")
            message = (
                f"{len(unscored)} of {len(found['success'])} <success> bags are <detect> bags "
                f"({shown}) and the invariants file keeps no held-out replay of them: false "
                f"positives are 0 by construction; hold successful runs out of <detect>, "
                f"infer with calibration, or run imrosc classify --cross-validate K"
            )
            out.diagnostics.append(
                _diagnostic(config_path, check.span, "success-in-detect", message)
            )
        onset_runs = {b: o for b, o in runs["fail"].items() if o.onset is not None}
        delays: dict[str, list[float]] = {}
        for outcome in onset_runs.values():
            assert outcome.onset is not None
            for ident, at in outcome.after.items():
                delays.setdefault(ident, []).append(at - outcome.onset)
        detecting = {b: set(o.detected) for b, o in runs["fail"].items()}
        untrained = [
            o for b, o in success_runs.items() if b not in overlap or cross_validate is not None
        ]
        # cross-validated, the <detect> runs are scored by their folds' replays, not again
        # by calibration's held-out units
        whole = (
            whole_monitor(document, runs["fail"], untrained, units=cross_validate is None)
            if check.select == "cover"
            else None
        )
        learnt: list[Learnt] = []
        if logistic:
            learnt, refused = learn_detectors(document, runs["success"], onset_runs)
            report["detectors"] = [detector_entry(d) for d in learnt]
            report["detectors_refused"] = [refused_entry(r) for r in refused]
            document = {**document, "invariants": [*document["invariants"]]}
            for found_detector in learnt:
                ident = found_detector.invariant["id"]
                document["invariants"].append(found_detector.invariant)
                for bag in onset_runs:
                    if str(bag) in found_detector.choice.detected:
                        detecting[bag].add(ident)
                delays[ident] = list(found_detector.choice.delays.values())
        scores, families, chosen = classify(
            document,
            success_broken,
            detecting,
            beta=check.beta,
            threshold=check.threshold,
            before={b: o.before for b, o in onset_runs.items() if o.onset},
            delays=delays if onset_runs else None,
            untested={b: seen.untested for b, seen in held.items()},
            select=check.select,
            detectors={d.invariant["id"]: detector_nominal(d) for d in learnt},
            folds=blocked_runs(runs["fail"]),
            whole=whole,
        )
        report["scores"], report["families"] = scores, families
        if chosen is not None:
            report["cover"] = {
                "chosen": list(chosen.chosen),
                "detected": chosen.detected,
                "false_alarm": _number(chosen.false_alarm),
                "value": _number(chosen.value),
            }
            if chosen.worth is not None:
                report["cover"]["monitor"] = chosen.worth.name
                report["cover"]["held_out"] = [
                    {
                        "monitor": w.name,
                        "detected": w.detected,
                        "early": w.early,
                        "expected_false_alarms": _number(w.expected),
                        "value": _number(w.value),
                    }
                    for w in chosen.candidates
                ]
            if chosen.worth is not None and chosen.worth.name == NONE:
                message = none_kept_message(chosen)
                out.diagnostics.append(
                    _diagnostic(config_path, check.span, "no-monitor-kept", message)
                )
        out.refined = refined(document, scores, report)
        whole_kept = chosen is not None and chosen.worth is not None and chosen.worth.name in WHOLE
        if "alarms" in document and runs["success"] and not whole_kept:
            # (every invariant kept: the file's own rule, calibrated for all of them)
            out.refined["alarms"] = refined_rule(
                out.refined, list(runs["success"]), workers, cluster
            )
        rule = AlarmRule.from_json(out.refined.get("alarms"))
        kept = {inv["id"] for inv in out.refined["invariants"]}
        report["runs"] = [
            held_out_entry(run_entry(o, "success"), held[b], kept, rule)
            if b in held
            else run_entry(o, "success")
            for b, o in success_runs.items()
        ]
        report["runs"] += [run_entry(o, "fail") for o in runs["fail"].values()]
        report["detection"] = detection(report["runs"])
        out.output = refined_path
        report["output"] = str(out.output)
    else:
        report["scores"], report["families"] = compare(
            document, {b: o.violated for b, o in runs["reference"].items()}
        )
        warned = {str(b): list(o.warnings) for b, o in runs["reference"].items() if o.warnings}
        if warned:  # per bag, what replay warns of (topics missing, points unchecked)
            report["warnings"] = warned
        unchecked = {str(b): o.unchecked for b, o in runs["reference"].items() if o.unchecked}
        if unchecked:  # per bag, the points that checked no sample
            report["unchecked"] = unchecked
    out.diagnostics = finalize(out.diagnostics)
    out.report = report
    return out


def blocked_runs(runs: Mapping[Path, RunOutcome], folds: int = FOLDS) -> list[list[Path]]:
    """The runs in blocked folds by their start (:func:`imrosc.folds.blocked`)."""
    bags = list(runs)
    return [
        [bags[k] for k in fold] for fold in blocked(bags, lambda b: (runs[b].start, str(b)), folds)
    ]


def learn_detectors(
    document: Mapping[str, Any],
    success: Mapping[Path, RunOutcome],
    failed: Mapping[Path, RunOutcome],
) -> tuple[list[Learnt], list[Refused]]:
    """The fault detectors of the publish points (:mod:`imrosc.detectors`), from the samples
    of the successful runs and of the failed runs with an onset, and the points whose best
    detector was refused (chance explains its held-out detections). Each of the ``m``
    points a detector is learnt for gets ``budget / m`` of the document's false-alarm
    budget per run (Bonferroni): the monitor's detectors together keep the budget."""
    from imrosc.calibrate import DEFAULT_BUDGET

    candidates = []
    for key, info in sorted(document["points"].items()):
        variables = variables_of(info)
        runs = [
            run_of(str(bag), o.start, o.onset if bag in failed else None, o.samples[key])
            for group in (success, failed)
            for bag, o in group.items()
            if key in o.samples and len(o.samples[key].times)
        ]
        if learnable(variables, runs):
            candidates.append((key, variables, runs))
    budget = float((document.get("calibration") or {}).get("budget", DEFAULT_BUDGET))
    alpha = budget / max(1, len(candidates))
    found: list[Learnt] = []
    refused: list[Refused] = []
    for key, variables, runs in candidates:
        learnt = learn(key, variables, runs, alpha)
        if isinstance(learnt, Refused):
            refused.append(learnt)
        elif learnt is not None:
            found.append(learnt)
    return found, refused


def detector_nominal(learnt: Learnt) -> Nominal:
    """What the held-out good runs say of a learnt detector: ``n`` runs, none above its
    threshold (``1/(n+1)``: the threshold's rank), its share of the budget the ceiling."""
    choice = learnt.choice
    return Nominal(max(choice.nominal - 1, 0), 0, choice.false_alarm)


def detector_entry(learnt: Learnt) -> dict[str, Any]:
    """The report's account of a learnt detector: what its cross-fitting saw."""
    choice = learnt.choice
    return {
        "id": learnt.invariant["id"],
        "point": learnt.invariant["point"],
        "variables": len(learnt.invariant["variables"]),
        **_choice_entry(choice),
        "chance": _number(choice.chance),
        "delays": {run: _number(delay) for run, delay in sorted(choice.delays.items())},
    }


def refused_entry(refused: Refused) -> dict[str, Any]:
    """The report's account of a refused detector: what its best choice detected held
    out, and how likely chance alone would have done as well."""
    choice = refused.choice
    return {
        "point": refused.point,
        "variables": refused.variables,
        **_choice_entry(choice),
        "pairs": choice.tried,
        "chance": _number(choice.chance),
        "share": _number(choice.alpha),
    }


def _choice_entry(choice: Choice) -> dict[str, Any]:
    """What the report says of a detector's cross-fitted choice, kept or refused."""
    return {
        "penalty": choice.strength,
        "smooth": choice.smooth,
        "threshold": _number(choice.threshold),
        "held_out_nominal": choice.nominal,
        "held_out_failed": choice.failed,
        "detected": sorted(choice.detected),
        "horizon": _number(choice.horizon) if math.isfinite(choice.horizon) else None,
        "prompt": choice.prompt,
    }


def success_in_detect(project: Project, base: Path, success: Sequence[Path]) -> list[Path]:
    """The ``<success>`` bags that are also ``<detect>`` bags (resolved paths compared)."""
    if project.detect is None:
        return []
    detect, _ = bags_of(base, project.detect.bags)
    learnt = {b.resolve() for b in detect}
    return [b for b in success if b.resolve() in learnt]


def cross_validated(
    config_path: Path,
    project: Project,
    success: Sequence[Path],
    folds: int,
    workers: int | None,
    cluster: Fleet | None = None,
) -> tuple[dict[str, Any], dict[Path, RunOutcome], list[Diagnostic]]:
    """The successful runs that are detect runs, each replayed against the invariants
    inferred from the folds of the detect bags that do not hold it (stability's folds)."""
    from imrosc.detect import run_detect
    from imrosc.stability import folds_of

    if project.detect is None:
        raise CheckStageError(f"{config_path}: --cross-validate needs a <detect> element")
    detect, problems = bags_of(config_path.parent, project.detect.bags)
    if not 2 <= folds <= len(detect):
        raise CheckStageError(
            f"{config_path}: --cross-validate {folds} needs 2 <= K <= the {len(detect)} "
            f"<detect> bag(s)"
        )
    rounds: list[dict[str, Any]] = []
    replaced: dict[Path, RunOutcome] = {}
    for held_out in folds_of(detect, folds):
        train = [b for b in detect if b not in held_out]
        held = {b.resolve() for b in held_out}
        scored = [b for b in success if b.resolve() in held]
        detected = run_detect(
            config_path,
            workers=workers,
            bags=train,
            reducer=cluster,
            replays=cluster.replay_held_out if cluster is not None else None,
            noter=cluster.note_bags if cluster is not None else None,
        )
        for problem in detected.diagnostics:
            if problem.code.startswith("bag-"):
                problems.append(problem)
        inferred = detected.document
        if inferred is None or has_errors(detected.diagnostics):
            raise CheckStageError(
                f"{config_path}: cross-validation could not infer from "
                f"{', '.join(str(b) for b in train)}: "
                + "; ".join(
                    d.as_text() for d in detected.diagnostics if d.severity.value == "error"
                )
            )
        outcomes = observe_runs(inferred, scored, workers, cluster=cluster) if scored else {}
        replaced.update(outcomes)
        rounds.append(
            {
                "held_out": [str(b) for b in held_out],
                "trained_on": [str(b) for b in train],
                "invariants": len(inferred["invariants"]),
                "success": [
                    {
                        "bag": str(b),
                        "violated": len(o.first),
                        "alarms": len(o.alarms),
                        "error": o.error,
                    }
                    for b, o in outcomes.items()
                ],
            }
        )
    report = {
        "folds": folds,
        "rounds": rounds,
        "scored": [str(b) for b in replaced],
        "note": "successful runs that are detect runs are scored against the invariants of "
        "the folds that do not hold them; failed runs against the checked invariants file",
    }
    return report, replaced, problems
