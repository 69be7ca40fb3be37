"""Replay: bags fed to the runtime engine as if live, message by message, in bag order.

The very engine the monitor runs (``imrosc.runtime``) gets each message flattened with the
flattener the monitor uses, each service call, parameter set and architecture snapshot
from the ``/imrosc/*`` records, and the clock of the bag. A bag without architecture
records gives its connections' publishers (ROS 1 ``callerid``), each from its connection's
first message on, which tells publishers only, as in inference. Each ROS 1 message comes with
its connection's publisher, as a live monitor hears it: a publisher the architecture does
not know breaks its ``max_pubs`` invariants and is checked by no other
(``Engine.intruder``). Each bag is one run: the
engine is reset between bags. A bag missing topics the invariants read gets a warning; a bag
holding none of them is not read at all.
"""

from __future__ import annotations

import os
from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from imrosc import records
from imrosc.bags import BagError, MessageError, open_bag, publisher_of, recovered
from imrosc.checking.recorded import RECORDS, record_call
from imrosc.checking.run import ChunkedChecker, gc_paused
from imrosc.graph.bags import PublisherStart, publisher_starts
from imrosc.outputs import REPORT, mark
from imrosc.progress import Progress, bag_done
from imrosc.runtime import Engine, Violation
from imrosc.runtime.alarms import Alarm, alarms_json
from imrosc.runtime.families import FREQUENCY, POLYGON
from imrosc.runtime.flatten import make_flattener
from imrosc.runtime.violation import json_safe

CHUNKED = "IMROSC_CHUNKED"
"""Environment: ``0`` replays message by message (the per-message engine) by default."""


@dataclass
class RunResult:
    """What replaying one bag gave."""

    bag: Path
    violations: list[Violation] = field(default_factory=list)
    alarms: list[Alarm] = field(default_factory=list)
    messages: int = 0
    start: float = 0.0
    end: float = 0.0
    skipped: int = 0
    error: str | None = None
    warnings: list[str] = field(default_factory=list)
    """What the run could not check: topics of the invariants missing from the bag."""
    checked: dict[str, int] = field(default_factory=dict)
    """Per value point (publish, call, parameter), the samples it checked."""
    recovered: str | None = None
    """What was recovered of a ROS 1 bag cut short or never indexed (also a warning)."""
    unchecked: list[str] = field(default_factory=list)
    """The unconditional publish points that checked no sample: their invariants were not
    checked in this run (``imrosc replay`` and ``classify`` exit with their own status)."""

    @property
    def violated(self) -> set[str]:
        """Ids of the invariants this run broke."""
        return {v.invariant for v in self.violations}


class _Publishers:
    """The publishers of a bag without architecture records, each from its connection's
    first message on (``starts``, earliest first)."""

    def __init__(self, starts: list[PublisherStart]) -> None:
        self.starts = starts
        self.seen: dict[str, set[str]] = {}

    def until(self, engine: Engine, stamp: int) -> list[Violation]:
        """Feed the engine a snapshot at each first message up to ``stamp`` (ns)."""
        found: list[Violation] = []
        while self.starts and self.starts[0].time <= stamp:
            at = self.starts[0].time
            while self.starts and self.starts[0].time == at:
                start = self.starts.pop(0)
                self.seen.setdefault(start.topic, set()).add(start.node)
            snapshot = {"pub": {t: frozenset(p) for t, p in self.seen.items()}}
            found += engine.graph(at / 1e9, snapshot, ("pub",))
        return found


def _topic_warnings(wanted: Iterable[str], present: Iterable[str]) -> list[str]:
    """A warning naming the invariants' topics a bag lacks (all of them: nothing is read)."""
    wanted = sorted(set(wanted))
    missing = sorted(set(wanted) - set(present))
    if not missing:
        return []
    if len(missing) == len(wanted):
        return [f"none of the invariants' topics is in this bag ({', '.join(missing)}): not read"]
    return [f"no messages on {', '.join(missing)}: their invariants are not checked"]


def _unchecked(
    document: Mapping[str, Any], checked: Mapping[str, int], present: Iterable[str]
) -> list[str]:
    """A warning per unconditional publish point that checked no sample although its
    topic was read: an input topic or parameter it pairs every message with never came,
    so its invariants were never checked (a conditional point whose condition never held
    is a state the run did not visit, not a fault)."""
    read = set(present)
    found = []
    for key, count in sorted(checked.items()):
        info = document["points"].get(key, {})
        if count or info.get("kind") != "publish" or info.get("condition"):
            continue
        if info.get("trigger") in read:
            found.append(
                f"point {key} checked no sample: a topic or parameter it pairs "
                f"{info.get('trigger')} with never came"
            )
    return found


def no_samples(document: Mapping[str, Any], checked: Mapping[str, int]) -> list[str]:
    """The unconditional publish points that checked no sample (a conditional point whose
    condition never held is a state the run did not visit, not a gap in the check)."""
    points = document["points"]
    return [
        key
        for key, count in sorted(checked.items())
        if not count
        and points.get(key, {}).get("kind") == "publish"
        and not points.get(key, {}).get("condition")
    ]


def _drifted(topics: Mapping[str, Any], connections: Iterable[Any]) -> dict[str, str]:
    """Per topic whose type in the bag is not the one the invariants were learnt on, a
    warning naming both: its messages are not read (its fields may mean other things)."""
    found: dict[str, str] = {}
    for connection in connections:
        learnt = (topics.get(connection.topic) or {}).get("type")
        if learnt and connection.msgtype != learnt and connection.topic not in found:
            found[connection.topic] = (
                f"topic {connection.topic} has type {connection.msgtype} in this bag but "
                f"{learnt} in the invariants: its points are not checked"
            )
    return found


class Replayer:
    """Feeds bags to one engine built from an invariants document.

    A bag is checked over column chunks (:mod:`imrosc.checking`: the same violations,
    alarms and samples kept by a recording alarm tracker, in the same order, at decode
    speed) unless ``chunked`` is false (by default when ``IMROSC_CHUNKED=0``): then each
    message goes to the engine in turn (:meth:`run_messages`).
    """

    def __init__(
        self,
        document: Mapping[str, Any],
        engine: Engine | None = None,
        chunked: bool | None = None,
    ) -> None:
        self.document = document
        self.engine = engine if engine is not None else Engine(document, lazy=True)
        self.flatteners: dict[str, Callable[[Any], list[Any]]] = {
            topic: make_flattener(info["variables"]) for topic, info in document["topics"].items()
        }
        self.chunked = chunked if chunked is not None else os.environ.get(CHUNKED, "1") != "0"
        self._checker: ChunkedChecker | None = None

    def run(self, bag: Path) -> RunResult:
        """Replay one bag as one run; a broken bag gives its error instead of raising."""
        if self._checker is None and not self.chunked:
            return self.run_messages(bag)
        if self._checker is None:
            self._checker = ChunkedChecker(self.document, self.engine)
        result = RunResult(bag)
        self._checker.run(bag, result)
        return result

    def run_messages(self, bag: Path) -> RunResult:
        """Replay one bag as one run, message by message (the monitor's way)."""
        result = RunResult(bag)
        engine = self.engine
        engine.reset()
        found = result.violations
        try:
            with open_bag(bag) as reader, np.errstate(all="ignore"):
                result.start, result.end = reader.start_time / 1e9, reader.end_time / 1e9
                result.recovered = recovered(reader)
                result.warnings += filter(None, [result.recovered])
                drifted = _drifted(self.document["topics"], reader.connections)
                result.warnings += drifted.values()
                wanted = [
                    c
                    for c in reader.connections
                    if (c.topic in self.flatteners or c.topic in RECORDS)
                    and c.msgcount
                    and c.topic not in drifted
                ]
                present = {c.topic for c in wanted}
                result.warnings += _topic_warnings(set(self.flatteners) - set(drifted), present)
                publishers = _Publishers(
                    [] if records.ARCH_TOPIC in present else publisher_starts(reader)
                )
                # rosbags reads every message when given no connection
                for connection, stamp, raw in reader.messages(wanted) if wanted else ():
                    found += publishers.until(engine, stamp)
                    result.messages += 1
                    time = stamp / 1e9
                    try:
                        message = reader.deserialize(raw, connection.msgtype)
                    except MessageError:
                        result.skipped += 1
                        continue
                    topic = connection.topic
                    flatten = self.flatteners.get(topic)
                    if flatten is not None:
                        values = flatten(message)
                        found += engine.message(topic, time, values, publisher_of(connection))
                    else:
                        found += self._record(topic, time, message)
                found += publishers.until(engine, reader.end_time)
                result.checked = engine.checked()
                result.unchecked = no_samples(self.document, result.checked)
                result.warnings += _unchecked(self.document, result.checked, present)
                withdrawn = {id(v) for v in engine.end_run()}
                if withdrawn:
                    found[:] = [v for v in found if id(v) not in withdrawn]
                result.alarms = [
                    a for a in engine.take_alarms() if id(a.violation) not in withdrawn
                ]
        except BagError as error:
            result.error = str(error)
        return result

    def _record(self, topic: str, time: float, message: Any) -> list[Violation]:
        call = record_call(self.engine, topic, message)
        return [] if call is None else call(time)


def replay(document: Mapping[str, Any], bags: Iterable[Path]) -> list[RunResult]:
    """Replay each bag as one run (alarms under the file's rule)."""
    replayer = Replayer(document)
    return [replayer.run(bag) for bag in bags]


EPISODE_GAP = 1.0
"""Seconds: violations of one invariant closer than this form one episode of the timeline."""
PLOT_POINTS = 4096
"""Samples kept per point for plots (every k-th, k doubling as the run grows)."""


def episodes(violations: Iterable[Violation]) -> list[dict[str, Any]]:
    """The timeline: per invariant, runs of violations no more than EPISODE_GAP apart."""
    open_: dict[str, dict[str, Any]] = {}
    done: list[dict[str, Any]] = []
    for v in violations:
        current = open_.get(v.invariant)
        if current is not None and v.time - current["last"] <= EPISODE_GAP:
            current["last"] = v.time
            current["count"] += 1
            continue
        if current is not None:
            done.append(current)
        open_[v.invariant] = {
            "invariant": v.invariant,
            "point": v.point,
            "family": v.family,
            "kind": v.kind,
            "text": v.text,
            "first": v.time,
            "last": v.time,
            "count": 1,
            "observed": json_safe(v.observed),
            "expected": v.expected,
        }
    done += open_.values()
    return sorted(done, key=lambda e: (e["first"], e["invariant"]))


class PlotTrace:
    """Keeps a thinned copy of the samples of points with polygons or frequencies."""

    def __init__(self, document: Mapping[str, Any]) -> None:
        self.wanted = {
            i["point"] for i in document["invariants"] if i["family"] in (POLYGON, FREQUENCY)
        }
        self.points = document["points"]
        self.reset()

    def reset(self) -> None:
        self.samples: dict[str, list[tuple[float, Any, float | None]]] = {}
        self.stride: dict[str, int] = {}
        self.seen: dict[str, int] = {}

    def __call__(self, point: str, time: float, row: Any, frequency: float | None) -> None:
        if point not in self.wanted:
            return
        seen = self.seen.get(point, 0)
        self.seen[point] = seen + 1
        stride = self.stride.get(point, 1)
        if seen % stride:
            return
        kept = self.samples.setdefault(point, [])
        kept.append((time, row, frequency))
        if len(kept) >= PLOT_POINTS:
            self.samples[point] = kept[::2]
            self.stride[point] = stride * 2

    def trace_rows(
        self, point: str, times: Sequence[float], rows: Any, frequencies: Sequence[float | None]
    ) -> None:
        """A chunk of samples of ``point`` at once (``rows``: a matrix), kept as calling
        the trace with each in turn keeps them."""
        if point not in self.wanted:
            return
        count = len(times)
        seen = self.seen.get(point, 0)
        self.seen[point] = seen + count
        kept = self.samples.setdefault(point, [])
        stride = self.stride.get(point, 1)
        at = -seen % stride  # the first sample of the chunk whose number the stride divides
        chosen: list[int] = []
        while at < count:
            chosen.append(at)
            kept.append((times[at], at, frequencies[at]))
            if len(kept) >= PLOT_POINTS:
                kept = self.samples[point] = kept[::2]
                stride = self.stride[point] = stride * 2
            at += stride - (seen + at) % stride
        # the rows of this chunk still kept, copied at once (not views of the chunk)
        fresh = {at: k for k, at in enumerate(chosen)}
        copied = rows[chosen] if chosen else rows[:0]
        first = len(kept) - sum(1 for entry in kept if isinstance(entry[1], int))
        for k in range(first, len(kept)):
            time, at, frequency = kept[k]
            kept[k] = (time, copied[fresh[at]], frequency)

    def plots(self, document: Mapping[str, Any], found: list[Violation]) -> dict[str, Any]:
        """Plots of the violated polygons and frequencies of one run."""
        broken: dict[str, list[Violation]] = {}
        for v in found:
            if v.family in (POLYGON, FREQUENCY):
                broken.setdefault(v.invariant, []).append(v)
        polygons, frequencies = [], []
        matrices: dict[str, Any] = {}
        for inv in document["invariants"]:
            hits = broken.get(inv["id"])
            if not hits:
                continue
            samples = self.samples.get(inv["point"], [])
            numeric = [
                v["name"]
                for v in self.points[inv["point"]]["variables"]
                if v["type"] in ("float", "int", "uint", "bool", "time")
            ]
            if inv["family"] == POLYGON:
                xi, yi = (numeric.index(n) for n in inv["variables"])
                if inv["point"] not in matrices:  # the point's kept rows, once
                    matrices[inv["point"]] = np.array([r for _, r, _ in samples], np.float64)
                polygons.append(
                    {
                        "invariant": inv["id"],
                        "point": inv["point"],
                        "text": inv["text"],
                        "x": inv["variables"][0],
                        "y": inv["variables"][1],
                        "vertices": inv["params"]["vertices"],
                        "trajectory": _trajectory(samples, matrices[inv["point"]], xi, yi),
                        "offending": [[v.time, *json_safe(list(v.observed))] for v in hits][
                            :PLOT_POINTS
                        ],
                    }
                )
            else:
                frequencies.append(
                    {
                        "invariant": inv["id"],
                        "point": inv["point"],
                        "topic": inv["params"].get("topic", inv["point"]),
                        "min": inv["params"]["min"],
                        "max": inv["params"]["max"],
                        "series": [[t, f] for t, _, f in samples if f is not None],
                    }
                )
        return {"polygons": polygons, "frequencies": frequencies}


def _trajectory(
    samples: Sequence[tuple[float, Any, float | None]], rows: Any, xi: int, yi: int
) -> list[list[Any]]:
    """``[time, x, y]`` of each kept sample (``rows``: their values), JSON-safe."""
    if not len(samples):
        return []
    xs, ys = rows[:, xi], rows[:, yi]
    times = [t for t, _, _ in samples]
    if np.isfinite(xs).all() and np.isfinite(ys).all():
        return [[t, x, y] for t, x, y in zip(times, xs.tolist(), ys.tolist(), strict=True)]
    return [
        [t, json_safe(x), json_safe(y)]
        for t, x, y in zip(times, xs.tolist(), ys.tolist(), strict=True)
    ]


class RunReplayer:
    """Replays bag after bag against one invariants document (its engine built once)."""

    def __init__(self, document: Mapping[str, Any], plots: bool) -> None:
        self.document = document
        self.trace = PlotTrace(document) if plots else None
        self.replayer = Replayer(document, Engine(document, self.trace, lazy=True))

    def __call__(self, bag: Path) -> tuple[RunResult, dict[str, Any]]:
        """A bag's result and its run in the report."""
        if self.trace is not None:
            self.trace.reset()
        with gc_paused():  # the run's checking, then its plots
            result = self.replayer.run(bag)
            run = self._run(bag, result)
        return result, run

    def _run(self, bag: Path, result: RunResult) -> dict[str, Any]:
        """A bag's run in the report."""
        trace, document = self.trace, self.document
        return {
            "bag": str(bag),
            "start": result.start,
            "end": result.end,
            "messages": result.messages,
            "skipped": result.skipped,
            "error": result.error,
            "warnings": list(result.warnings),
            "checked": dict(result.checked),
            "unchecked": list(result.unchecked),
            "violations": len(result.violations),
            "alarms": alarms_json(result.alarms),
            "episodes": episodes(result.violations),
            "plots": trace.plots(document, result.violations)
            if trace is not None
            else {"polygons": [], "frequencies": []},
        }


RunsReplay = Callable[
    [Mapping[str, Any], list[Path], bool, "Progress | None"],
    list[tuple["RunResult", dict[str, Any]]],
]
"""Replays the bags elsewhere (a cluster, :mod:`imrosc.fleet`), their runs in bag order."""


def replay_document(
    inv: Path,
    document: Mapping[str, Any],
    bags: Iterable[Path],
    *,
    plots: bool = True,
    progress: Progress | None = None,
    elsewhere: RunsReplay | None = None,
) -> tuple[dict[str, Any], list[RunResult]]:
    """Replay ``bags`` and describe each run: its timeline and, with ``plots``, the data
    of its violated polygons and frequencies; ``progress`` hears of each bag done;
    ``elsewhere`` replays them instead (a cluster)."""
    if elsewhere is not None:
        answers = elsewhere(document, list(bags), plots, progress)
    else:
        replay = RunReplayer(document, plots)
        answers = []
        for bag in bags:
            answers.append(replay(bag))
            bag_done(progress, bag, answers[-1][0].messages, answers[-1][0].error)
    results = [result for result, _ in answers]
    runs = [run for _, run in answers]
    out = {
        "$comment": f"{mark(REPORT)} (imrosc replay)",
        "format": "imrosc-replay",
        "version": 1,
        "invariants": str(inv),
        "project": document.get("project", ""),
        "runs": runs,
    }
    return out, results
