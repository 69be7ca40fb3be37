"""Support of a ternary relation over a variable with few values, level by level.

A variable with 2 or 3 distinct values (a mode, a gear, a sign) may take part in a ternary
relation ``t = a - 2*m + 1`` when the relation is not an artefact of few points: on each
level of ``m`` the relation is a line between the two other variables, and Daikon's own
rule for lines asks for more than 3 distinct points (two or three always lie on one).
:class:`LevelSupport` counts, per candidate triple and per member that has few values so
far, the distinct points of the two other members on each of its levels, up to
``ENOUGH`` (then the level is *full* and its points are forgotten). A triple's member is
*supported* once ``LEVELS`` of its levels are full: the common slope is then tested on
two independent lines and the offset between them by the relation.

Sets of distinct points merge by union, and a full level stays full, so folding chunks
and merging states in any grouping give the same counts.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np

from imrosc.infer.core import FloatArray
from imrosc.infer.daikon.common import IntArray

ENOUGH = 4
"""Distinct points that make a level full (more than 3: Daikon's rule for a line)."""
LEVELS = 2
"""Full levels that support a few-valued member."""

Key = tuple[tuple[int, int, int], int]
Points = set[tuple[float, float]]


@dataclass
class LevelSupport:
    """Per ``(triple, member)``: level value -> distinct points (``None`` once full)."""

    levels: dict[Key, dict[float, Points | None]] = field(default_factory=dict)

    def supported(self, triple: tuple[int, int, int], member: int) -> bool:
        """Whether ``member`` (0, 1 or 2) of ``triple`` has ``LEVELS`` full levels."""
        found = self.levels.get((triple, member), {})
        return sum(points is None for points in found.values()) >= LEVELS

    def update(self, columns: Sequence[FloatArray], live: IntArray, few: Sequence[bool]) -> None:
        """Count the chunk's points of the ``live`` triples whose members in ``few`` have
        few values so far (members already supported are skipped)."""
        for row in live.tolist():
            triple = (int(row[0]), int(row[1]), int(row[2]))
            for member in range(3):
                if not few[triple[member]] or self.supported(triple, member):
                    continue
                self._add(triple, member, [columns[v] for v in triple])

    def _add(self, triple: tuple[int, int, int], member: int, columns: list[FloatArray]) -> None:
        own = columns[member] + 0.0  # -0.0 is 0.0
        x, y = (columns[k] + 0.0 for k in range(3) if k != member)
        present = ~(np.isnan(own) | np.isnan(x) | np.isnan(y))
        if not present.all():
            own, x, y = own[present], x[present], y[present]
        found = self.levels.setdefault((triple, member), {})
        while len(own):  # one level per round: the member has at most 3 values so far
            level = float(own[0])
            on = own == level
            points = found.get(level, set())
            if points is not None:
                found[level] = _more(points, x[on], y[on])
            off = ~on
            own, x, y = own[off], x[off], y[off]

    def merge(self, other: LevelSupport) -> None:
        """Absorb the counts of another state (unions; full stays full)."""
        for key, theirs in other.levels.items():
            mine = self.levels.setdefault(key, {})
            for level, points in theirs.items():
                have = mine.get(level, set())
                if have is None or points is None:
                    mine[level] = None
                    continue
                union = have | points
                mine[level] = None if len(union) >= ENOUGH else union


_HEAD = 64
"""Rows of a level looked at first: continuous partners show ``ENOUGH`` points in them."""


def _more(points: Points, x: FloatArray, y: FloatArray) -> Points | None:
    """``points`` with the distinct ``(x, y)`` (``None`` once ``ENOUGH``): the level's first
    ``_HEAD`` rows first, all of them only if those do not fill it."""
    if not len(x):
        return points
    if (x == x[0]).all() and (y == y[0]).all():  # partners constant on the level here
        union = points | {(float(x[0]), float(y[0]))}
        return None if len(union) >= ENOUGH else union
    union = points
    for stop in (_HEAD, len(x)):
        pair = np.empty(min(stop, len(x)), np.complex128)
        pair.real, pair.imag = x[:stop], y[:stop]
        union = points | {(z.real, z.imag) for z in np.unique(pair).tolist()}
        if len(union) >= ENOUGH:
            return None
        if stop >= len(x):
            break
    return union
