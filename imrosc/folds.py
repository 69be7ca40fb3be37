"""Blocked folds: held-out evaluation that keeps runs recorded together together.

Runs recorded close together (one session, one day, neighbouring segments of one run)
share their conditions; holding them out together keeps a held-out run from being
explained by its own neighbour, which would make held-out figures optimistic about a run of
another day. Calibration (:mod:`imrosc.calibrate`), the detectors' cross-fitting
(:mod:`imrosc.detectors`) and classification's held-out choice of the monitor all cut their
runs so.
"""

from __future__ import annotations

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
    size, extra = divmod(len(ranked), k)
    found, at = [], 0
    for fold in range(k):
        width = size + (fold < extra)
        found.append(ranked[at : at + width])
        at += width
    return [group for group in found if group]
