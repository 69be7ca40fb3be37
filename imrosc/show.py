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

A calibrated file says first when its violations raise an alarm:

>>> doc["alarms"] = {"persist": 12, "seconds": None, "distinct": 4, "window": 1.0}
>>> doc["calibration"] = {"budget": 0.05, "units": "runs", "count": 8, "certified": False}
>>> line = render(doc).splitlines()[0]
>>> line.startswith("alarms: 12 consecutive violating samples of one invariant, or 4 invariants")
True
>>> line.endswith("within 1 s (calibrated on 8 runs, budget 0.05 per run, not certified)")
True
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

from imrosc.infer.polygon.text import polygon_text
from imrosc.runtime.families import NAMES, POLYGON

RULE = "=" * 75


def render(
    doc: Mapping[str, Any],
    *,
    families: Sequence[str] = (),
    points: Sequence[str] = (),
    ids: bool = False,
) -> str:
    """The listing, filtered to ``families`` and ``points`` when given (the file's alarm
    rule first when not)."""
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
    lines: list[str] = [] if families or points else alarm_lines(doc)
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


def unknown_filter(
    doc: Mapping[str, Any], *, families: Sequence[str] = (), points: Sequence[str] = ()
) -> str | None:
    """What is wrong with the filters asked for, or None: a family imrosc does not know, or a
    point the file has not (a point's key, or the key of the point a conditional one
    refines: ``a`` shows ``a?1`` too). A filter that matches nothing would print nothing.

    >>> doc = {"points": {"a": {}, "a?1": {}, "b": {}}}
    >>> unknown_filter(doc, families=["bounds"], points=["a", "a?1"]) is None
    True
    >>> unknown_filter(doc, families=["boundz"])[:50]
    "unknown family 'boundz' (families: bounds, one-of,"
    >>> unknown_filter(doc, points=["c"])
    "no point 'c' in the file (points: a, b)"
    """
    for family in families:
        if family not in NAMES:
            return f"unknown family {family!r} (families: {', '.join(NAMES)})"
    keys = set(doc["points"])
    bases = {key.split("?")[0] for key in keys}
    for point in points:
        if point not in keys and point not in bases:
            return f"no point {point!r} in the file (points: {', '.join(sorted(bases))})"
    return None


def alarm_lines(doc: Mapping[str, Any]) -> list[str]:
    """The file's alarm rule and how it was calibrated, in one line (none without a rule)."""
    rule = doc.get("alarms")
    if not rule:
        return []
    parts = [f"{rule.get('persist', 1)} consecutive violating samples of one invariant"]
    if rule.get("seconds") is not None:
        parts.append(f"{rule['seconds']:g} s of them")
    if rule.get("distinct"):
        parts.append(
            f"{rule['distinct']} invariants of a point within {float(rule.get('window', 1.0)):g} s"
        )
    families = rule.get("severe_families") or ()
    if families and rule.get("severe"):
        parts.append(
            f"at once beyond {float(rule['severe']):g} margin"
            f"{'s' * (float(rule['severe']) != 1)} ({', '.join(families)})"
        )
    line = "alarms: " + ", or ".join(parts)
    calibration = doc.get("calibration")
    if calibration:
        certified = "certified" if calibration.get("certified") else "not certified"
        line += (
            f" (calibrated on {calibration.get('count')} {calibration.get('units')}, budget "
            f"{calibration.get('budget')} per run, {certified})"
        )
    return [line]


def text(invariant: Mapping[str, Any]) -> str:
    """How the listing shows an invariant: its ``text``, but a polygon with every vertex."""
    params = invariant.get("params") or {}
    if invariant["family"] == POLYGON and {"x", "y", "vertices"} <= params.keys():
        return polygon_text(params["x"], params["y"], params["vertices"], whole=True)
    return str(invariant["text"])
