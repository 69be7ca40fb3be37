"""A point's checks compiled by numba into one call that clears a sample, when numba is
importable.

A monitor relaying a topic checks each message cold: other processes have emptied the
caches since the last one, and each of the dozen numpy calls of :meth:`.checks.Checks.check`
then costs several microseconds of dispatch before any work. Most samples break nothing, so
one compiled loop first asks the question that decides the common case: does the sample
break nothing? It evaluates every check numpy would on the way (the linear forms, the
polygons' ranges, their bits and the edges of the candidates, the one-of sets, the non-zero
values) and answers ``True`` only when all of them hold. Anything else (a broken invariant,
a value outside a polygon's range or not finite where a polygon reads it) answers ``False``
and numpy's path finds the violations as before, so the violations are numpy's either way.

The arithmetic is the exact paths': a form sums its terms' products ``w * x`` in order and
compares with its limit (the constant moved into the limit, as the dense product does: the
tolerance of a relation covers any order of summation; bounds and orderings have one
rounding at most); a polygon's cell is numpy's ``(x - origin) * scale`` truncated to uint8
and its edges are ``a * x + b * y > c`` in float64 (numba emits no fused multiply-add). A
missing value (NaN) breaks no form, set or non-zero invariant, as in numpy.

The tables are packed into three arrays (:class:`Tables`: int32, float64 and the polygons'
bits), so the kernel is compiled once per process (for the kinds of sample a check gets:
:func:`_samples`), cached on disk where numba can, and a call passes four arrays.

numba is optional: Debian's ``python3-numba`` (or ``pip install numba``). Without it, or
with ``IMROSC_NUMBA=0`` in the environment, :func:`compile_checks` gives ``None`` and numpy
checks every sample.
"""

from __future__ import annotations

import functools
import math
import os
from typing import Any, Callable, Iterator, List, NamedTuple, Optional, Sequence, Tuple

import numpy as np

Edge = Tuple[float, float, float]
Form = Tuple[Sequence[Tuple[int, float]], float]
"""A linear form's terms ``(position, weight)`` over the sample, and the limit its sum
must not exceed."""
Guard = Tuple[int, float, float, float, float]
"""A variable the polygons read: its position, range (low, high) and quantisation (origin,
scale) into the bits' cells."""


class Polygon(NamedTuple):
    """A polygon as the kernel reads it."""

    column: int
    row: int
    """Positions of the variables of its bits' columns and rows."""
    base: int
    bit: int
    """Its start in the bits, and its bit there."""
    coarse: Sequence[int]
    """Its coarse bits: ``COARSE x COARSE`` cells (column first), each the union of the
    fine cells it holds (``fine >> shift``), as 32-bit words."""
    x: int
    y: int
    edges: Sequence[Edge]
    """Positions of its x and y, and its edges ``a*x + b*y <= c``."""


COARSE = 16
"""Coarse cells per axis of a polygon's first look (its 256 bits in its record)."""
_RECORD = 16
"""int32 per polygon record: column, row, base, bit, x, y, first and stop edge, and the
eight words of its coarse bits: 64 bytes, read in order (the polygons' records one after
the other: a stream the processor fetches ahead)."""
OneOf = Tuple[int, Sequence[float]]
Kernel = Callable[[Any, Any, Any, Any], bool]

# the header of Tables.ints: counts, and where each section starts in ints or floats
_FORMS, _TERM_START, _TERM_AT, _TERM_WEIGHT, _LIMIT = 0, 1, 2, 3, 4
_GUARDS, _GUARD_AT, _GUARD_RANGE, _GUARD_SCALE, _WIDTH = 5, 6, 7, 8, 9
_POLYGONS, _POLYGON, _ABC = 10, 11, 12
_ONE_OF, _ONE_AT, _ONE_START, _ONE_VALUES = 14, 15, 16, 17
_NONZERO, _NONZERO_AT, _SHIFT = 18, 19, 20
_HEADER = 21


class Tables(NamedTuple):
    """A point's checks as the kernel reads them."""

    ints: Any
    """int32: the header, then positions, section starts and the polygons' records."""
    floats: Any
    """float64: weights, limits, ranges, quantisations, edges and sets' values."""
    bits: Any
    """uint8: the polygons' bits (:mod:`.polygons`)."""


def numba_module() -> Any:
    """numba, or ``None`` (not installed, not importable, or ``IMROSC_NUMBA=0``)."""
    if os.environ.get("IMROSC_NUMBA", "1") == "0":
        return None
    return _imported_numba()


@functools.lru_cache(maxsize=None)
def _imported_numba() -> Any:
    """numba, imported once (a failed import is not retried for every point)."""
    try:
        import numba  # type: ignore[import-not-found, unused-ignore]
    except Exception:  # ImportError, or a numba built for another numpy
        return None
    return numba


def pack(
    forms: Sequence[Form],
    guards: Sequence[Guard],
    polygons: Sequence[Polygon],
    bits: Any,
    shift: int,
    one_of: Sequence[OneOf],
    nonzero: Sequence[int],
) -> Tables:
    """The tables of one point's checks."""
    header = [0] * _HEADER
    ints: List[int] = []
    floats: List[float] = []

    def put_ints(slot: int, values: Sequence[int]) -> None:
        header[slot] = _HEADER + len(ints)
        ints.extend(int(v) for v in values)

    def put_floats(slot: int, values: Sequence[float]) -> None:
        header[slot] = len(floats)
        floats.extend(float(v) for v in values)

    starts: List[int] = [0]
    at: List[int] = []
    weights: List[float] = []
    for terms, _ in forms:
        for position, weight in terms:
            at.append(position)
            weights.append(weight)
        starts.append(len(at))
    header[_FORMS] = len(forms)
    put_ints(_TERM_START, starts)
    put_ints(_TERM_AT, at)
    put_floats(_TERM_WEIGHT, weights)
    put_floats(_LIMIT, [limit for _, limit in forms])
    header[_GUARDS] = len(guards)
    header[_WIDTH] = max([g[0] + 1 for g in guards] + [0])
    put_ints(_GUARD_AT, [g[0] for g in guards])
    put_floats(_GUARD_RANGE, [end for g in guards for end in g[1:3]])
    put_floats(_GUARD_SCALE, [q for g in guards for q in g[3:5]])
    header[_POLYGONS] = len(polygons)
    header[_SHIFT] = shift
    records: List[int] = []
    abc: List[float] = []
    for polygon in polygons:
        first = len(abc) // 3
        abc += [v for edge in polygon.edges for v in edge]
        stop = len(abc) // 3
        records += [polygon.column, polygon.row, polygon.base, polygon.bit, polygon.x, polygon.y]
        records += [first, stop, *polygon.coarse]
    put_ints(_POLYGON, records)
    put_floats(_ABC, abc)
    header[_ONE_OF] = len(one_of)
    put_ints(_ONE_AT, [position for position, _ in one_of])
    values = [v for _, held in one_of for v in held]
    ends = np.cumsum([0] + [len(held) for _, held in one_of]).tolist()
    put_ints(_ONE_START, ends)
    put_floats(_ONE_VALUES, values)
    header[_NONZERO] = len(nonzero)
    put_ints(_NONZERO_AT, nonzero)
    return Tables(
        np.asarray(header + ints, dtype=np.int32),
        np.asarray(floats, dtype=np.float64),
        np.ascontiguousarray(bits, dtype=np.uint8),
    )


def clears(row: Any, ints: Any, floats: Any, bits: Any) -> bool:
    """Whether ``row`` breaks none of the checks in the tables (``False``: it may break
    one). Plain Python that numba compiles; it runs uncompiled too (the tests' reference)."""
    count = ints[_FORMS]
    start, at, weight, limit = ints[_TERM_START], ints[_TERM_AT], ints[_TERM_WEIGHT], ints[_LIMIT]
    for k in range(count):
        total = 0.0
        for t in range(ints[start + k], ints[start + k + 1]):
            total += floats[weight + t] * row[ints[at + t]]
        if total > floats[limit + k]:
            return False
    count = ints[_GUARDS]
    if count:
        at, ends, scales = ints[_GUARD_AT], ints[_GUARD_RANGE], ints[_GUARD_SCALE]
        cells = np.zeros(ints[_WIDTH], np.int32)
        for k in range(count):
            x = row[ints[at + k]]
            if not (x >= floats[ends + 2 * k] and x <= floats[ends + 2 * k + 1]):
                return False  # outside a range, or NaN: numpy's slow path
            cell = (x - floats[scales + 2 * k]) * floats[scales + 2 * k + 1]
            cells[ints[at + k]] = np.int32(np.uint8(cell))
        shift, abc = ints[_SHIFT], ints[_ABC]
        r = ints[_POLYGON]
        for _ in range(ints[_POLYGONS]):
            column, line = cells[ints[r]], cells[ints[r + 1]]
            # the coarse bits first (in the record: read in order), the fine ones if set
            coarse = (column >> shift) + COARSE * (line >> shift)
            if (ints[r + 8 + (coarse >> 5)] >> (coarse & 31)) & 1 and (
                bits[ints[r + 2] + column + 256 * line] & ints[r + 3]
            ):
                x, y = row[ints[r + 4]], row[ints[r + 5]]
                for m in range(ints[r + 6], ints[r + 7]):
                    q = abc + 3 * m
                    if floats[q] * x + floats[q + 1] * y > floats[q + 2]:
                        return False
            r += _RECORD
    at, start, values = ints[_ONE_AT], ints[_ONE_START], ints[_ONE_VALUES]
    for k in range(ints[_ONE_OF]):
        x = row[ints[at + k]]
        if math.isnan(x):
            continue  # NaN breaks nothing
        held = False
        for t in range(ints[start + k], ints[start + k + 1]):
            if x == floats[values + t]:
                held = True
                break
        if not held:
            return False
    at = ints[_NONZERO_AT]
    for k in range(ints[_NONZERO]):  # noqa: SIM110 (a loop numba compiles)
        if row[ints[at + k]] == 0:
            return False
    return True


_kernel: List[Optional[Kernel]] = []
"""The compiled :func:`clears`, once compiled (``[None]``: numba cannot)."""


def compile_checks(tables: Tables, width: int) -> Optional[Kernel]:
    """:func:`clears` compiled (once per process) and ready for samples of ``width``
    values of every kind a check gets (:func:`_samples`); ``None`` without numba."""
    numba = numba_module()
    if numba is None:
        return None
    if not _kernel:
        _kernel.append(_compiled(numba))
    kernel = _kernel[0]
    if kernel is None:
        return None
    try:
        for sample in _samples(np.zeros(max(width, 1))):
            kernel(sample, *tables)
    except Exception:  # a numba that cannot compile this: numpy checks every sample
        return None
    return kernel


def _compiled(numba: Any) -> Optional[Kernel]:
    """:func:`clears` compiled by numba, cached in ``__pycache__`` where numba can write
    (a monitor then starts without compiling); ``None`` if numba cannot."""
    # the GIL is kept: released, a relay's thread would queue for it behind the others
    for cache in (True, False):
        try:
            kernel: Kernel = numba.njit(cache=cache)(clears)
            return kernel
        except Exception:  # no cache locator for this file: compiled in memory
            continue
    return None


def _samples(values: Any) -> Iterator[Any]:
    """``values`` as each kind of array a check gets, for numba to compile them all before
    the first sample: writable (a list read into an array), and read-only views of bytes
    (a monitor's values), aligned or not (after a string of odd length)."""
    data = values.tobytes()
    yield values.copy()
    yield np.frombuffer(data, dtype=np.float64)
    yield np.frombuffer(b"\0" + data, dtype=np.float64, offset=1)
