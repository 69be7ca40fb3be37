"""User-defined pattern invariants with multi-pointer DFAs (thesis 3.4.4.2, Algorithm 9).

Each concrete pattern of a temporal point (one binding of a ``<pattern>``'s placeholders)
becomes a minimal DFA (:mod:`imrosc.infer.temporal.dfa`) over the events it names. Exact
semantics (the monitor, Algorithm 12, runs the same machine with a state set):

* A machine is driven only by the events of its alphabet; other events of the scope pass it
  by (Algorithm 9 drives a DFA "if applicable").
* At the start of every run (bag) the machine has one pointer per state, since recording may
  start anywhere in the pattern (Figure 3.14). On each event every pointer moves; a pointer
  that falls into the error state is dropped. When no pointer is left the machine is dead
  for good: the pattern does not hold.
* Each pointer remembers the states it has visited, its starting state included. A run gives
  *evidence* when a pointer that is still alive at the end of the run has visited every state
  of the machine: one consistent reading of the whole run went all around the pattern.
* A machine is reported when it survived every run, at least one run gave evidence, the
  number ``n`` of events that drove it is justified (``1 - 2**-n`` above the confidence limit;
  the machine never changes, so ``n`` counts all of them), and it can die at all: a machine
  no event sequence can kill (``(a|b)*`` over ``a, b``) can never report a violation.

Pointers that reach the same state with the same or a smaller visited set are merged (only
the maximal visited sets per state matter for the evidence), and the transitions between
pointer configurations are memoised, so driving a machine costs one lookup per event.
Merging states of consecutive runs is exact: runs share nothing, so alive is the
conjunction, evidence the disjunction and ``n`` the sum.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from imrosc.infer.core import FinalizeContext, Invariant, Samples, confidence
from imrosc.infer.temporal.dfa import Dfa, compile_pattern
from imrosc.infer.temporal.interval import event_codes
from imrosc.runtime.families import PATTERN

__all__ = ["FAMILY", "Machine", "PatternState"]

FAMILY = PATTERN

Config = tuple[tuple[int, tuple[int, ...]], ...]
"""Pointers of a machine: (current state, maximal visited-state masks standing on it), sorted."""

_DEAD = 0
_MEMO_LIMIT = 1 << 16


def _step(moves: Sequence[Sequence[int]], config: Config, symbol: int) -> Config:
    moved: dict[int, set[int]] = {}
    for state, masks in config:
        target = moves[state][symbol]
        if target < 0:
            continue
        bit = 1 << target
        moved.setdefault(target, set()).update(mask | bit for mask in masks)
    return tuple(sorted((state, _maximal(masks)) for state, masks in moved.items()))


def _maximal(masks: set[int]) -> tuple[int, ...]:
    if len(masks) <= 1:
        return tuple(masks)
    ordered = sorted(masks, key=lambda m: (-m.bit_count(), m))
    kept: list[int] = []
    for mask in ordered:
        if not any(mask | other == other for other in kept):
            kept.append(mask)
    return tuple(sorted(kept))


class Machine:
    """One concrete pattern's DFA and its inference state.

    The pointer configurations a machine goes through are few, so their transitions are
    memoised: driving the machine costs one list lookup per event.
    """

    def __init__(
        self, general: str, binding: Mapping[str, str], text: str, events: Sequence[str]
    ) -> None:
        self.general = general
        self.binding = dict(binding)
        self.text = text
        self.dfa: Dfa = compile_pattern(text, events)
        index = {event: i for i, event in enumerate(events)}
        self.lookup = np.full(len(events), -1, dtype=np.int64)
        for local, event in enumerate(self.dfa.alphabet):
            self.lookup[index[event]] = local
        self.moves = [[row.get(e, -1) for e in self.dfa.alphabet] for row in self.dfa.table()]
        self.full = (1 << self.dfa.states) - 1
        self.alive = True
        self.evidence = False
        self.driven = 0
        self.pointers: Config | None = None  # None: no event of the current run yet
        self._reset_memo()

    def _reset_memo(self) -> None:
        self._configs: list[Config] = [()]
        self._ids: dict[Config, int] = {(): _DEAD}
        self._next: list[list[int]] = [[_DEAD] * len(self.dfa.alphabet)]

    def _id(self, config: Config) -> int:
        known = self._ids.get(config)
        if known is not None:
            return known
        if len(self._configs) >= _MEMO_LIMIT:
            self._reset_memo()
        self._ids[config] = len(self._configs)
        self._configs.append(config)
        self._next.append([-1] * len(self.dfa.alphabet))
        return len(self._configs) - 1

    def _follow(self, current: int, symbol: int) -> int:
        config = self._configs[current]
        target = self._id(_step(self.moves, config, symbol))
        if self._ids.get(config) == current:  # the memo may just have been reset
            self._next[current][symbol] = target
        return target

    def start(self) -> Config:
        return tuple((s, (1 << s,)) for s in range(self.dfa.states))

    def drive(self, symbols: Sequence[int]) -> None:
        """Drive the machine on alphabet positions (``lookup`` of the event codes), in order."""
        if not self.alive or not symbols:
            return
        current = self._id(self.pointers if self.pointers is not None else self.start())
        table = self._next
        for symbol in symbols:
            target = table[current][symbol]
            if target < 0:
                target = self._follow(current, symbol)
                table = self._next
            if target == _DEAD:
                self.alive = False
                self.pointers = None
                return
            current = target
        self.driven += len(symbols)
        self.pointers = self._configs[current]

    def run_evidence(self) -> bool:
        """Whether the current run so far has a live pointer that visited every state."""
        if self.pointers is None:
            return False
        return any(self.full in masks for _, masks in self.pointers)

    def end_run(self) -> None:
        if self.alive and self.run_evidence():
            self.evidence = True
        self.pointers = None

    def merge(self, other: Machine) -> None:
        self.end_run()
        self.alive = self.alive and other.alive
        self.evidence = self.evidence or other.evidence
        self.driven += other.driven
        self.pointers = other.pointers
        if not self.alive:
            self.pointers = None

    def reported(self, context: FinalizeContext) -> bool:
        evidence = self.evidence or self.run_evidence()
        return self.alive and evidence and context.justified(self.driven) and self.dfa.can_die()


class PatternState:
    """All concrete patterns of one temporal point (see the module docstring)."""

    family = FAMILY

    def __init__(
        self,
        events: Sequence[str],
        patterns: Sequence[tuple[str, Sequence[tuple[Mapping[str, str], str]]]],
    ) -> None:
        self.events = tuple(events)
        self.index = {event: i for i, event in enumerate(self.events)}
        self.machines: list[Machine] = []
        for general, concrete in patterns:
            for binding, text in concrete:
                machine = Machine(general, binding, text, self.events)
                if machine.dfa.alphabet:
                    self.machines.append(machine)

    def update(self, samples: Samples) -> None:
        codes = event_codes(samples, self.index)
        if len(codes) == 0:
            return
        for machine in self.machines:
            if machine.alive:
                local = machine.lookup[codes]
                machine.drive(local[local >= 0].tolist())

    def end_run(self) -> None:
        for machine in self.machines:
            machine.end_run()

    def merge(self, other: Any) -> None:
        if (
            not isinstance(other, PatternState)
            or other.events != self.events
            or [m.text for m in other.machines] != [m.text for m in self.machines]
        ):
            raise TypeError("can only merge a PatternState over the same events and patterns")
        for mine, theirs in zip(self.machines, other.machines, strict=True):
            mine.merge(theirs)

    def finalize(self, context: FinalizeContext) -> list[Invariant]:
        found: list[Invariant] = []
        for machine in self.machines:
            if not machine.reported(context):
                continue
            params: dict[str, Any] = {
                "pattern": machine.text,
                "general": machine.general,
                "binding": dict(machine.binding),
            }
            params.update(machine.dfa.to_json())
            found.append(
                Invariant(
                    family=FAMILY,
                    kind="pattern",
                    point=context.point,
                    variables=("event",),
                    params=params,
                    text=machine.text,
                    samples=machine.driven,
                    confidence=confidence(machine.driven),
                    condition=context.condition,
                    runs=context.runs,
                )
            )
        return found
