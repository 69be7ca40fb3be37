"""The polygons' candidate lookup compiled by numba, when numba is importable.

A cold lookup (the caches emptied by other processes since the last sample, as in a monitor
relaying a topic) spends most of its time in numpy's dispatch of a dozen small operations,
not in the work. One compiled loop over the polygons does the same work in one call: the
fine cell of each variable, each polygon's offset in the bits, its bit. The arithmetic is
numpy's, operation for operation (``(x - origin) * scale`` in float64, truncated to uint8;
``column + 256 * row``), so the candidates are the same; ``tests/runtime`` compares the two.

numba is optional: Debian's ``python3-numba`` (or ``pip install numba``). Without it, or
with ``IMROSC_NUMBA=0`` in the environment, :func:`candidate_lookup` gives ``None`` and the
polygons use numpy. The tables are compiled in as constants: building the checks costs a
compilation (a quarter of a second for 1,000 polygons), done before the first sample.
"""

from __future__ import annotations

import os
from typing import Any, Callable, Iterator, Optional

import numpy as np

Lookup = Callable[[Any, Any, Any], int]
"""``lookup(row, offsets, found) -> n``: writes every polygon's offset in the bits to
``offsets`` and the polygons whose bit is set (the candidates, ascending) to ``found[:n]``."""


def numba_module() -> Any:
    """numba, or ``None`` (not installed, not importable, or ``IMROSC_NUMBA=0``)."""
    if os.environ.get("IMROSC_NUMBA", "1") == "0":
        return None
    try:
        import numba  # type: ignore[import-not-found, unused-ignore]
    except Exception:  # ImportError, or a numba built for another numpy
        return None
    return numba


def candidate_lookup(
    size: int, origin: Any, scale: Any, at: Any, base: Any, bits: Any, bit: Any
) -> Optional[Lookup]:
    """The compiled lookup of the polygons whose tables are given (``PolygonChecks``:
    ``size`` variables quantised by ``origin`` and ``scale``; ``at``, two variables per
    polygon, column first; ``base``, each polygon's start in ``bits``; ``bit``, its bit),
    compiled for every kind of sample a check gets (:func:`_samples`); ``None`` without numba.
    Samples must be inside the polygons' ranges (the fast path)."""
    numba = numba_module()
    if numba is None:
        return None
    origin = np.ascontiguousarray(origin, dtype=np.float64)
    scale = np.ascontiguousarray(scale, dtype=np.float64)
    at = np.ascontiguousarray(at, dtype=np.int64)
    base = np.ascontiguousarray(base, dtype=np.int64)
    bits = np.ascontiguousarray(bits, dtype=np.uint8)
    bit = np.ascontiguousarray(bit, dtype=np.uint8)
    count = len(base)

    def lookup(row: Any, offsets: Any, found: Any) -> int:
        cells = np.empty(size, np.uint8)
        for v in range(size):
            cells[v] = np.uint8((row[v] - origin[v]) * scale[v])
        n = 0
        for j in range(count):
            offset = base[j] + cells[at[2 * j]] + 256 * cells[at[2 * j + 1]]
            offsets[j] = offset
            if bits[offset] & bit[j]:
                found[n] = j
                n += 1
        return n

    try:
        # the GIL is kept: released, a relay's thread would queue for it behind the others
        compiled = numba.njit(lookup)
        offsets = np.zeros(count, dtype=np.int64)
        found = np.zeros(count, dtype=np.int64)
        for sample in _samples(origin):
            compiled(sample, offsets, found)
    except Exception:  # a numba that cannot compile this: numpy does the lookup
        return None
    return compiled  # type: ignore[no-any-return]


def _samples(values: Any) -> Iterator[Any]:
    """``values`` as each kind of array a check gets, for numba to compile them all before
    the first sample: writable (a list read into an array), and read-only views of bytes
    (a monitor's values), aligned or not (after a string of odd length)."""
    data = values.tobytes()
    yield values.copy()
    yield np.frombuffer(data, dtype=np.float64)
    yield np.frombuffer(b"\0" + data, dtype=np.float64, offset=1)
