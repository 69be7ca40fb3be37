"""A polygon's text: its variables, its vertices as short as they read back, their count."""

from __future__ import annotations

import re

import numpy as np
from hypothesis import given
from hypothesis import strategies as st

from imrosc.infer.polygon.text import HEAD, LISTED, polygon_text, vertex_text

VERTEX = re.compile(r"\(([^(),]+), ([^(),]+)\)")


def ring(count: int) -> list[list[float]]:
    """``count`` vertices on a circle, counter-clockwise."""
    angle = np.linspace(0, 2 * np.pi, count, endpoint=False)
    return [[float(np.cos(a)), float(np.sin(a))] for a in angle]


def test_a_small_polygon_lists_every_vertex() -> None:
    square = [[0.0, 0.0], [2.0, 0.0], [2.0, 1.0], [0.0, 1.0]]
    assert polygon_text("UAV.y", "iRobot.y", square) == (
        "(UAV.y, iRobot.y) inside [(0, 0), (2, 0), (2, 1), (0, 1)] (4 vertices)"
    )


def test_coordinates_are_as_short_as_read_back_exactly() -> None:
    assert vertex_text([-0.30400615, 15.0]) == "(-0.30400615, 15)"
    assert vertex_text([0.1 + 0.2, -0.0]) == "(0.30000000000000004, 0)"
    assert vertex_text([1e-300, 2.0**53]) == "(1e-300, 9007199254740992.0)"
    assert vertex_text([np.float64(5e5), np.float32(0.5)]) == "(500000, 0.5)"


def test_a_large_polygon_lists_its_first_vertices_and_its_count() -> None:
    vertices = ring(60)
    text = polygon_text("a", "b", vertices)
    assert text.startswith("(a, b) inside [(1, 0), ")
    assert text.endswith(", ...] (60 vertices)")
    assert len(VERTEX.findall(text)) == HEAD + 1  # the variables read like a vertex too
    assert "∩" not in text


def test_whole_lists_every_vertex() -> None:
    vertices = ring(60)
    text = polygon_text("a", "b", vertices, whole=True)
    assert "..." not in text and text.endswith("] (60 vertices)")
    assert len(VERTEX.findall(text)) == 61


def test_the_cut_is_past_the_listed_limit() -> None:
    assert "..." not in polygon_text("a", "b", ring(LISTED))
    assert "..." in polygon_text("a", "b", ring(LISTED + 1))


finite = st.floats(allow_nan=False, allow_infinity=False)


@given(st.lists(st.tuples(finite, finite), min_size=3, max_size=LISTED))
def test_the_vertices_read_back_exactly(points: list[tuple[float, float]]) -> None:
    text = polygon_text("x.a", "y.b", [list(p) for p in points])
    read = [(float(a), float(b)) for a, b in VERTEX.findall(text)[1:]]
    assert read == [(x + 0.0, y + 0.0) for x, y in points]  # -0.0 reads as 0
