"""Polygon invariants (thesis 3.4.2): the convex hull of every pair of numeric variables.

``make_states(variables, tunables, families)`` builds the point's :class:`PolygonState`;
its invariants are half-planes ``A @ (x, y) <= b`` (params ``x``, ``y``, ``vertices``,
``A``, ``b``, ``area``, ``box_area``, ``ratio``) kept by Algorithm 10's area ratio, and
they read as their vertices (:func:`polygon_text`).
"""

from __future__ import annotations

from imrosc.infer.polygon.hull import GroupSet, hulls
from imrosc.infer.polygon.predicates import orientation
from imrosc.infer.polygon.state import (
    THIN_RATIO,
    PolygonState,
    half_planes,
    make_states,
    polygon_variables,
)
from imrosc.infer.polygon.text import polygon_text

__all__ = [
    "THIN_RATIO",
    "GroupSet",
    "PolygonState",
    "half_planes",
    "hulls",
    "make_states",
    "orientation",
    "polygon_text",
    "polygon_variables",
]
