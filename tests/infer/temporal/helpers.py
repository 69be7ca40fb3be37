"""Event streams as temporal-point samples, and concrete patterns as the plan lists them."""

from __future__ import annotations

import itertools
from collections.abc import Sequence

import numpy as np

from imrosc.infer.core import FinalizeContext, Samples, Variable
from imrosc.ir import Tunables
from imrosc.passes.temporal import render
from imrosc.schema import pattern as rx

VARIABLES = (Variable("event", "string"),)
Event = tuple[str, float]


def samples(events: Sequence[Event], run: int = 0, point: str = "e") -> Samples:
    column = np.empty(len(events), dtype=object)
    for i, (event, _) in enumerate(events):
        column[i] = event
    time = np.array([t for _, t in events], dtype=np.float64)
    return Samples(point, run, time, {"event": column}, VARIABLES)


def trace(text: str, step: float = 0.25, start: float = 0.0) -> list[Event]:
    """Single-letter events one ``step`` apart: ``trace("ab")``."""
    return [(event, start + i * step) for i, event in enumerate(text)]


def context(limit: float = 0.99, point: str = "e") -> FinalizeContext:
    return FinalizeContext(Tunables(confidence=limit), VARIABLES, point)


def concrete(text: str, events: Sequence[str]) -> tuple[str, list[tuple[dict[str, str], str]]]:
    """A ``<pattern>`` with its concrete patterns, as the ``label_events`` pass binds them."""
    tree = rx.parse_pattern(text)
    holes = sorted(rx.placeholders(tree))
    bound = []
    for chosen in itertools.permutations(events, len(holes)):
        binding = dict(zip(holes, chosen, strict=True))
        bound.append((binding, render(tree, binding)))
    return text, bound
