"""The inference engine: bags to per-point family states, merged in bag order, finalized.

Each bag is one run. A worker translates one bag and updates fresh states of every point;
the parent merges the bags' states in sorted bag order. ``-j 1`` runs the very same per-bag
work in-process, so the result is the same whatever the number of workers; that merging
equals one sequential pass is each family's own guarantee (tested per family).

Conditional invariants (thesis 3.6): declared conditions are points of the plan already;
discrete variables (integers, bools, strings with 2 to ``discrete`` values over all runs)
are found in the first pass, and a second pass over the points that have them infers one
conditional point per value (``a?state==4``).
"""

from __future__ import annotations

import copy
import math
import multiprocessing
import os
from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any, Protocol, runtime_checkable

import numpy as np

from imrosc.bags import BagError
from imrosc.infer.core import (
    FamilyState,
    FinalizeContext,
    Invariant,
    Samples,
    Variable,
    condition_restarts,
)
from imrosc.infer.registry import make_point_states
from imrosc.ir import Tunables
from imrosc.progress import bag_done
from imrosc.runtime.families import (
    BOUNDS,
    MEAN,
    ONE_OF,
    PATTERN,
    RATE,
    STEP,
    STRING_ONE_OF,
    VARIANCE,
)
from imrosc.translate.layout import TopicLayout
from imrosc.translate.points import PointSpec
from imrosc.translate.stream import BagTranslator


@dataclass
class DiscreteValues:
    """The values of a point's discrete variables, up to ``limit + 1`` each (mergeable)."""

    limit: int
    values: dict[str, set[Any]] = field(default_factory=dict)

    def update(self, samples: Samples) -> None:
        for variable in samples.variables:
            if not variable.discrete:
                continue
            seen = self.values.setdefault(variable.name, set())
            if len(seen) > self.limit:
                continue
            column = samples.column(variable.name)
            kept = column if column.dtype == object else column[~np.isnan(column)]
            seen.update(np.unique(kept[: 4 * (self.limit + 1)]).tolist())
            if len(seen) <= self.limit:
                seen.update(np.unique(kept).tolist())

    def merge(self, other: DiscreteValues) -> None:
        for name, values in other.values.items():
            self.values.setdefault(name, set()).update(values)

    def conditions(self) -> list[tuple[str, Any]]:
        """(variable, value) for each variable with 2 to ``limit`` values."""
        return [
            (name, value)
            for name, values in sorted(self.values.items())
            if 2 <= len(values) <= self.limit
            for value in sorted(values, key=repr)
        ]


@dataclass
class PointState:
    """The family states of one point and its support."""

    spec: PointSpec
    states: list[FamilyState]
    samples: int = 0
    runs: int = 0
    discrete: DiscreteValues | None = None
    nonfinite: dict[str, list[int]] = field(default_factory=dict)
    """Per numeric variable that had some, its NaN (or missing), +inf and -inf values: the
    families leave them out, ``imrosc infer`` says how many there were."""
    _in_run: bool = False

    def update(self, samples: Samples) -> None:
        self.samples += len(samples)
        self._in_run = True
        count_nonfinite(self.nonfinite, samples)
        for state in self.states:
            state.update(samples)
        if self.discrete is not None:
            self.discrete.update(samples)

    def end_run(self) -> None:
        self.runs += int(self._in_run)
        self._in_run = False
        for state in self.states:
            state.end_run()

    def merge(self, other: PointState) -> None:
        self.samples += other.samples
        self.runs += other.runs
        for name, counts in other.nonfinite.items():
            sums = self.nonfinite.setdefault(name, [0, 0, 0])
            sums[:] = [a + b for a, b in zip(sums, counts, strict=True)]
        for mine, theirs in zip(self.states, other.states, strict=True):
            mine.merge(theirs)
        if self.discrete is not None and other.discrete is not None:
            self.discrete.merge(other.discrete)

    def finalize(self, tunables: Tunables, condition: str | None) -> list[Invariant]:
        context = FinalizeContext(
            tunables, self.spec.variables, self.spec.key, condition, self.runs
        )
        found: list[Invariant] = []
        for state in self.states:
            found += state.finalize(context)
        return suppress_implied(found)


def count_nonfinite(counts: dict[str, list[int]], samples: Samples) -> None:
    """Add the NaN, +inf and -inf values of each numeric variable of ``samples`` (not the
    statistics of arrays) to ``counts``."""
    for variable in samples.variables:
        if not variable.numeric or variable.derived is not None:
            continue
        column = samples.column(variable.name)
        finite = np.isfinite(column)
        if finite.all():
            continue
        bad = column[~finite]
        nan = int(np.isnan(bad).sum())
        positive = int((bad > 0).sum())
        found = counts.setdefault(variable.name, [0, 0, 0])
        found[0] += nan
        found[1] += positive
        found[2] += len(bad) - nan - positive


WINDOW_STATISTICS = frozenset({VARIANCE, RATE, MEAN, STEP})
"""Window statistics of one variable: a constant's say nothing its one-of does not."""


def suppress_implied(found: list[Invariant]) -> list[Invariant]:
    """Drop what another family's invariant implies: a constant has no variance, no rate and
    no mean but itself.

    >>> from imrosc.infer.core import Invariant
    >>> c = Invariant("one-of", "one-of", "a", ("x",), {"values": [0.0]}, "x == 0", 9, 0.99)
    >>> r = Invariant("rate", "range", "a", ("x",), {"min": 0.0, "max": 0.0}, "", 9, 0.99)
    >>> [i.family for i in suppress_implied([c, r])]
    ['one-of']
    """
    constants = {
        invariant.variables[0]
        for invariant in found
        if invariant.family in (ONE_OF, STRING_ONE_OF)
        and len(invariant.params.get("values", ())) == 1
    }
    kept: list[Invariant] = []
    languages: set[str] = set()
    for invariant in found:
        if invariant.family in WINDOW_STATISTICS and set(invariant.variables) <= constants:
            continue
        if invariant.family == PATTERN:  # one language, however its placeholders were bound
            machine = repr((invariant.params.get("transitions"), invariant.params.get("accepting")))
            if machine in languages:
                continue
            languages.add(machine)
        kept.append(invariant)
    return kept


def informative_only(found: list[Invariant]) -> list[Invariant]:
    """Drop the window means that say little beyond their variable's bounds.

    The mean over a window of a smooth signal is nearly the signal: its envelope is the
    bounds' again, and its violations last as long as the signal's excursion, so it adds
    false alarms and no evidence. It is kept where the windows average most of the values'
    spread away: its envelope spans at most half the bounds' range (a noisy sensor's level,
    which a scaled or biased reading moves while every sample stays within the range). Only
    the merged invariants are filtered: each run's own keep every mean, so calibration reads
    every run's extreme.

    >>> from imrosc.infer.core import Invariant
    >>> def make(family, low, high):
    ...     return Invariant(family, "range", "a", ("x",), {"min": low, "max": high}, "", 9, 0.9)
    >>> [i.family for i in informative_only([make("bounds", 0.0, 10.0), make("mean", 4.0, 6.0)])]
    ['bounds', 'mean']
    >>> [i.family for i in informative_only([make("bounds", 0.0, 10.0), make("mean", 1.0, 9.0)])]
    ['bounds']
    """
    spans = {
        (i.point, i.variables[0], i.condition): i.params["max"] - i.params["min"]
        for i in found
        if i.family == BOUNDS and len(i.variables) == 1 and "min" in i.params and "max" in i.params
    }
    kept: list[Invariant] = []
    for invariant in found:
        if invariant.family == MEAN:
            span = spans.get((invariant.point, invariant.variables[0], invariant.condition))
            width = invariant.params["max"] - invariant.params["min"]
            if span is not None and not width < span / 2:  # (NaN: not informative either)
                continue
        kept.append(invariant)
    return kept


def new_states(
    specs: Sequence[PointSpec], tunables: Tunables, *, discover: bool
) -> dict[str, PointState]:
    """Fresh states for every spec."""
    states = {}
    for spec in specs:
        tracker = None
        if (
            discover
            and tunables.discrete > 0
            and spec.condition is None
            and spec.kind in ("publish", "call")
        ):
            tracker = DiscreteValues(tunables.discrete)
        states[spec.key] = PointState(spec, make_point_states(spec, tunables), discrete=tracker)
    return states


@dataclass(frozen=True)
class Discovered:
    """A condition found in the first pass: ``variable == value`` at ``point``."""

    point: str
    variable: str
    value: Any

    @property
    def text(self) -> str:
        """The condition as an expression: ``subject_ctrl_state.data==4``."""
        shown = f"'{self.value}'" if isinstance(self.value, str) else _number_text(self.value)
        return f"{self.variable}=={shown}"

    @property
    def key(self) -> str:
        return f"{self.point}?{self.text}"


def _number_text(value: Any) -> str:
    number = float(value)
    return str(int(number)) if number.is_integer() else repr(number)


@dataclass
class Unit:
    """The invariants of one unit of calibration: a whole run, or a time segment of one
    (``span``, seconds of the bag's clock) when there are too few runs."""

    bag: Path
    invariants: list[Invariant]
    span: tuple[float, float] | None = None
    start: float = 0.0
    """When its recording began (bag clock, s): calibration holds out neighbours together."""
    end: float | None = None
    """When its recording ended (bag clock, s; ``None``: unknown): runs that overlap on the
    bag clock are not told apart by their starts (:func:`imrosc.folds.at_gaps`)."""


MIN_RUNS = 4
"""With fewer bags, calibration splits each into time segments (pseudo-runs)."""
MIN_UNITS = 6
"""How many pseudo-runs the segments give at least."""


def segments_for(runs: int) -> int:
    """Segments per bag for calibration: 1 (runs are the units) with :data:`MIN_RUNS` bags
    or more, else enough for :data:`MIN_UNITS` pseudo-runs.

    >>> [segments_for(r) for r in (1, 2, 3, 4, 10)]
    [6, 3, 2, 1, 1]
    """
    return 1 if runs >= MIN_RUNS else math.ceil(MIN_UNITS / max(runs, 1))


@dataclass(frozen=True)
class BagJob:
    """What a worker needs to translate and infer one bag."""

    bag: Path
    run: int
    specs: tuple[PointSpec, ...]
    layouts: Mapping[str, TopicLayout]
    callerids: Mapping[str, frozenset[str]]
    tunables: Tunables
    discovered: tuple[Discovered, ...] = ()
    discover: bool = True
    units: int = 0
    """Calibration: 0 none, 1 the bag's own invariants, n > 1 those of n time segments."""


@dataclass
class BagResult:
    """A worker's answer: the states of every point for one bag, or why the bag failed;
    with calibration, the invariants of the bag (or of its segments) alone."""

    bag: Path
    states: dict[str, PointState] = field(default_factory=dict)
    messages: int = 0
    error: str | None = None
    skipped: dict[str, int] = field(default_factory=dict)
    units: list[Unit] = field(default_factory=list)


class _Segments:
    """Fresh point states per time segment of one bag, fed the rows of their segment."""

    def __init__(self, count: int, make: Callable[[str], PointState]) -> None:
        self.count = count
        self.make = make
        self.states: list[dict[str, PointState]] = [{} for _ in range(count)]
        self.span = (0.0, 0.0)

    def feed(self, key: str, samples: Samples) -> None:
        start, end = self.span
        width = (end - start) / self.count or 1.0
        index = np.clip(((samples.time - start) / width).astype(np.int64), 0, self.count - 1)
        for segment in np.unique(index).tolist():
            states = self.states[segment]
            state = states.get(key)
            if state is None:
                state = states[key] = self.make(key)
            state.update(samples.select(index == segment))

    def units(self, bag: Path, finalize: Callable[[PointState], list[Invariant]]) -> list[Unit]:
        start, end = self.span
        width = (end - start) / self.count
        found = []
        for segment, states in enumerate(self.states):
            invariants: list[Invariant] = []
            for state in states.values():
                state.end_run()
                invariants += finalize(state)
            span = (start + segment * width, start + (segment + 1) * width)
            found.append(Unit(bag, invariants, span, span[0], span[1]))
        return found


def run_bag(job: BagJob) -> BagResult:
    """Translate one bag and update fresh states (the work of one worker)."""
    os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
    second_pass = bool(job.discovered)
    states = {} if second_pass else new_states(job.specs, job.tunables, discover=job.discover)
    split = _conditional_states(job)
    callerids = {k: set(v) for k, v in job.callerids.items()}
    translator = BagTranslator(job.specs, job.layouts, callerids)
    segments = _Segments(job.units, _state_maker(job)) if job.units > 1 else None
    gaps: dict[str, bool] = {}
    """Per discovered condition: it did not hold at the point's last sample so far."""
    try:
        for samples in translator.translate(job.bag, job.run):
            if segments is not None:
                segments.span = translator.span
            if not second_pass:
                states[samples.point].update(samples)
                if segments is not None:
                    segments.feed(samples.point, samples)
            for discovered, state in split.get(samples.point, ()):
                column = samples.column(discovered.variable)
                held = column == discovered.value
                begins, gaps[discovered.key] = condition_restarts(
                    held, gaps.get(discovered.key, False), samples.restarts
                )
                chosen = samples.select(held, begins)
                state.update(chosen)
                if segments is not None:
                    segments.feed(discovered.key, chosen)
    except BagError as error:
        return BagResult(job.bag, error=error.message)
    for state in states.values():
        state.end_run()
    for pairs in split.values():
        for discovered, state in pairs:
            state.end_run()
            states[discovered.key] = state
    result = BagResult(job.bag, states, translator.messages, skipped=translator.skipped)
    finalize = _finalizer(job)
    if segments is not None:
        result.units = segments.units(job.bag, finalize)
    elif job.units == 1:
        alone = [i for s in copy.deepcopy(list(states.values())) for i in finalize(s)]
        result.units = [Unit(job.bag, alone, start=translator.span[0], end=translator.span[1])]
    return result


def _state_maker(job: BagJob) -> Callable[[str], PointState]:
    """Fresh states of a point of the job, by key (conditional keys included)."""
    by_key = {spec.key: spec for spec in job.specs}
    for discovered in job.discovered:
        by_key[discovered.key] = replace(by_key[discovered.point], key=discovered.key)

    def make(key: str) -> PointState:
        spec = by_key[key]
        return PointState(spec, make_point_states(spec, job.tunables))

    return make


def _finalizer(job: BagJob) -> Callable[[PointState], list[Invariant]]:
    """Finalizes a state of the job with its condition (declared or discovered)."""
    conditions = {d.key: d.text for d in job.discovered}

    def finalize(state: PointState) -> list[Invariant]:
        spec = state.spec
        condition = spec.condition.id if spec.condition else conditions.get(spec.key)
        return state.finalize(job.tunables, condition)

    return finalize


def _conditional_states(job: BagJob) -> dict[str, list[tuple[Discovered, PointState]]]:
    by_key = {spec.key: spec for spec in job.specs}
    split: dict[str, list[tuple[Discovered, PointState]]] = {}
    for discovered in job.discovered:
        spec = replace(by_key[discovered.point], key=discovered.key)
        state = PointState(spec, make_point_states(spec, job.tunables))
        split.setdefault(discovered.point, []).append((discovered, state))
    return split


@dataclass
class InferenceResult:
    """Merged states of all bags, and what went wrong on the way."""

    states: dict[str, PointState]
    bags: list[Path]
    failed: dict[Path, str]
    messages: int
    discovered: tuple[Discovered, ...] = ()
    empty: tuple[Path, ...] = ()
    units: list[Unit] = field(default_factory=list)
    """With calibration: the invariants of each run (or segment) alone, in bag order."""

    def invariants(self, tunables: Tunables) -> list[Invariant]:
        conditions = {d.key: d.text for d in self.discovered}
        found: list[Invariant] = []
        for key, state in self.states.items():
            condition = state.spec.condition.id if state.spec.condition else conditions.get(key)
            found += state.finalize(tunables, condition)
        return informative_only(found)


Progress = Callable[[Path, int], None]


def _map(jobs: Sequence[BagJob], workers: int, progress: Progress | None) -> list[BagResult]:
    results: list[BagResult] = []
    if workers <= 1 or len(jobs) <= 1:
        for job in jobs:
            results.append(run_bag(job))
            bag_done(progress, job.bag, results[-1].messages, results[-1].error)
        return results
    context = multiprocessing.get_context("fork")
    with context.Pool(min(workers, len(jobs))) as pool:
        for result in pool.imap(run_bag, jobs):
            results.append(result)
            bag_done(progress, result.bag, result.messages, result.error)
    return results


@dataclass
class Merged:
    """The merged answers of consecutive bags: their states (``None`` until a bag that could
    be read), failed and empty bags, messages and calibration units, all in bag order."""

    states: dict[str, PointState] | None = None
    failed: dict[Path, str] = field(default_factory=dict)
    messages: int = 0
    empty: list[Path] = field(default_factory=list)
    units: list[Unit] = field(default_factory=list)

    @classmethod
    def of(cls, result: BagResult) -> Merged:
        """One bag's answer (a failed bag brings its error and nothing else)."""
        if result.error is not None:
            return cls(failed={result.bag: result.error})
        empty = [] if result.messages else [result.bag]
        return cls(result.states, {}, result.messages, empty, list(result.units))

    def join(self, later: Merged) -> Merged:
        """Absorb the answers of the bags that come right after ours (in place): the exact
        merge of every point's states, so joining adjacent answers in any grouping gives one
        sequential pass over the bags."""
        self.failed.update(later.failed)
        self.messages += later.messages
        self.empty += later.empty
        self.units += later.units
        if self.states is None:
            self.states = later.states
        elif later.states is not None:
            for key, state in later.states.items():
                self.states[key].merge(state)
        return self


BagReducer = Callable[[Sequence[BagJob], Progress | None], Merged]
"""Runs the jobs of one pass elsewhere (a cluster: :mod:`imrosc.fleet`) and returns their
answers merged in bag order."""


@dataclass
class Early:
    """What a pass run elsewhere tells as soon as every bag is read, before its merged states
    arrive: the values of its points' discrete variables merged over every bag (per point
    key, in the points' order), which give the conditions of the second pass, and the bags
    that failed."""

    discrete: dict[str, DiscreteValues] = field(default_factory=dict)
    failed: set[Path] = field(default_factory=set)


class Staged(Protocol):
    """A pass started elsewhere (:meth:`StagedReducer.begin`)."""

    def early(self) -> Early:
        """Once every bag is read: the pass's :class:`Early` facts."""
        ...

    def result(self) -> Merged:
        """The pass's answers merged in bag order."""
        ...


@runtime_checkable
class StagedReducer(Protocol):
    """A :data:`BagReducer` that can start a pass and tell its :class:`Early` facts before its
    merged answers (a cluster: the second pass starts while the first one's answers are
    still being joined)."""

    def __call__(self, jobs: Sequence[BagJob], progress: Progress | None) -> Merged: ...

    def begin(self, jobs: Sequence[BagJob], progress: Progress | None) -> Staged:
        """Start the pass (its tasks submitted)."""
        ...


def discovered_in(discrete: Mapping[str, DiscreteValues]) -> tuple[Discovered, ...]:
    """The conditions found in the first pass's merged discrete values, by point."""
    return tuple(
        Discovered(key, variable, value)
        for key, values in discrete.items()
        for variable, value in values.conditions()
    )


def _merge(
    results: Iterable[BagResult],
    specs: Sequence[PointSpec],
    tunables: Tunables,
    units: list[Unit] | None = None,
) -> tuple[dict[str, PointState], dict[Path, str], int, tuple[Path, ...]]:
    merged = Merged()
    for result in results:
        merged.join(Merged.of(result))
    return _unpack(merged, specs, tunables, units)


def _unpack(
    merged: Merged,
    specs: Sequence[PointSpec],
    tunables: Tunables,
    units: list[Unit] | None,
) -> tuple[dict[str, PointState], dict[Path, str], int, tuple[Path, ...]]:
    if units is not None:
        units += merged.units
    states = merged.states
    if states is None:
        states = new_states(specs, tunables, discover=False)
    return states, merged.failed, merged.messages, tuple(merged.empty)


def infer(
    bags: Sequence[Path],
    specs: Sequence[PointSpec],
    layouts: Mapping[str, TopicLayout],
    callerids: Mapping[str, set[str]],
    tunables: Tunables,
    *,
    workers: int = 1,
    progress: Progress | None = None,
    calibrate: bool = False,
    reducer: BagReducer | None = None,
) -> InferenceResult:
    """Infer over ``bags`` (sorted; one run each) with ``workers`` processes, or with
    ``reducer`` (a cluster) when given; with ``calibrate``, also the invariants of each run
    alone (of time segments of the runs when there are fewer than :data:`MIN_RUNS`)."""

    def run(
        jobs: Sequence[BagJob],
        specs: Sequence[PointSpec],
        shown: Progress | None,
        found: list[Unit],
    ) -> tuple[dict[str, PointState], dict[Path, str], int, tuple[Path, ...]]:
        if reducer is not None:
            return _unpack(reducer(jobs, shown), specs, tunables, found)
        return _merge(_map(jobs, workers, shown), specs, tunables, found)

    def second_pass(
        discovered: tuple[Discovered, ...], failed: Iterable[Path]
    ) -> tuple[tuple[PointSpec, ...], list[BagJob]]:
        """The second pass's points (those with conditions) and jobs (the bags read)."""
        points = {d.point for d in discovered}
        second_specs = tuple(s for s in specs if s.key in points)
        bad = set(failed)
        return second_specs, [
            BagJob(b, i, second_specs, layouts, frozen, tunables, discovered, False, units)
            for i, b in enumerate(ordered)
            if b not in bad
        ]

    ordered = sorted(bags)
    frozen = {topic: frozenset(names) for topic, names in callerids.items()}
    units = segments_for(len(ordered)) if calibrate else 0
    jobs = [
        BagJob(b, i, tuple(specs), layouts, frozen, tunables, units=units)
        for i, b in enumerate(ordered)
    ]
    found: list[Unit] = []
    more: list[Unit] = []
    if isinstance(reducer, StagedReducer) and jobs:
        # the second pass starts as soon as the first one's bags are read, while their
        # answers are still being joined on the cluster
        started = reducer.begin(jobs, progress)
        early = started.early()
        discovered = discovered_in(early.discrete)
        second_specs, second = second_pass(discovered, early.failed)
        later = reducer.begin(second, None) if discovered and second else None
        first, failed, messages, empty = _unpack(started.result(), specs, tunables, found)
        if not discovered:
            return InferenceResult(first, ordered, failed, messages, empty=empty, units=found)
        merged = later.result() if later is not None else Merged()
        extra, _, _, _ = _unpack(merged, second_specs, tunables, more)
    else:
        first, failed, messages, empty = run(jobs, specs, progress, found)
        discovered = discovered_in(
            {key: state.discrete for key, state in first.items() if state.discrete is not None}
        )
        if not discovered:
            return InferenceResult(first, ordered, failed, messages, empty=empty, units=found)
        second_specs, second = second_pass(discovered, failed)
        extra, _, _, _ = run(second, second_specs, None, more)
    first.update(extra)
    _join_units(found, more)
    return InferenceResult(first, ordered, failed, messages, discovered, empty, found)


def _join_units(units: list[Unit], more: Sequence[Unit]) -> None:
    """Add the conditional points' invariants of the second pass to their units."""
    at = {(u.bag, u.span): u for u in units}
    for unit in more:
        mine = at.get((unit.bag, unit.span))
        if mine is not None:
            mine.invariants += unit.invariants


def default_workers() -> int:
    """The core count (at least 1)."""
    return max(1, os.cpu_count() or 1)


def variables_of(states: Mapping[str, PointState]) -> dict[str, tuple[Variable, ...]]:
    """Each point's variables."""
    return {key: state.spec.variables for key, state in states.items()}
