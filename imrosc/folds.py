"""Blocked folds: held-out evaluation that keeps runs recorded together together.

Runs recorded close together (one session, one day, neighbouring segments of one run)
share their conditions; holding them out together keeps a held-out run from being
explained by its own neighbour, which would make held-out figures optimistic about a run of
another day. The detectors' cross-fitting (:mod:`imrosc.detectors`) and classification's
held-out choice of the monitor cut their runs into near-equal blocks (:func:`blocked`);
calibration (:mod:`imrosc.calibrate`) cuts at the widest gaps between the runs' starts
(:func:`at_gaps`), so that a session is never split.
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Callable, Sequence
from typing import Any, TypeVar

T = TypeVar("T")


def blocked(items: Sequence[T], order: Callable[[T], Any], folds: int) -> list[list[int]]:
    """The items (indexes) sorted by ``order``, cut into ``folds`` contiguous blocks (at
    least 2, at most one per item) of sizes differing by at most one.

    >>> blocked([30, 10, 20, 40, 50], lambda x: x, 2), blocked([30, 10, 20, 40, 50], lambda x: x, 3)
    ([[1, 2, 0], [3, 4]], [[1, 2], [0, 3], [4]])
    """
    ranked = sorted(range(len(items)), key=lambda k: (order(items[k]), k))
    k = max(2, min(folds, len(ranked)))
    return [ranked[part.start : part.stop] for part in _even(len(ranked), k) if len(part)]


def at_gaps(
    starts: Sequence[float], folds: int, ends: Sequence[float | None] | None = None
) -> list[list[int]]:
    """The items (indexes) in the order of their ``starts``, cut into ``folds`` contiguous
    blocks (at least 2, at most one per item) at the widest gaps between consecutive
    starts: runs recorded in one session (minutes apart) stay in one block, and sessions of
    other days are held out from each other. Gaps of the same width (within a millionth:
    the time segments of one run, runs recorded at a steady pace) are cut where
    :func:`blocked` cuts, so evenly spaced items give its near-equal blocks.

    ``ends`` (where known): a gap counts only where every item before it had ended. Items
    that overlap were recorded side by side (one session) or on clocks that restart with
    every run (simulated time, from 0 in each bag), and then their starts, milliseconds
    apart by the jitter of a first message, say nothing of sessions: the gap between them
    is none, and runs that all overlap get near-equal blocks.

    >>> at_gaps([0, 1, 2, 100, 101, 500], 3)
    [[0, 1, 2], [3, 4], [5]]
    >>> at_gaps([30, 10, 20, 40, 50], 2), at_gaps([30, 10, 20, 40, 50], 3)
    ([[1, 2, 0], [3, 4]], [[1, 2], [0, 3], [4]])
    >>> at_gaps([0.01, 0.01, 0.01, 0.01, 0.03, 0.07], 3)
    [[0, 1, 2, 3], [4], [5]]
    >>> at_gaps([0.01, 0.01, 0.01, 0.01, 0.03, 0.07], 3, ends=[22, 25, 40, 23, 30, 22])
    [[0, 1], [2, 3], [4, 5]]
    """
    ranked = sorted(range(len(starts)), key=lambda k: (starts[k], k))
    k = max(2, min(folds, len(ranked)))
    if len(ranked) < 2:
        return [ranked] if ranked else []
    even = [part.stop for part in _even(len(ranked), k)][:-1]
    gaps = [float(starts[b]) - float(starts[a]) for a, b in itertools.pairwise(ranked)]
    if ends is not None:
        ended = -math.inf  # the latest end of the items before each gap
        for at, item in enumerate(ranked[:-1]):
            end = ends[item]
            ended = max(ended, float(starts[item]) if end is None else float(end))
            if float(starts[ranked[at + 1]]) < ended:
                gaps[at] = 0.0  # overlapping items: no gap between their starts
    widest = max(gaps)
    scale = 1e-6 * widest if widest > 0 else 0.0

    def rank(cut: int) -> tuple[float, int]:
        # cut before ranked[cut]; equal gaps (to a millionth) go where the even blocks cut
        width = round(gaps[cut - 1] / scale) if scale else 0
        return (-width, min(abs(cut - e) for e in even))

    cuts = sorted(sorted(range(1, len(ranked)), key=rank)[: k - 1])
    edges = [0, *cuts, len(ranked)]
    return [ranked[a:b] for a, b in itertools.pairwise(edges)]


def _even(n: int, k: int) -> list[range]:
    """``n`` positions in ``k`` contiguous parts of sizes differing by at most one (the
    near-equal blocks of :func:`blocked`, and where :func:`at_gaps` cuts equal gaps)."""
    size, extra = divmod(n, k)
    found, at = [], 0
    for fold in range(k):
        width = size + (fold < extra)
        found.append(range(at, at + width))
        at += width
    return found
