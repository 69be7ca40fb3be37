"""``imrosc show``: an invariants file as a Daikon-like listing, grouped by program point.

>>> doc = {"points": {"a": {"kind": "publish", "trigger": "/x", "condition": None,
...                         "support": {"samples": 9, "runs": 1}}},
...        "invariants": [{"point": "a", "family": "bounds", "text": "x.data >= 1"}]}
>>> print(render(doc), end="")
===========================================================================
a:::POINT  publish /x  (9 samples, 1 run)
x.data >= 1

A polygon lists every vertex (its ``text`` in the file lists the first few of a large one):

>>> doc["invariants"] = [{"point": "a", "family": "polygon", "text": "...",
...     "params": {"x": "x.u", "y": "x.v", "vertices": [[0, 0], [1, 0], [0, 1.5]]}}]
>>> print(render(doc), end="")
===========================================================================
a:::POINT  publish /x  (9 samples, 1 run)
(x.u, x.v) inside [(0, 0), (1, 0), (0, 1.5)] (3 vertices)
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

from imrosc.infer.polygon.text import polygon_text

RULE = "=" * 75


def render(
    doc: Mapping[str, Any],
    *,
    families: Sequence[str] = (),
    points: Sequence[str] = (),
    ids: bool = False,
) -> str:
    """The listing, filtered to ``families`` and ``points`` when given."""
    by_point: dict[str, list[Mapping[str, Any]]] = {}
    for invariant in doc["invariants"]:
        if families and invariant["family"] not in families:
            continue
        if (
            points
            and invariant["point"] not in points
            and invariant["point"].split("?")[0] not in points
        ):
            continue
        by_point.setdefault(invariant["point"], []).append(invariant)
    lines: list[str] = []
    for key in sorted(by_point):
        info = doc["points"].get(key, {})
        support = info.get("support", {})
        runs = support.get("runs", 0)
        header = f"{key}:::POINT  {info.get('kind', '?')} {info.get('trigger', '')}".rstrip()
        if info.get("condition"):
            header += f"  when {info['condition']}"
        header += f"  ({support.get('samples', 0)} samples, {runs} run{'s' * (runs != 1)})"
        lines += [RULE, header]
        for invariant in by_point[key]:
            prefix = f"[{invariant['id']}] " if ids and "id" in invariant else ""
            lines.append(prefix + text(invariant))
    return "\n".join(lines) + ("\n" if lines else "")


def text(invariant: Mapping[str, Any]) -> str:
    """How the listing shows an invariant: its ``text``, but a polygon with every vertex."""
    params = invariant.get("params") or {}
    if invariant["family"] == "polygon" and {"x", "y", "vertices"} <= params.keys():
        return polygon_text(params["x"], params["y"], params["vertices"], whole=True)
    return str(invariant["text"])
