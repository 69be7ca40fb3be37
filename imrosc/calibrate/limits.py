"""The envelopes of the invariants, as one-sided limits each family widens in its own scale.

An envelope is a set of *limits* ``statistic <= value`` (an upper limit) or
``statistic >= value`` (a lower one). Calibration reads each limit's value in the merged
invariant and its *support* in every unit (a run, or a segment of one): how far that unit
alone went. It compares them in the limit's scale:

* ``add``: the value itself (bounds and array elements, change rates, window means,
  interval times);
* ``log``: the logarithm (variance: a tolerance is a factor, so a frozen sensor, whose
  variance falls to zero, still breaks a lower bound however wide);
* ``count``: whole counts of ``quantum`` (messages per window for a frequency, events for an
  ordered pair): the units' counts are rounded values, whose spread the prediction bound
  corrects for their rounding (:mod:`.tolerance`); a widened count limit moves by whole
  counts, at least one, since a window's phase alone can move one message in or out of it.

Polygons are limits too: the hull's half-planes ``a_k . (x, y) <= b_k``, whose support in
a unit is the largest ``a_k . v`` over the vertices of that unit's own hull (the unit's
points reach no further along ``a_k``); widening offsets each half-plane.

Sets (one-of values, strings, the nodes of architecture invariants) cannot widen: a unit
breaks them when it holds a value the others never had (or lacks a node all the others
had). Other families (relations, orderings, non-zero, patterns) hold exactly on every run
they were inferred from and are left as they are.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any, Literal

import numpy as np

from imrosc.runtime.families import (
    ARCHITECTURE,
    ARRAY,
    BOUNDS,
    FREQUENCY,
    INTERVAL,
    MEAN,
    ONE_OF,
    POLYGON,
    RATE,
    STEP,
    STRING_ONE_OF,
    VARIANCE,
)

Scale = Literal["add", "log", "count"]

WIDENED = frozenset({BOUNDS, ARRAY, RATE, MEAN, STEP, VARIANCE, FREQUENCY, INTERVAL, POLYGON})
ADDITIVE = frozenset({BOUNDS, ARRAY, RATE, MEAN, STEP})
"""Ranges widened in the value's own scale."""
"""Families whose limits calibration widens."""
MARGINED = frozenset({BOUNDS, ARRAY, RATE, MEAN, STEP, VARIANCE})
"""Ranges of one scalar whose limits get a margin (``params.margin``): how far beyond the
centre of the units' extremes a violation is severe (``docs/calibration.md``)."""
SETS = frozenset({ONE_OF, STRING_ONE_OF, ARCHITECTURE})
"""Families calibration keeps or drops whole."""


@dataclass(frozen=True)
class Slot:
    """One limit of an invariant: which parameter, at which index, upper or lower."""

    param: str
    """``max``, ``min``, ``max_time``, ``min_time``, ``max_events``, ``min_events``, ``b``."""
    index: int | str | None
    upper: bool
    scale: Scale
    quantum: float = 1.0


def slots(invariant: Mapping[str, Any]) -> list[Slot]:
    """The limits of an invariant of a widened family (none for other families)."""
    family, params = invariant["family"], invariant["params"]
    if family in ADDITIVE:
        return [Slot(p, None, p == "max", "add") for p in ("min", "max") if p in params]
    if family == VARIANCE:
        return [Slot(p, None, p == "max", "log") for p in ("min", "max") if p in params]
    if family == FREQUENCY:
        quantum = 1.0 / float(params.get("window", 1.0))
        return [Slot(p, None, p == "max", "count", quantum) for p in ("min", "max")]
    if family == INTERVAL:
        found = [Slot("min_time", None, False, "add"), Slot("max_time", None, True, "add")]
        found += [Slot("min_events", e, False, "count") for e in params.get("min_events", {})]
        found += [Slot("max_events", e, True, "count") for e in params.get("max_events", {})]
        return found
    if family == POLYGON:
        return [Slot("b", k, True, "add") for k in range(len(params.get("b", ())))]
    return []


def raw(params: Mapping[str, Any], slot: Slot) -> float | None:
    """The slot's value in ``params`` as a number (``None`` if absent or not finite)."""
    value = params.get(slot.param)
    if slot.index is not None:
        if type(value) is list and type(slot.index) is int:  # the common case, quickly
            value = value[slot.index] if slot.index < len(value) else None
        elif isinstance(value, Mapping):
            value = value.get(str(slot.index), 0 if slot.param == "min_events" else None)
        elif isinstance(value, Sequence) and isinstance(slot.index, int):
            value = value[slot.index] if slot.index < len(value) else None
        else:
            value = None
    return number(value)


def number(value: Any) -> float | None:
    """``value`` as a finite float (``None``: not a number, or not finite)."""
    try:
        found = float(value)
    except (TypeError, ValueError):
        return None
    return found if math.isfinite(found) else None


def to_scale(value: float | None, slot: Slot) -> float | None:
    """A raw value in the slot's comparison space, where larger is always further out."""
    if value is None:
        return None
    if slot.scale == "log":
        if value <= 0:
            return None if slot.upper else math.inf  # a zero lower limit: nothing below
        value = math.log(value)
    return value if slot.upper else -value


def from_scale(value: float, slot: Slot) -> float:
    """The inverse of :func:`to_scale`."""
    value = value if slot.upper else -value
    return math.exp(value) if slot.scale == "log" else value


def support(merged: Mapping[str, Any], unit: Mapping[str, Any] | None, slot: Slot) -> float | None:
    """How far a unit's own invariant (``unit``: its params, or ``None``) reaches along the
    slot, in the slot's space; ``None`` when the unit says nothing about it."""
    if unit is None:
        return None
    if slot.param == "b":
        if not isinstance(slot.index, int):
            return None
        found = polygon_supports([merged["A"][slot.index]], unit)
        return None if found is None else found[0]
    return to_scale(raw(unit, slot), slot)


def polygon_supports(
    normals: Sequence[Sequence[float]], unit: Mapping[str, Any] | None
) -> list[float] | None:
    """How far a unit's polygon (``unit``: its params, or ``None``) reaches along each of
    ``normals``: the largest ``a_k . v`` over its vertices ``v`` (``None``: no vertices).

    The unit's vertices are converted once and multiplied by every normal in one call:
    ``np.matmul`` broadcasts the ``(n, 2)`` vertices over a stack of ``(2, 1)`` normals, one
    matrix-vector product per normal, the same BLAS call (so the same bits, whatever fused
    multiply-adds the machine's BLAS uses) as ``vertices @ normal`` for each normal alone. A
    matrix-matrix product ``vertices @ A.T`` would round differently.
    """
    if unit is None:
        return None
    vertices = np.asarray(unit.get("vertices") or [], dtype=np.float64).reshape(-1, 2)
    if not len(vertices):
        return None
    stack = np.asarray(normals, dtype=np.float64).reshape(-1, 2, 1)
    found: list[float] = np.matmul(vertices, stack).max(axis=1)[:, 0].tolist()
    return found


def widened(base: float, tolerance: float, slot: Slot) -> float:
    """The raw value of a limit whose base (in the slot's space) moves out by
    ``tolerance``; count limits move by whole quanta, at least one."""
    if slot.scale == "count":
        steps = math.ceil(tolerance / slot.quantum - 1e-9) + 1
        tolerance = max(0, steps) * slot.quantum
    value = from_scale(base + tolerance, slot)
    if slot.scale == "count" and not slot.upper:
        value = max(0.0, value)
    return value


def with_value(params: dict[str, Any], slot: Slot, value: float) -> None:
    """Write a limit's raw value into ``params`` (in place)."""
    if slot.index is None:
        params[slot.param] = value
    elif isinstance(slot.index, str):
        counts = dict(params.get(slot.param) or {})
        counts[slot.index] = round(value)
        params[slot.param] = counts
    else:
        values = list(params[slot.param])
        values[slot.index] = value
        params[slot.param] = values


def members(invariant: Mapping[str, Any]) -> frozenset[Any] | None:
    """The set an invariant of a set family holds (values or nodes)."""
    params = invariant["params"]
    found = params.get("values", params.get("nodes"))
    return None if found is None else frozenset(_hashable(v) for v in found)


def _hashable(value: Any) -> Any:
    return tuple(value) if isinstance(value, list) else value


def set_broken(invariant: Mapping[str, Any], unit: frozenset[Any], others: frozenset[Any]) -> bool:
    """Whether a unit breaks a set learnt from the others: a new value or node for a
    ``one-of``, ``string-one-of`` or ``max_*`` set, a missing node for a ``min_*`` set."""
    if invariant["family"] == ARCHITECTURE and invariant["kind"].startswith("min_"):
        return bool(others - unit)
    return bool(unit - others)


def merge_sets(invariant: Mapping[str, Any], sets: Sequence[frozenset[Any]]) -> frozenset[Any]:
    """The set learnt from several units: the union, or for ``min_*`` the intersection."""
    if not sets:
        return frozenset()
    if invariant["family"] == ARCHITECTURE and invariant["kind"].startswith("min_"):
        return frozenset.intersection(*sets)
    return frozenset.union(*sets)
