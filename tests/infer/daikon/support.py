"""Helpers of the Daikon family tests: hand-made chunks, folding, merging."""

from __future__ import annotations

import pickle
from collections.abc import Mapping, Sequence
from itertools import pairwise
from typing import Any

import numpy as np
import numpy.typing as npt

from imrosc.infer.core import FamilyState, FinalizeContext, Invariant, Samples, Variable
from imrosc.infer.daikon import FAMILIES, make_states
from imrosc.ir import Tunables

Rows = Mapping[str, Any]
POINT = "p"


def column(values: Sequence[Any] | npt.NDArray[Any], variable: Variable) -> npt.NDArray[Any]:
    """A column as the translator gives it: float64, or object for strings."""
    if variable.type == "string":
        out = np.empty(len(values), dtype=object)
        for i, value in enumerate(values):
            out[i] = value
        return out
    return np.asarray(values, dtype=np.float64)


def chunk(
    variables: tuple[Variable, ...],
    rows: Rows,
    start: int = 0,
    stop: int | None = None,
    run: int = 0,
) -> Samples:
    """Rows ``start:stop`` of ``rows`` as one chunk of the point."""
    length = len(next(iter(rows.values())))
    stop = length if stop is None else stop
    columns = {v.name: column(rows[v.name], v)[start:stop] for v in variables}
    time = np.arange(start, stop, dtype=np.float64) * 0.01
    return Samples(POINT, run, time, columns, variables)


def states(
    variables: tuple[Variable, ...],
    families: Sequence[str] | None = None,
    tunables: Tunables | None = None,
) -> list[FamilyState]:
    """Fresh states of the given families (all Daikon families by default)."""
    chosen = frozenset(FAMILIES if families is None else families)
    return make_states(variables, tunables or Tunables(), chosen)


def feed(built: list[FamilyState], samples: Samples) -> None:
    """Update every state with one chunk."""
    for state in built:
        state.update(samples)


def finalize(
    built: list[FamilyState], variables: tuple[Variable, ...], confidence: float = 0.99
) -> list[Invariant]:
    """Every state's invariants."""
    context = FinalizeContext(Tunables(confidence=confidence), variables, POINT, None, 1)
    return [invariant for state in built for invariant in state.finalize(context)]


def infer(
    variables: tuple[Variable, ...],
    rows: Rows,
    families: Sequence[str] | None = None,
    *,
    chunk_rows: int | None = None,
    confidence: float = 0.99,
) -> list[Invariant]:
    """Invariants of ``rows`` fed in chunks of ``chunk_rows`` (one chunk by default)."""
    built = states(variables, families)
    length = len(next(iter(rows.values())))
    step = chunk_rows or max(1, length)
    for start in range(0, length, step):
        feed(built, chunk(variables, rows, start, min(length, start + step)))
    return finalize(built, variables, confidence)


def texts(found: list[Invariant]) -> list[str]:
    """The invariants' texts."""
    return [invariant.text for invariant in found]


def fold(
    variables: tuple[Variable, ...],
    rows: Rows,
    cuts: Sequence[int],
    families: Sequence[str],
    runs: Sequence[int] = (),
) -> list[FamilyState]:
    """One state per family updated with the chunks between ``cuts`` (runs end at ``runs``)."""
    built = states(variables, families)
    for index, (start, stop) in enumerate(pairwise(cuts)):
        feed(built, chunk(variables, rows, start, stop))
        if index + 1 in runs:
            for state in built:
                state.end_run()
    for state in built:
        state.end_run()
    return built


def merged(
    variables: tuple[Variable, ...],
    rows: Rows,
    cuts: Sequence[int],
    families: Sequence[str],
    parts: Sequence[int],
) -> list[FamilyState]:
    """States built apart over contiguous groups of chunks (split after chunk indices
    ``parts``), pickled like worker results, then merged in order."""
    bounds = [0, *sorted(set(parts)), len(cuts) - 1]
    pieces = []
    for first, last in pairwise(bounds):
        piece = fold(variables, rows, cuts[first : last + 1], families)
        copied: list[FamilyState] = pickle.loads(pickle.dumps(piece))
        pieces.append(copied)
    total = pieces[0]
    for piece in pieces[1:]:
        for mine, theirs in zip(total, piece, strict=True):
            mine.merge(theirs)
    return total
