"""Concrete temporal patterns as minimal DFAs over event ids (thesis 3.4.4.2, Algorithms 9, 12).

A concrete pattern is the text the plan gives for one binding of a ``<pattern>``'s
placeholders: a regular expression over event ids, one letter per id, with a longer id written
``<id>`` (``(ab)*``, ``((<scan>|<imu>)+<sync>)*``). :func:`compile_pattern` maps the longer
ids to fresh letters, parses the text with :func:`imrosc.schema.pattern.parse_pattern`, builds
a Thompson NFA, determinises it by subset construction, drops the states from which no
accepting state can be reached (they all mean "error"), minimises by partition refinement and
numbers the states breadth-first from the start state, trying events in alphabet order. The
result is canonical: equal languages over the same alphabet give equal :class:`Dfa` s.

The alphabet is the set of events the pattern names. A machine is driven only by events of its
alphabet ("drive DFA on event if applicable", Algorithm 9); other events of the scope pass it
by. A missing transition is the error state.

>>> dfa = compile_pattern("(aab)*", ("a", "b"))
>>> dfa.states, dfa.accepting, dfa.transitions
(3, (0,), ((('a', 1),), (('a', 2),), (('b', 0),)))
>>> dfa.step_set(frozenset(dfa.all_states()), "b")
frozenset({0})
"""

from __future__ import annotations

import re
import string
from collections import deque
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass
from typing import Any

from imrosc.schema import pattern as rx

__all__ = ["Dfa", "compile_pattern", "dfa_from_json", "pattern_letters"]

_LONG_ID = re.compile(r"<([^<>]*)>")


@dataclass(frozen=True)
class Dfa:
    """A minimal DFA whose states are ``0 .. states-1`` (0 the start), all of them live.

    ``transitions[s]`` lists ``(event, next_state)`` in alphabet order; an event missing
    from it leads to the error state.
    """

    alphabet: tuple[str, ...]
    states: int
    transitions: tuple[tuple[tuple[str, int], ...], ...]
    accepting: tuple[int, ...]

    def all_states(self) -> range:
        return range(self.states)

    def table(self) -> list[dict[str, int]]:
        """``table()[s][event]`` is the next state; a missing key is the error state."""
        return [dict(row) for row in self.transitions]

    def step_set(self, current: Iterable[int], event: str) -> frozenset[int]:
        """Algorithm 12: drive every state of a state set; the error state drops out."""
        table = self.table()
        return frozenset(table[s][event] for s in current if event in table[s])

    def can_die(self, limit: int = 1 << 14) -> bool:
        """Whether some event sequence empties the state set that starts as all states.

        A machine that can never die can never report a violation: its invariant is vacuous
        (``(a|b)*`` over ``a, b``). Explores at most ``limit`` state sets and answers ``True``
        (keep the invariant) if that is not enough to decide.
        """
        table = self.table()
        start = frozenset(self.all_states())
        seen = {start}
        queue = deque([start])
        while queue:
            current = queue.popleft()
            for event in self.alphabet:
                nxt = frozenset(table[s][event] for s in current if event in table[s])
                if not nxt:
                    return True
                if nxt not in seen:
                    if len(seen) >= limit:
                        return True
                    seen.add(nxt)
                    queue.append(nxt)
        return False

    def to_json(self) -> dict[str, Any]:
        """The params form: ``{"alphabet", "states", "start", "transitions", "accepting"}``.

        ``transitions`` maps each state (as a decimal string, JSON keys being strings) to an
        object from event id to next state.
        """
        return {
            "alphabet": list(self.alphabet),
            "states": self.states,
            "start": 0,
            "transitions": {str(s): dict(row) for s, row in enumerate(self.transitions)},
            "accepting": list(self.accepting),
        }


def pattern_letters(text: str, events: Sequence[str]) -> tuple[str, dict[str, str]]:
    """Text with every ``<id>`` replaced by a fresh letter, and the map from letters to ids.

    Single-letter ids stand for themselves. Raise ``ValueError`` for an id outside
    ``events``, a placeholder left unbound or more ids than letters.
    """
    scope = set(events)
    longs: list[str] = []
    for match in _LONG_ID.finditer(text):
        event = match.group(1)
        if event not in scope:
            raise ValueError(f"pattern {text!r} names event {event!r} outside the scope")
        if event not in longs:
            longs.append(event)
    plain = _LONG_ID.sub("", text)
    used = {c for c in plain if c in string.ascii_letters} | {e for e in events if len(e) == 1}
    free = [c for c in string.ascii_lowercase + string.ascii_uppercase if c not in used]
    if len(free) < len(longs):
        raise ValueError(f"pattern {text!r} uses more events than there are letters")
    letters = dict(zip(longs, free, strict=False))
    mapping = {letter: event for event, letter in letters.items()}
    for c in plain:
        if c in string.ascii_letters:
            if c not in scope:
                what = "placeholder" if c.isupper() else "event"
                raise ValueError(f"pattern {text!r}: {what} {c!r} is not an event of the scope")
            mapping[c] = c
    rewritten = _LONG_ID.sub(lambda m: letters[m.group(1)], text)
    return rewritten, mapping


class _Nfa:
    """Thompson construction: ``edges[s]`` labelled (letter or ``None`` for epsilon)."""

    def __init__(self) -> None:
        self.edges: list[list[tuple[str | None, int]]] = []

    def state(self) -> int:
        self.edges.append([])
        return len(self.edges) - 1

    def build(self, node: rx.Pattern) -> tuple[int, int]:
        if isinstance(node, rx.Symbol | rx.Epsilon):
            start, end = self.state(), self.state()
            label = node.letter if isinstance(node, rx.Symbol) else None
            self.edges[start].append((label, end))
            return start, end
        if isinstance(node, rx.Concat):
            first, last = self.build(node.parts[0])
            for part in node.parts[1:]:
                start, end = self.build(part)
                self.edges[last].append((None, start))
                last = end
            return first, last
        if isinstance(node, rx.Union):
            start, end = self.state(), self.state()
            for option in node.options:
                inner_start, inner_end = self.build(option)
                self.edges[start].append((None, inner_start))
                self.edges[inner_end].append((None, end))
            return start, end
        start, end = self.state(), self.state()
        inner_start, inner_end = self.build(node.inner)
        self.edges[start].append((None, inner_start))
        self.edges[inner_end].append((None, inner_start))
        self.edges[inner_end].append((None, end))
        if isinstance(node, rx.Star):
            self.edges[start].append((None, end))
        return start, end

    def closure(self, states: Iterable[int]) -> frozenset[int]:
        stack = list(states)
        seen = set(stack)
        while stack:
            state = stack.pop()
            for label, target in self.edges[state]:
                if label is None and target not in seen:
                    seen.add(target)
                    stack.append(target)
        return frozenset(seen)


def _determinise(
    nfa: _Nfa, start: int, end: int, alphabet: Sequence[str]
) -> tuple[list[dict[str, int]], set[int]]:
    first = nfa.closure((start,))
    index = {first: 0}
    order = [first]
    table: list[dict[str, int]] = []
    position = 0
    while position < len(order):
        current = order[position]
        position += 1
        row: dict[str, int] = {}
        for letter in alphabet:
            moved = [t for s in current for label, t in nfa.edges[s] if label == letter]
            if not moved:
                continue
            target = nfa.closure(moved)
            if target not in index:
                index[target] = len(order)
                order.append(target)
            row[letter] = index[target]
        table.append(row)
    accepting = {i for i, subset in enumerate(order) if end in subset}
    return table, accepting


def _minimise(
    table: list[dict[str, int]], accepting: set[int], alphabet: Sequence[str]
) -> tuple[list[dict[str, int]], set[int]]:
    # Drop states that cannot reach acceptance: they behave as the error state.
    reverse: list[list[int]] = [[] for _ in table]
    for source, row in enumerate(table):
        for target in row.values():
            reverse[target].append(source)
    live = set(accepting)
    stack = list(accepting)
    while stack:
        for source in reverse[stack.pop()]:
            if source not in live:
                live.add(source)
                stack.append(source)
    # Moore refinement; a missing or dead transition is class -1.
    block = {s: (1 if s in accepting else 0) for s in live}
    while True:
        signatures = {
            s: (
                block[s],
                tuple(
                    block[table[s][a]] if a in table[s] and table[s][a] in live else -1
                    for a in alphabet
                ),
            )
            for s in live
        }
        numbering: dict[tuple[int, tuple[int, ...]], int] = {}
        refined = {s: numbering.setdefault(sig, len(numbering)) for s, sig in signatures.items()}
        if len(numbering) == len(set(block.values())):
            break
        block = refined
    # Number the blocks breadth-first from the start (state 0 of the subset construction).
    order = {block[0]: 0}
    queue = deque([0])
    members: dict[int, int] = {block[0]: 0}
    while queue:
        state = queue.popleft()
        for a in alphabet:
            nxt = table[state].get(a)
            if nxt is None or nxt not in live:
                continue
            if block[nxt] not in order:
                order[block[nxt]] = len(order)
                members[block[nxt]] = nxt
                queue.append(nxt)
    result: list[dict[str, int]] = []
    for blk, _ in sorted(order.items(), key=lambda item: item[1]):
        state = members[blk]
        result.append(
            {
                a: order[block[table[state][a]]]
                for a in alphabet
                if a in table[state] and table[state][a] in live
            }
        )
    final = {order[block[s]] for s in accepting}
    return result, final


def compile_pattern(text: str, events: Sequence[str]) -> Dfa:
    """The minimal DFA of a concrete pattern over the events of a temporal point.

    Raise ``ValueError`` (:class:`imrosc.schema.pattern.PatternError` for bad syntax) if the
    text is no pattern over ``events``.
    """
    rewritten, mapping = pattern_letters(text, events)
    tree = rx.parse_pattern(rewritten)
    letters = sorted(
        {c for c in rewritten if c in mapping}, key=lambda c: list(events).index(mapping[c])
    )
    nfa = _Nfa()
    start, end = nfa.build(tree)
    table, accepting = _determinise(nfa, start, end, letters)
    minimal, final = _minimise(table, accepting, letters)
    return Dfa(
        alphabet=tuple(mapping[c] for c in letters),
        states=len(minimal),
        transitions=tuple(
            tuple((mapping[a], row[a]) for a in letters if a in row) for row in minimal
        ),
        accepting=tuple(sorted(final)),
    )


def dfa_from_json(params: Mapping[str, Any]) -> Dfa:
    """Read back :meth:`Dfa.to_json` (the monitor's view of a ``pattern`` invariant)."""
    alphabet = tuple(str(e) for e in params["alphabet"])
    states = int(params["states"])
    rows = params["transitions"]
    transitions = tuple(
        tuple((e, int(rows[str(s)][e])) for e in alphabet if e in rows[str(s)])
        for s in range(states)
    )
    return Dfa(alphabet, states, transitions, tuple(int(s) for s in params["accepting"]))
