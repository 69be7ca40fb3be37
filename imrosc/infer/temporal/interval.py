"""Ordered-pair interval invariants (thesis 3.4.4.1, Algorithm 8).

For every ordered pair ``(e1, e2)`` of distinct events of a temporal point, an interval opens
when ``e1`` happens and closes at the next ``e2``. Exact semantics (the monitor, Algorithm 11,
checks the same ones):

* While the pair's interval is closed, ``e1`` opens it (its time is the opening time); every
  other event, ``e2`` included, does nothing.
* While it is open, ``e2`` closes it and records one interval: its time ``t(e2) - t(e1)`` and
  the multiset of events strictly between the opening and the closing. Any other event,
  **including a repeated** ``e1``, is added to that multiset; a repeated ``e1`` does not
  re-open the interval (the first opening is kept), so ``a a b`` gives ``a -> b`` one
  interval holding ``{a}``.
* Thresholds: if an interval lasts longer than ``max_interval`` seconds (checked at the
  closing ``e2`` and at every event recorded while it is open) or holds more than
  ``max_events`` events, the pair is a weak relationship and is dropped for good ("remove
  interval" in Algorithm 8; the thesis' case study reports 3 interval invariants over 6 pairs):
  no invariant for it, whatever other runs show.
* A run (bag) ends every open interval without recording it: runs never share an interval.
  Nothing is checked at the end of a run (the samples carry no end-of-bag time).
* Events of a run arrive in time order (ties in input order); times only subtract.

Algorithm 8's ``break`` after a removal would skip the other pairs for that event; it is read
as "continue with the next pair".

Output, per pair that closed at least one interval and was never dropped: the least and
greatest interval time and the element-wise least and greatest multisets of events in
between (Figure 3.13: ``a -> c`` with ``{2 x b}``). Justification: ``1 - 2**-n``, ``n`` the
intervals since any of the four summaries last changed (the first interval counts).

Exact merging: per pair the state keeps the interval count, each summary's value and the
position of the interval where it was first reached (the last change of a running minimum
is the first occurrence of the final minimum); merging a later state moves a summary and its
position only where the later value is strictly better.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np
import numpy.typing as npt

from imrosc.infer.core import FinalizeContext, Invariant, Samples, confidence
from imrosc.runtime.families import INTERVAL

__all__ = ["FAMILY", "IntervalState", "format_multiset"]

FAMILY = INTERVAL

IntArray = npt.NDArray[np.int64]
FloatArray = npt.NDArray[np.float64]


def format_multiset(counts: dict[str, int]) -> str:
    """``{}``, ``{b}``, ``{2 x b, c}`` (in the order given)."""
    parts = [event if n == 1 else f"{n} x {event}" for event, n in counts.items() if n > 0]
    return "{" + ", ".join(parts) + "}"


def event_codes(samples: Samples, index: dict[str, int]) -> IntArray:
    """The ``event`` column as indices into the point's events; ``ValueError`` if unknown."""
    column = samples.column("event")
    if len(column) == 0:
        return np.zeros(0, dtype=np.int64)
    names, inverse = np.unique(column.astype(str), return_inverse=True)
    unknown = [str(n) for n in names if str(n) not in index]
    if unknown:
        raise ValueError(f"point {samples.point}: events {unknown} are not among {sorted(index)}")
    lookup = np.array([index[str(n)] for n in names], dtype=np.int64)
    return lookup[inverse.reshape(-1)]


class IntervalState:
    """Ordered-pair intervals of one temporal point (see the module docstring)."""

    family = FAMILY

    def __init__(self, events: Sequence[str], max_interval: float, max_events: int) -> None:
        self.events = tuple(events)
        self.index = {event: i for i, event in enumerate(self.events)}
        self.max_interval = float(max_interval)
        self.max_events = int(max_events)
        k = len(self.events)
        self.pairs: tuple[tuple[int, int], ...] = tuple(
            (i, j) for i in range(k) for j in range(k) if i != j
        )
        p = len(self.pairs)
        self.dropped = np.zeros(p, dtype=bool)
        self.count = np.zeros(p, dtype=np.int64)
        self.min_time = np.zeros(p, dtype=np.float64)
        self.max_time = np.zeros(p, dtype=np.float64)
        self.min_time_at = np.zeros(p, dtype=np.int64)
        self.max_time_at = np.zeros(p, dtype=np.int64)
        self.min_events = np.zeros((p, k), dtype=np.int64)
        self.max_events_seen = np.zeros((p, k), dtype=np.int64)
        self.min_events_at = np.zeros((p, k), dtype=np.int64)
        self.max_events_at = np.zeros((p, k), dtype=np.int64)
        # The open interval of each pair in the current run.
        self.open = np.zeros(p, dtype=bool)
        self.open_time = np.zeros(p, dtype=np.float64)
        self.open_counts = np.zeros((p, k), dtype=np.int64)

    # -- summaries ---------------------------------------------------------------------------

    def _absorb(
        self,
        p: int,
        count: int,
        times: tuple[float, int, float, int],
        mins: tuple[IntArray, IntArray],
        maxs: tuple[IntArray, IntArray],
    ) -> None:
        """Fold a block of ``count`` later intervals of pair ``p`` into its summaries.

        ``times`` is (least, position, greatest, position) and ``mins``/``maxs`` the
        element-wise least/greatest counts with positions, all positions within the block.
        """
        if count == 0:
            return
        offset = int(self.count[p])
        low, low_at, high, high_at = times
        if offset == 0 or low < self.min_time[p]:
            self.min_time[p] = low
            self.min_time_at[p] = offset + low_at
        if offset == 0 or high > self.max_time[p]:
            self.max_time[p] = high
            self.max_time_at[p] = offset + high_at
        least, least_at = mins
        most, most_at = maxs
        if offset == 0:
            self.min_events[p] = least
            self.min_events_at[p] = least_at
            self.max_events_seen[p] = most
            self.max_events_at[p] = most_at
        else:
            lower = least < self.min_events[p]
            self.min_events[p, lower] = least[lower]
            self.min_events_at[p, lower] = offset + least_at[lower]
            higher = most > self.max_events_seen[p]
            self.max_events_seen[p, higher] = most[higher]
            self.max_events_at[p, higher] = offset + most_at[higher]
        self.count[p] = offset + count

    def _record(self, p: int, elapsed: FloatArray, counts: IntArray) -> None:
        """Record closed intervals of pair ``p`` (in order); drop the pair if one is weak."""
        if len(elapsed) == 0:
            return
        if bool(np.any(elapsed > self.max_interval)) or bool(
            np.any(counts.sum(axis=1) > self.max_events)
        ):
            self.dropped[p] = True
            return
        low_at = int(np.argmin(elapsed))
        high_at = int(np.argmax(elapsed))
        self._absorb(
            p,
            len(elapsed),
            (float(elapsed[low_at]), low_at, float(elapsed[high_at]), high_at),
            (counts.min(axis=0), counts.argmin(axis=0).astype(np.int64)),
            (counts.max(axis=0), counts.argmax(axis=0).astype(np.int64)),
        )

    # -- FamilyState -------------------------------------------------------------------------

    def update(self, samples: Samples) -> None:
        codes = event_codes(samples, self.index)
        n = len(codes)
        if n == 0:
            return
        times = np.asarray(samples.time, dtype=np.float64)
        k = len(self.events)
        onehot = np.zeros((n + 1, k), dtype=np.int64)
        onehot[np.arange(1, n + 1), codes] = 1
        cum = np.cumsum(onehot, axis=0)
        positions = [np.flatnonzero(codes == e) for e in range(k)]
        last_time = float(times[-1])
        for p, (first, second) in enumerate(self.pairs):
            if self.dropped[p]:
                continue
            opens, closes = positions[first], positions[second]
            carried = bool(self.open[p])
            tail_from = 0
            if len(closes):
                previous = np.concatenate(([-1], closes[:-1]))
                # The first e1 after the previous e2 opens the interval this e2 closes.
                padded = np.append(opens, n)
                opener = padded[np.searchsorted(opens, previous + 1)]
                valid = opener < closes
                if carried:
                    opener[0] = -1
                    valid[0] = True
                begin, end = opener[valid], closes[valid]
                start_time = times[np.maximum(begin, 0)]
                between = cum[end] - cum[begin + 1]
                if carried:
                    start_time[0] = self.open_time[p]
                    between[0] += self.open_counts[p]
                self._record(p, times[end] - start_time, between)
                if self.dropped[p]:
                    continue
                tail_from = int(closes[-1]) + 1
                carried = False
            if carried:
                self.open_counts[p] += cum[n] - cum[0]
            else:
                at_tail = int(np.searchsorted(opens, tail_from))
                if at_tail == len(opens):
                    self.open[p] = False
                    continue
                begin_tail = int(opens[at_tail])
                self.open[p] = True
                self.open_time[p] = times[begin_tail]
                self.open_counts[p] = cum[n] - cum[begin_tail + 1]
            if (
                last_time - self.open_time[p] > self.max_interval
                or int(self.open_counts[p].sum()) > self.max_events
            ):
                self.dropped[p] = True

    def end_run(self) -> None:
        self.open[:] = False
        self.open_counts[:] = 0
        self.open_time[:] = 0.0

    def merge(self, other: Any) -> None:
        if not isinstance(other, IntervalState) or other.events != self.events:
            raise TypeError("can only merge an IntervalState over the same events")
        self.end_run()
        for p in range(len(self.pairs)):
            if other.dropped[p]:
                self.dropped[p] = True
            if self.dropped[p]:
                continue
            self._absorb(
                p,
                int(other.count[p]),
                (
                    float(other.min_time[p]),
                    int(other.min_time_at[p]),
                    float(other.max_time[p]),
                    int(other.max_time_at[p]),
                ),
                (other.min_events[p], other.min_events_at[p]),
                (other.max_events_seen[p], other.max_events_at[p]),
            )
        self.open[:] = other.open
        self.open_time[:] = other.open_time
        self.open_counts[:] = other.open_counts

    def _multiset(self, counts: IntArray) -> dict[str, int]:
        return {self.events[e]: int(c) for e, c in enumerate(counts) if c > 0}

    def finalize(self, context: FinalizeContext) -> list[Invariant]:
        found: list[Invariant] = []
        for p, (first, second) in enumerate(self.pairs):
            count = int(self.count[p])
            if self.dropped[p] or count == 0:
                continue
            changed = max(
                int(self.min_time_at[p]),
                int(self.max_time_at[p]),
                int(self.min_events_at[p].max(initial=0)),
                int(self.max_events_at[p].max(initial=0)),
            )
            since = count - changed
            if not context.justified(since):
                continue
            low, high = float(self.min_time[p]), float(self.max_time[p])
            least = self._multiset(self.min_events[p])
            most = self._multiset(self.max_events_seen[p])
            e1, e2 = self.events[first], self.events[second]
            found.append(
                Invariant(
                    family=FAMILY,
                    kind="interval",
                    point=context.point,
                    variables=("event",),
                    params={
                        "first": e1,
                        "second": e2,
                        "min_time": low,
                        "max_time": high,
                        "min_events": least,
                        "max_events": most,
                        "max_interval": self.max_interval,
                        "max_events_threshold": self.max_events,
                    },
                    text=(
                        f"{e1} -> {e2}: [{low!r}, {high!r}] s, "
                        f"min {format_multiset(least)}, max {format_multiset(most)}"
                    ),
                    samples=count,
                    confidence=confidence(since),
                    condition=context.condition,
                    runs=context.runs,
                )
            )
        return found
