"""Temporal checks: ordered-pair intervals (Algorithm 11) and pattern DFAs (Algorithm 12).

Both read an invariant the way ``imrosc.infer.temporal`` built it (see
``docs/families/arch-and-temporal.md``, "Monitor"):

* an interval machine opens at ``e1``, counts every other event (a repeated ``e1``
  included) and reports a count above the greatest multiset, a timer past ``max_time``,
  and at ``e2`` a time outside ``[min_time, max_time]`` or a count below the least
  multiset; then it closes;
* a pattern keeps the set of DFA states the trace may be in (all of them at the start of a
  run); an event of its alphabet moves every state, states without a transition drop out,
  and an empty set is a violation, after which the set is reset to all states.

>>> machine = IntervalMachine({"id": "i1", "family": "interval", "kind": "interval",
...     "text": "a -> b", "params": {"first": "a", "second": "b", "min_time": 1.0,
...     "max_time": 2.0, "min_events": {}, "max_events": {}}}, "e")
>>> machine.event(0.0, "a"), [v.expected for v in machine.event(0.5, "b")]
([], ['[1, 2] s'])
"""

from __future__ import annotations

from typing import Any, Dict, FrozenSet, List, Mapping, Optional

from .violation import Violation, show

Found = List[Violation]


def _violation(
    time: float, point: str, inv: Mapping[str, Any], observed: Any, expected: str
) -> Violation:
    return Violation(
        time, point, inv["id"], inv["family"], inv["kind"], inv["text"], observed, expected
    )


def _multiset(counts: Mapping[str, int]) -> str:
    return "{" + ", ".join(f"{n} x {e}" for e, n in sorted(counts.items()) if n) + "}"


class IntervalMachine:
    """Algorithm 11 for one ordered-pair invariant."""

    def __init__(self, invariant: Mapping[str, Any], point: str) -> None:
        params = invariant["params"]
        self.invariant = invariant
        self.point = point
        self.first: str = params["first"]
        self.second: str = params["second"]
        self.min_time = float(params["min_time"])
        self.max_time = float(params["max_time"])
        self.min_events: Dict[str, int] = dict(params["min_events"])
        self.max_events: Dict[str, int] = dict(params["max_events"])
        self.reset()

    def reset(self) -> None:
        """A new run: closed."""
        self.opened: Optional[float] = None
        self.counts: Dict[str, int] = {}
        self.timed_out = False
        self.pending: Found = []
        """Violations of the interval still open (a run that ends now never closes it;
        :meth:`unfinished`)."""

    def unfinished(self) -> Found:
        """The violations raised by the interval still open and still within ``max_time``,
        which the end of a recorded run leaves undecided, as inference leaves it
        unrecorded; then closed. An interval whose ``max_time`` ran out is decided: its
        violations stand, and none is returned."""
        found = [] if self.timed_out else self.pending
        self.reset()
        return found

    def event(self, time: float, event: str) -> Found:
        """Feed one event of the scope."""
        if self.opened is None:
            if event == self.first:
                self.opened, self.counts, self.timed_out = time, {}, False
            return []
        found: Found = []
        if event != self.second:
            count = self.counts.get(event, 0) + 1
            self.counts[event] = count
            if count == self.max_events.get(event, 0) + 1:
                most = self.max_events.get(event, 0)
                expected = f"at most {most} x {event} within {self.first} -> {self.second}"
                found.append(_violation(time, self.point, self.invariant, event, expected))
            if not self.timed_out:
                found += self.tick(time)
            self.pending += found
            return found
        elapsed = time - self.opened
        if not self.timed_out and not self.min_time <= elapsed <= self.max_time:
            expected = f"[{show(self.min_time)}, {show(self.max_time)}] s"
            found.append(_violation(time, self.point, self.invariant, elapsed, expected))
        missing = {e: n for e, n in self.min_events.items() if self.counts.get(e, 0) < n}
        if missing:
            expected = (
                f"at least {_multiset(self.min_events)} between {self.first} and {self.second}"
            )
            observed = _multiset(self.counts)
            found.append(_violation(time, self.point, self.invariant, observed, expected))
        self.opened = None
        self.pending = []
        return found

    def tick(self, now: float) -> Found:
        """The timer: an open interval older than ``max_time`` is a violation (once)."""
        if self.opened is None or self.timed_out or now - self.opened <= self.max_time:
            return []
        self.timed_out = True
        expected = f"{self.second} within {show(self.max_time)} s of {self.first}"
        found = [_violation(now, self.point, self.invariant, now - self.opened, expected)]
        self.pending += found
        return found


class PatternMachine:
    """Algorithm 12 for one pattern invariant: a DFA run with the set of current states."""

    def __init__(self, invariant: Mapping[str, Any], point: str) -> None:
        params = invariant["params"]
        self.invariant = invariant
        self.point = point
        self.alphabet: FrozenSet[str] = frozenset(params["alphabet"])
        self.transitions: Dict[int, Dict[str, int]] = {
            int(state): dict(moves) for state, moves in params["transitions"].items()
        }
        self.all_states: FrozenSet[int] = frozenset(range(int(params["states"])))
        self.reset()

    def reset(self) -> None:
        """A new run: the trace may be anywhere in the pattern."""
        self.states = self.all_states
        self.trace: List[str] = []

    def event(self, time: float, event: str) -> Found:
        """Feed one event of the scope (events outside the alphabet pass it by)."""
        if event not in self.alphabet:
            return []
        self.trace = [*self.trace, event][-8:]
        moved = frozenset(
            self.transitions[s][event] for s in self.states if event in self.transitions.get(s, {})
        )
        if moved:
            self.states = moved
            return []
        observed = " ".join(self.trace)
        self.states = self.all_states
        self.trace = []
        expected = "events in the order " + str(self.invariant["params"]["pattern"])
        return [_violation(time, self.point, self.invariant, observed, expected)]
