"""``imrosc show``'s listing: each invariant's text, a polygon with every vertex."""

from __future__ import annotations

from typing import Any

import numpy as np

from imrosc.infer.polygon.text import polygon_text
from imrosc.show import alarm_lines, render, text


def polygon(vertices: list[list[float]]) -> dict[str, Any]:
    return {
        "point": "a",
        "family": "polygon",
        "text": polygon_text("u.x", "u.y", vertices),
        "params": {"x": "u.x", "y": "u.y", "vertices": vertices},
    }


def test_a_large_polygon_is_listed_whole() -> None:
    angle = np.linspace(0, 2 * np.pi, 40, endpoint=False)
    vertices = np.stack([np.cos(angle) * 3, np.sin(angle) + 10], axis=1).tolist()
    invariant = polygon(vertices)
    assert invariant["text"].endswith(", ...] (40 vertices)")
    assert text(invariant) == polygon_text("u.x", "u.y", vertices, whole=True)
    doc = {"points": {}, "invariants": [invariant, {**invariant, "id": "i1"}]}
    lines = render(doc, ids=True).splitlines()
    assert lines[2:] == [text(invariant), "[i1] " + text(invariant)]


def test_other_invariants_and_polygons_without_vertices_show_their_text() -> None:
    bounds = {"point": "a", "family": "bounds", "text": "0 <= u.x <= 1"}
    bare = {"point": "a", "family": "polygon", "text": "u.x + u.y <= 1 ∩ ...", "params": {}}
    assert (text(bounds), text(bare)) == ("0 <= u.x <= 1", "u.x + u.y <= 1 ∩ ...")


def test_the_alarm_line_names_the_families_with_severe_alarms() -> None:
    rule = {"persist": 12, "seconds": None, "distinct": 0, "window": 1.0}
    (line,) = alarm_lines({"alarms": rule})
    assert "at once" not in line
    severe = {**rule, "severe": 1.0, "severe_families": ["step", "variance"]}
    (line,) = alarm_lines({"alarms": severe})
    assert line.endswith("or at once beyond 1 margin (step, variance)")
    (line,) = alarm_lines({"alarms": {**severe, "severe": 0.0}})  # alarm_severe="0": off
    assert "at once" not in line
