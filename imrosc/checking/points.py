"""One publish point checked over a chunk of its samples, as the engine checks them one by one.

A chunk's samples are the point's trigger messages of the chunk, each paired with the latest
message of each input topic at or before it (:class:`TopicRows` carry each topic's last row
into the next chunk), kept where every input has been seen and every condition holds. Then:

* value checks: one vectorised pass over the chunk marks the samples that may break an
  invariant (a superset: the forms of bounds, orderings and relations with a margin for the
  rounding of relations, the polygons' edges, sets, non-zero values, functions, strings,
  and any sample with a value not finite); the engine's own :meth:`Checks.check` then finds
  the violations of those samples alone;
* time windows: frequency, variance and mean (the same dyadic algorithm, vectorised by
  :func:`~imrosc.infer.timed.windows.windowed_moments`) and change rate of every sample's
  window at once; the engine's :meth:`WindowChecks.check` gives the violations of the
  windows out of bounds;
* the silence timer (a frequency lower bound checked at every message of the bag while the
  point's topic is silent): the clock events where a window would hold too few samples are
  found at once, and a walk over those and the samples that end a silence gives the
  silences reported and the samples checked while silent;
* alarms: the engine's tracker is told each violating sample and the clean sample after it,
  in the point's order (its state is per point);
* the engine's trace (plots, classification's samples) sees every sample.

Every violation and alarm carries its place in the engine's order: the clock event (message)
it belongs to, whether it is a timer's or a sample's, and the point's rank.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import numpy.typing as npt

from imrosc.infer.core import kept_restarts
from imrosc.infer.timed.windows import episode_starts, windowed_moments, with_silences
from imrosc.runtime.alarms import Alarm, Fed
from imrosc.runtime.conditions import holds
from imrosc.runtime.engine import PARAMS, Engine, _Point
from imrosc.runtime.families import (
    ARRAY,
    BOUNDS,
    EQUALITY,
    FUNCTION,
    LINEAR,
    MEAN,
    NON_ZERO,
    ONE_OF,
    ORDER,
    POLYGON,
    RATE,
    STEP,
    STRING_ONE_OF,
    TERNARY,
    VARIANCE,
)
from imrosc.runtime.violation import Violation

from .words import RowChecks

FloatArray = npt.NDArray[np.float64]
IntArray = npt.NDArray[np.int64]
BoolArray = npt.NDArray[np.bool_]
Key = tuple[int, int, int]
"""A violation's or alarm's place: clock event, stage (0 timers, 2 samples), point rank."""
TIMER, SAMPLE = 0, 2
_RELATION_SLACK = 1e-12
"""Relative margin on relations (a constant or three terms: any order of summation)."""


@dataclass
class TopicRows:
    """One topic's rows of a chunk, after the last row of the chunks before (``carried``)."""

    pos: IntArray
    time: FloatArray
    numeric: FloatArray
    strings: list[npt.NDArray[Any]]
    names: Sequence[str]
    """The topic's variables in layout order (for its condition values)."""
    numeric_at: Sequence[int]
    string_at: Sequence[int]
    carried: int = 0

    def tail(self) -> TopicRows:
        """The last row (what the next chunk pairs with)."""
        return TopicRows(
            self.pos[-1:],
            self.time[-1:],
            self.numeric[-1:],
            [s[-1:] for s in self.strings],
            self.names,
            self.numeric_at,
            self.string_at,
            1,
        )

    def kept(self, rows: npt.NDArray[np.bool_]) -> TopicRows:
        """Only the ``rows`` flagged (the carried rows among them: they are the chunks'
        before, never dropped)."""
        return TopicRows(
            self.pos[rows],
            self.time[rows],
            self.numeric[rows],
            [s[rows] for s in self.strings],
            self.names,
            self.numeric_at,
            self.string_at,
            int(np.count_nonzero(rows[: self.carried])),
        )

    def named(self, row: int) -> dict[str, Any]:
        """A row's values by variable name (what a condition on the topic reads)."""
        values: dict[str, Any] = {}
        for k, at in enumerate(self.numeric_at):
            values[self.names[at]] = float(self.numeric[row, k])
        for k, at in enumerate(self.string_at):
            values[self.names[at]] = self.strings[k][row]
        return values


VECTORISED = frozenset(
    {BOUNDS, ARRAY, ONE_OF, NON_ZERO, EQUALITY, ORDER, LINEAR, TERNARY, POLYGON}
    | {STRING_ONE_OF, FUNCTION}
)
"""The value families :meth:`ChunkPoint._may_break` flags and :class:`RowChecks` words; a
point holding another (a family added to the catalog and the engine's checks only) is
checked by the engine, per message, never passed over."""


def vectorisable(engine: Engine, point: _Point) -> bool:
    """Whether :class:`ChunkPoint` checks ``point`` (else the engine does, per message): a
    publish point without parameters, learnt detectors, strings read from parameters or
    value families the vectorised pass does not know (:data:`VECTORISED`)."""
    if point.kind != "publish" or point.params or point.detectors:
        return False
    if point.checks.families - VECTORISED:
        return False
    _, _, strings = engine._gather[point.key]
    if any(source in ("", PARAMS) for source, _ in strings):
        return False
    for condition in point.filters:
        value = condition.value
        if condition.variable is not None and not isinstance(value, (bool, float, str, int)):
            return False
        if isinstance(value, int) and abs(value) > 2**53:
            return False
    return True


def _equal(column: npt.NDArray[Any], value: Any) -> BoolArray:
    """``column == value`` per row, as Python compares one value."""
    if isinstance(value, (bool, int, float)) and column.dtype == np.float64:
        return np.asarray(column == value)
    return np.fromiter((x == value for x in column.tolist()), dtype=bool, count=len(column))


@dataclass
class _WindowState:
    """A point's open window, carried from chunk to chunk."""

    first_time: float | None = None
    times: FloatArray = field(default_factory=lambda: np.empty(0))
    values: FloatArray = field(default_factory=lambda: np.empty((0, 0)))
    silent: bool = False
    gap: bool = False
    """The point's condition did not hold at its last sample (the engine's ``gap``)."""
    restarts: BoolArray | None = None
    """The chunk's samples where an episode of the condition begins."""


@dataclass
class Found:
    """A point's violations and alarms of a chunk, each with its place."""

    violations: list[tuple[Key, Violation]] = field(default_factory=list)
    alarms: list[tuple[Key, Alarm]] = field(default_factory=list)
    fed: list[tuple[Key, Fed]] = field(default_factory=list)
    """The violating samples a recording tracker kept (``AlarmTracker.record``)."""


class ChunkPoint:
    """Checks one publish point of an engine over chunks of its samples."""

    def __init__(self, engine: Engine, point: _Point, rank: int) -> None:
        self.engine = engine
        self.point = point
        self.rank = rank
        sources, gather, strings = engine._gather[point.key]
        self.sources: list[str] = list(sources)
        self.gather: IntArray = gather
        self.strings: list[tuple[str, int]] = list(strings)
        self.used = self._used_columns()
        checks = point.checks
        self.forms = [
            (terms, limit, len(terms) > 2 or any(i == checks.forms.one for i, _ in terms))
            for terms, limit in checks.forms.rows
        ]
        self.polygons = []
        for inv in checks.polygons:
            xi, yi = (checks.index[n] for n in inv["variables"])
            a = np.asarray([row[0] for row in inv["params"]["A"]], dtype=np.float64)[:, None]
            b = np.asarray([row[1] for row in inv["params"]["A"]], dtype=np.float64)[:, None]
            c = np.asarray(inv["params"]["b"], dtype=np.float64)[:, None]
            self.polygons.append((xi, yi, a, b, c))
        self.timed = point.windows is not None and point.min_frequency > 0
        self.words = None if checks.compiled else RowChecks(checks)
        """The value violations of a chunk's flagged samples at once (``None``: numba
        compiled the checks, whose kernel answers first: the engine checks each sample)."""
        self.reset()

    def _used_columns(self) -> IntArray:
        checks = self.point.checks
        used: set[int] = set()
        for terms, _ in checks.forms.rows:
            used.update(i for i, _ in terms if i < checks.forms.zero)
        for inv in checks.polygons:
            used.update(checks.index[n] for n in inv["variables"])
        used.update(checks.one_of_at.tolist())
        used.update(checks.nonzero_at.tolist())
        used.update(checks.finite_at.tolist())
        for _, places, _ in checks.functions:
            used.update(places)
        return np.asarray(sorted(used), dtype=np.int64)

    def reset(self) -> None:
        """A new run."""
        width = len(self.point.tracked_at)
        self.window = _WindowState(values=np.empty((0, width)))

    # -- samples -------------------------------------------------------------------------

    def samples(
        self, topics: Mapping[str, TopicRows]
    ) -> tuple[IntArray, FloatArray, FloatArray, list[npt.NDArray[Any]]]:
        """The chunk's samples: positions, times, values and string columns."""
        point = self.point
        trigger = topics.get(point.trigger)
        if trigger is None or len(trigger.pos) <= trigger.carried:
            return np.empty(0, np.int64), np.empty(0), np.empty((0, 0)), []
        own = slice(trigger.carried, None)
        pos, time = trigger.pos[own], trigger.time[own]
        valid = np.ones(len(pos), dtype=bool)
        at: dict[str, IntArray] = {point.trigger: np.arange(trigger.carried, len(trigger.pos))}
        for source in self.sources[1:]:
            rows = topics.get(source)
            if rows is None or not len(rows.pos):
                return np.empty(0, np.int64), np.empty(0), np.empty((0, 0)), []
            index = np.searchsorted(rows.pos, pos, side="right") - 1
            valid &= index >= 0
            at[source] = np.maximum(index, 0)
        if point.direct:
            values = trigger.numeric[own]
        else:
            parts = [topics[s].numeric[at[s]] for s in self.sources]
            parts.append(np.full((len(pos), 1), np.nan))
            values = np.concatenate(parts, axis=1)[:, self.gather]
        texts = [topics[s].strings[k][at[s]] for s, k in self.strings]
        if point.filters:
            accepted = self._accepted(values, texts, pos, topics)
            self.window.restarts, self.window.gap = kept_restarts(valid, accepted, self.window.gap)
            valid &= accepted
        if not valid.all():
            keep = np.flatnonzero(valid)
            return pos[keep], time[keep], values[keep], [t[keep] for t in texts]
        return pos, time, values, texts

    def _accepted(
        self,
        values: FloatArray,
        texts: list[npt.NDArray[Any]],
        pos: IntArray,
        topics: Mapping[str, TopicRows],
    ) -> BoolArray:
        point = self.point
        ok = np.ones(len(pos), dtype=bool)
        for condition in point.filters:
            if condition.variable is not None:
                if condition.variable in point.numeric_index:
                    column = values[:, point.numeric_index[condition.variable]]
                    ok &= _equal(column, condition.value)
                elif condition.variable in point.string_names and texts:
                    column = texts[point.string_names.index(condition.variable)]
                    ok &= _equal(column, condition.value)
                else:
                    ok[:] = False
                continue
            rows = topics.get(condition.topic or "")
            if rows is None or not len(rows.pos):
                ok[:] = False
                continue
            index = np.searchsorted(rows.pos, pos, side="right") - 1
            verdict: dict[int, bool] = {}
            held = np.zeros(len(pos), dtype=bool)
            for k, row in enumerate(index.tolist()):
                if row < 0:
                    continue
                answer = verdict.get(row)
                if answer is None:
                    named = rows.named(row)
                    fields = {path: named.get(name, math.nan) for path, name in condition.fields}
                    answer = verdict[row] = holds(condition.expression, fields)
                held[k] = answer
            ok &= held
        return ok

    # -- checks --------------------------------------------------------------------------

    def _may_break(self, values: FloatArray, texts: list[npt.NDArray[Any]]) -> BoolArray:
        """A superset of the samples that break a value invariant."""
        checks = self.point.checks
        count = len(values)
        flagged = np.zeros(count, dtype=bool)
        if len(self.used):
            flagged |= ~np.isfinite(values[:, self.used]).all(axis=1)
        zero, one = checks.forms.zero, checks.forms.one
        for terms, limit, relation in self.forms:
            total = np.zeros(count)
            scale = np.zeros(count)
            for index, weight in terms:
                if index == zero:
                    continue
                term = weight * (values[:, index] if index != one else np.ones(count))
                total = total + term
                if relation:
                    scale = scale + np.abs(term)
            if relation:
                flagged |= total > limit - (_RELATION_SLACK * scale + 1e-300)
            else:
                flagged |= total > limit
        for xi, yi, a, b, c in self.polygons:
            flagged |= (a * values[:, xi] + b * values[:, yi] > c).any(axis=0)
        for at, held in zip(checks.one_of_at.tolist(), checks.one_of_values, strict=True):
            x = values[:, at]
            known = held[~np.isnan(held)]
            flagged |= ~np.isin(x, known) & ~np.isnan(x)
        for at in checks.nonzero_at.tolist():
            flagged |= values[:, at] == 0
        for at, held_set, _ in checks.string_sets:
            column = texts[at]
            flagged |= np.fromiter((s not in held_set for s in column), bool, count=count)
        for kind, places, _ in checks.functions:
            z = values[:, places[0]]
            if kind == "abs":
                expected = np.abs(values[:, places[1]])
            elif kind == "max":
                expected = np.maximum(values[:, places[1]], values[:, places[2]])
            else:
                expected = np.minimum(values[:, places[1]], values[:, places[2]])
            flagged |= z != expected
        return flagged

    def _windows(self, time: FloatArray, values: FloatArray) -> dict[str, Any]:
        """Every sample's window: defined, frequency, variance, rate and mean, the window's rows."""
        point = self.point
        windows = point.windows
        assert windows is not None
        state = self.window
        tracked = values[:, point.tracked_at]
        if state.first_time is None and len(time):
            state.first_time = float(time[0])
        old = len(state.times)
        all_time = np.concatenate([state.times, time])
        all_values = np.concatenate([state.values, tracked])
        cutoff = time - windows.width
        starts = np.searchsorted(all_time, cutoff, side="right").astype(np.int64)
        ends = np.arange(old, len(all_time), dtype=np.int64)
        assert state.first_time is not None
        # the engine resets its windows where an episode of the condition begins, and
        # begins a stretch after a silence longer than the window
        restarts = with_silences(state.restarts, all_time, cutoff, old)
        before = state.first_time
        starts, first, begun = episode_starts(restarts, all_time, starts, ends, before)
        defined = first <= cutoff
        if begun >= 0:
            state.first_time = float(all_time[begun])
        size = ends - starts + 1
        frequency = size / windows.window
        out: dict[str, Any] = {"defined": defined, "frequency": frequency}
        families = point.window_checks.arrays
        width = len(point.tracked_at)
        if VARIANCE in families or MEAN in families:
            variance = np.full((len(time), width), np.nan)
            mean = np.full((len(time), width), np.nan)
            wide = np.flatnonzero(defined & (size >= 2))
            if len(wide):
                mean[wide], variance[wide] = windowed_moments(all_values, starts[wide], size[wide])
            out[VARIANCE] = variance
            out[MEAN] = mean
        if RATE in families:
            with np.errstate(all="ignore"):
                dt = all_time[ends] - all_time[starts]
                rate = (all_values[ends] - all_values[starts]) / dt[:, None]
            rate[~(dt > 0)] = np.nan
            out[RATE] = rate
        if STEP in families:
            step = np.full((len(time), width), np.nan)
            pairs = np.flatnonzero(size >= 2)
            if len(pairs):
                with np.errstate(all="ignore"):
                    step[pairs] = all_values[ends[pairs]] - all_values[ends[pairs] - 1]
            out[STEP] = step
        keep = int(np.searchsorted(all_time, all_time[-1] - windows.width, side="right"))
        keep = max(keep, begun)
        state.times = all_time[keep:].copy()
        state.values = all_values[keep:].copy()
        out["all_time"] = all_time
        out["old"] = old
        out["first"] = np.broadcast_to(np.asarray(first, dtype=np.float64), (len(time),))
        out["first_before"] = before
        return out

    def _timer(
        self,
        pos: IntArray,
        window: Mapping[str, Any],
        clock: tuple[IntArray, FloatArray],
        resets: BoolArray,
        found: Found,
    ) -> BoolArray:
        """The silence timer over the chunk's clock events: the silences it reports (into
        ``found``) and, per sample, whether it is checked while silent."""
        point = self.point
        windows = point.windows
        assert windows is not None
        state = self.window
        events, now = clock
        all_time: FloatArray = window["all_time"]
        old: int = window["old"]
        seen = old + np.searchsorted(pos, events, side="left")
        gone = np.minimum(np.searchsorted(all_time, now - windows.width, side="right"), seen)
        size = seen - gone
        # the stretch in force at an event is its last seen sample's (or, before the
        # chunk's first, the one carried in)
        carried = window.get("first_before", state.first_time)
        firsts: FloatArray | None = window.get("first")
        if firsts is not None and len(firsts):
            at = seen - old - 1
            first = np.where(
                at >= 0, firsts[np.maximum(at, 0)], np.nan if carried is None else carried
            )
            defined = (seen > 0) & (first <= now - windows.width)
        elif carried is None:
            defined = np.zeros(len(events), dtype=bool)
        else:
            defined = (seen > 0) & (carried <= now - windows.width)
        candidate = defined & ((size + 1) / windows.window < point.min_frequency)
        ticks = 2 * events[candidate]
        tick_rows = np.flatnonzero(candidate)
        reset_at = 2 * pos[resets] + 1
        silent = state.silent
        cursor = -1
        spans: list[tuple[int, float]] = []
        begun = -1
        while True:
            if not silent:
                j = int(np.searchsorted(ticks, cursor, side="right"))
                if j == len(ticks):
                    break
                cursor = int(ticks[j])
                silent, begun = True, cursor
                e = int(tick_rows[j])
                self._silence(int(events[e]), float(now[e]), int(size[e]), all_time, seen[e], found)
            else:
                j = int(np.searchsorted(reset_at, cursor, side="right"))
                if j == len(reset_at):
                    spans.append((begun, math.inf))
                    break
                cursor = int(reset_at[j])
                spans.append((begun, cursor))
                silent = False
        state.silent = silent
        quiet = np.zeros(len(pos), dtype=bool)
        sample_at = 2 * pos + 1
        for start, end in spans:
            quiet |= (sample_at > start) & (sample_at < end)
        return quiet

    def _silence(
        self, event: int, now: float, size: int, all_time: FloatArray, seen: int, found: Found
    ) -> None:
        """The violations of a silence reported at ``now`` (the engine's timer's words)."""
        broken = self.point.silence(now, size, float(all_time[seen - 1]))
        key = (event, TIMER, self.rank)
        found.violations += [(key, v) for v in broken]
        found.alarms += [(key, a) for a in self.engine.alarms.event(broken)]

    def check(
        self, topics: Mapping[str, TopicRows], clock: tuple[IntArray, FloatArray], found: Found
    ) -> None:
        """Check the point's samples of one chunk (``clock``: the chunk's clock events,
        their positions and times)."""
        point = self.point
        engine = self.engine
        pos, time, values, texts = self.samples(topics)
        count = len(pos)
        point.checked += count
        window: dict[str, Any] | None = None
        flagged = self._may_break(values, texts) if count else np.zeros(0, dtype=bool)
        quiet = np.zeros(count, dtype=bool)
        window_flags = np.zeros(count, dtype=bool)
        if point.windows is not None and (count or self.timed):
            window = self._windows(time, values) if count else None
            if window is not None:
                defined = window["defined"]
                frequency = window["frequency"]
                if self.timed:
                    resets = defined & (frequency >= point.window_checks.recovered)
                    quiet = self._timer(pos, window, clock, resets, found)
                window_flags = self._window_flags(window, quiet)
            elif self.timed:
                empty = {"all_time": self.window.times, "old": len(self.window.times)}
                self._timer(pos, empty, clock, np.zeros(0, dtype=bool), found)
        trace = engine.trace
        if trace is not None and count:
            frequencies: list[float | None] = [None] * count
            if window is not None:
                shown = window["frequency"].tolist()
                defined = window["defined"].tolist()
                frequencies = [f if d else None for f, d in zip(shown, defined, strict=True)]
            batch = getattr(getattr(trace, "__self__", trace), "trace_rows", None)
            if batch is not None:  # the trace takes a chunk at once
                batch(point.key, time.tolist(), values, frequencies)
            else:
                for k in range(count):  # a row of its own, as the engine's are
                    trace(point.key, float(time[k]), values[k].copy(), frequencies[k])
        if not count:
            return
        self._violations(pos, time, values, texts, flagged, window_flags, window, quiet, found)

    def _window_flags(self, window: Mapping[str, Any], quiet: BoolArray) -> BoolArray:
        checks = self.point.window_checks
        defined = window["defined"]
        frequency = window["frequency"]
        flags = np.zeros(len(defined), dtype=bool)
        for inv in checks.frequency:
            lo = float(inv["params"]["min"])
            hi = float(inv["params"]["max"])
            flags |= ((frequency < lo) & ~quiet) | (frequency > hi)
        for family, (at, lo_, hi_, _) in checks.arrays.items():
            derived = window[family][:, at]
            with np.errstate(invalid="ignore"):
                bad = ((derived < lo_) | (derived > hi_)) & np.isfinite(derived)
            flags |= bad.any(axis=1)
        found: BoolArray = flags & defined
        return found

    def _worded(
        self,
        time: FloatArray,
        values: FloatArray,
        texts: list[npt.NDArray[Any]],
        flagged: BoolArray,
    ) -> dict[int, list[Violation]]:
        """The value violations of the flagged samples :class:`RowChecks` words at once, by
        sample (the others, near a relation's tolerance, are the engine's to check)."""
        words = self.words
        rows = np.flatnonzero(flagged)
        if words is None or not len(rows):
            return {}
        if words.relations:
            rows = rows[~words.may_relate(values[rows])]
        found = words.violations(
            time[rows].tolist(), self.point.key, values[rows], [t[rows] for t in texts]
        )
        return dict(zip(rows.tolist(), found, strict=True))

    def _violations(
        self,
        pos: IntArray,
        time: FloatArray,
        values: FloatArray,
        texts: list[npt.NDArray[Any]],
        flagged: BoolArray,
        window_flags: BoolArray,
        window: Mapping[str, Any] | None,
        quiet: BoolArray,
        found: Found,
    ) -> None:
        point = self.point
        alarms = self.engine.alarms
        key_of = point.key
        either = flagged | window_flags
        rows = np.flatnonzero(either)
        visit = set(rows.tolist())
        visit.update((rows + 1).tolist())
        if alarms.busy(key_of):
            visit.add(0)
        count = len(pos)
        worded = self._worded(time, values, texts, flagged)
        for k in sorted(r for r in visit if r < count):
            broken: list[Violation] = []
            t = float(time[k])
            if flagged[k]:
                found_k = worded.get(k)
                if found_k is None:
                    strings = [column[k] for column in texts]
                    found_k = point.checks.check(t, key_of, values[k], strings)
                broken = found_k
            if window_flags[k] and window is not None:
                frequency = float(window["frequency"][k])
                row = k

                def derived(family: str, row: int = row) -> Any:
                    assert window is not None
                    return window[family][row]

                broken += point.window_checks.check(
                    t, key_of, frequency, derived, point.checks.cleared, bool(quiet[k])
                )
            if broken or alarms.busy(key_of):
                key = (int(pos[k]), SAMPLE, self.rank)
                found.violations += [(key, v) for v in broken]
                before = len(alarms.fed)
                found.alarms += [(key, a) for a in alarms.sample(key_of, t, broken)]
                if len(alarms.fed) > before:  # kept in the engine's order at the run's end
                    found.fed += [(key, fed) for fed in alarms.fed[before:]]
                    del alarms.fed[before:]
