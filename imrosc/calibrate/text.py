"""The readable text of an invariant whose limits calibration moved, in its family's form."""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

from imrosc.infer.daikon.common import number_text
from imrosc.infer.polygon.text import polygon_text
from imrosc.infer.temporal.interval import format_multiset
from imrosc.infer.timed.families import format_bound
from imrosc.runtime.families import (
    ARRAY,
    BOUNDS,
    FREQUENCY,
    INTERVAL,
    MEAN,
    POLYGON,
    RATE,
    STEP,
    VARIANCE,
)

_RANGES = frozenset({BOUNDS, ARRAY, RATE, MEAN, STEP, VARIANCE, FREQUENCY})


def subject(text: str) -> str:
    """What a range's text bounds: ``x`` of ``1 <= x <= 2``, ``x == 3``, ``x >= 1``.

    >>> [subject(t) for t in ("1 <= freq(/a) <= 2", "x == 3", "len(y) >= 1", "z <= 4")]
    ['freq(/a)', 'x', 'len(y)', 'z']
    """
    parts = text.split(" <= ")
    if len(parts) == 3:
        return parts[1]
    for sign in (" == ", " >= ", " <= "):
        if sign in text:
            return text.rsplit(sign, 1)[0]
    return text


def retext(invariant: dict[str, Any], types: Mapping[tuple[str, str], str]) -> None:
    """Rewrite ``invariant["text"]`` from its (moved) params, in place."""
    family, params = invariant["family"], invariant["params"]
    if family in _RANGES:
        shown = subject(invariant["text"])
        kind = "float"
        if family == BOUNDS and invariant["variables"]:
            kind = types.get((invariant["point"], invariant["variables"][0]), "float")

        def number(value: float) -> str:
            return number_text(value, kind) if family in (BOUNDS, ARRAY) else format_bound(value)

        low, high = params.get("min"), params.get("max")
        if low is not None and high is not None:
            invariant["text"] = f"{number(low)} <= {shown} <= {number(high)}"
        elif low is not None:
            invariant["text"] = f"{shown} >= {number(low)}"
        elif high is not None:
            invariant["text"] = f"{shown} <= {number(high)}"
    elif family == POLYGON:
        invariant["text"] = polygon_text(params["x"], params["y"], params["vertices"])
    elif family == INTERVAL:
        invariant["text"] = (
            f"{params['first']} -> {params['second']}: "
            f"[{params['min_time']!r}, {params['max_time']!r}] s, "
            f"min {format_multiset(dict(params['min_events']))}, "
            f"max {format_multiset(dict(params['max_events']))}"
        )
