"""What the engine reports when an invariant breaks."""

from __future__ import annotations

import math
from typing import Any, Dict, NamedTuple


class Violation(NamedTuple):
    """One broken invariant at one moment.

    ``observed`` is what was seen (a number, a set of node names, an event sequence);
    ``expected`` the bound it broke, as text.
    """

    time: float
    point: str
    invariant: str
    family: str
    kind: str
    text: str
    observed: Any
    expected: str

    def as_json(self) -> Dict[str, Any]:
        """A JSON-safe dict (non-finite numbers as strings)."""
        return {
            "time": self.time,
            "point": self.point,
            "invariant": self.invariant,
            "family": self.family,
            "kind": self.kind,
            "text": self.text,
            "observed": json_safe(self.observed),
            "expected": self.expected,
        }


def json_safe(value: Any) -> Any:
    """``value`` with NaN/inf as strings, tuples and sets as (sorted) lists."""
    if isinstance(value, float):
        return value if math.isfinite(value) else repr(value)
    if isinstance(value, (list, tuple)):
        return [json_safe(v) for v in value]
    if isinstance(value, (set, frozenset)):
        return sorted(json_safe(v) for v in value)
    if isinstance(value, dict):
        return {str(k): json_safe(v) for k, v in value.items()}
    if hasattr(value, "item"):
        return json_safe(value.item())
    return value


def show(value: Any) -> str:
    """A short text of an observed value."""
    if isinstance(value, float):
        return repr(value) if not value.is_integer() or abs(value) >= 1e16 else str(int(value))
    if isinstance(value, (set, frozenset)):
        return "{" + ", ".join(sorted(str(v) for v in value)) + "}"
    if isinstance(value, (list, tuple)):
        return "(" + ", ".join(show(v) for v in value) + ")"
    return str(value)
