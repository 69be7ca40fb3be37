"""How a polygon invariant reads: its variables, its vertices and how many there are.

A polygon is the point ``(x, y)`` inside the hull of its vertices (counter-clockwise from
the lexicographic minimum), each coordinate as :func:`number_text` prints invariants'
values (the shortest text that reads back as the same float64, integers without a point):

>>> polygon_text("a", "b", [[0.0, 0.0], [2.0, 0.0], [0.5, 1.25]])
'(a, b) inside [(0, 0), (2, 0), (0.5, 1.25)] (3 vertices)'

The invariant's ``text`` is one line: a polygon of more than :data:`LISTED` vertices lists
its first :data:`HEAD` and ``...``; ``whole=True`` lists them all (``imrosc show``):

>>> octagon = [[0, 1], [1, 0], [2, 0], [3, 1], [3, 2], [2, 3], [1, 3], [0, 2]]
>>> polygon_text("a", "b", octagon)
'(a, b) inside [(0, 1), (1, 0), (2, 0), (3, 1), ...] (8 vertices)'
>>> polygon_text("a", "b", octagon, whole=True).endswith("(1, 3), (0, 2)] (8 vertices)")
True
"""

from __future__ import annotations

from collections.abc import Sequence

from imrosc.infer.daikon.common import number_text

LISTED = 6
"""A polygon of at most this many vertices is listed whole in its one-line text."""
HEAD = 4
"""The vertices a larger polygon's one-line text lists before ``...``."""


def vertex_text(vertex: Sequence[float]) -> str:
    """``(x, y)``, each coordinate as short as reads back exactly.

    >>> vertex_text([-0.30400615, 1e-300])
    '(-0.30400615, 1e-300)'
    """
    x, y = vertex
    return f"({number_text(float(x))}, {number_text(float(y))})"


def polygon_text(
    x: str, y: str, vertices: Sequence[Sequence[float]], *, whole: bool = False
) -> str:
    """``(x, y) inside [(x1, y1), ...] (N vertices)``: every vertex when ``whole`` or
    when there are at most :data:`LISTED`, else the first :data:`HEAD` and ``...``."""
    shown = vertices if whole or len(vertices) <= LISTED else vertices[:HEAD]
    listed = [vertex_text(v) for v in shown]
    if len(shown) < len(vertices):
        listed.append("...")
    return f"({x}, {y}) inside [{', '.join(listed)}] ({len(vertices)} vertices)"
