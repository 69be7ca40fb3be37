"""Slow, obviously exact references: monotone chain and the thesis' Algorithms 5 and 6."""

from __future__ import annotations

from collections.abc import Sequence
from fractions import Fraction

Point = tuple[float, float]
Vertex = tuple[float, float, int]


def cross(o: Point, a: Point, b: Point) -> Fraction:
    """Exact ``(a - o) x (b - o)``."""
    ox, oy = Fraction(o[0]), Fraction(o[1])
    return (Fraction(a[0]) - ox) * (Fraction(b[1]) - oy) - (Fraction(a[1]) - oy) * (
        Fraction(b[0]) - ox
    )


def hull(points: Sequence[Point]) -> list[Point]:
    """Strict hull vertices, counter-clockwise from the lexicographic minimum."""
    pts = sorted(set(points))
    if len(pts) <= 1:
        return pts
    lower: list[Point] = []
    for p in pts:
        while len(lower) >= 2 and cross(lower[-2], lower[-1], p) <= 0:
            lower.pop()
        lower.append(p)
    upper: list[Point] = []
    for p in reversed(pts):
        while len(upper) >= 2 and cross(upper[-2], upper[-1], p) <= 0:
            upper.pop()
        upper.append(p)
    return lower[:-1] + upper[:-1]


def hull_with_first(points: Sequence[Point]) -> list[Vertex]:
    """:func:`hull`, each vertex with the position where that point first occurs."""
    first: dict[Point, int] = {}
    for k, p in enumerate(points):
        first.setdefault(p, k)
    return [(x, y, first[(x, y)]) for x, y in hull(points)]


def contains(polygon: Sequence[Point], p: Point) -> bool:
    """Whether ``p`` is inside or on the convex ``polygon`` (any size)."""
    if not polygon:
        return False
    if len(polygon) == 1:
        return polygon[0] == p
    if len(polygon) == 2:
        a, b = polygon
        return cross(a, b, p) == 0 and min(a, b) <= p <= max(a, b)
    n = len(polygon)
    return all(cross(polygon[k], polygon[(k + 1) % n], p) >= 0 for k in range(n))


def quickhull(points: Sequence[Point]) -> list[Point]:
    """Algorithm 5 (exact arithmetic): the hull as found by divide and conquer."""
    pts = sorted(set(points))
    if len(pts) <= 2:
        return pts
    a, b = pts[0], pts[-1]

    def find(line: tuple[Point, Point], group: list[Point]) -> list[Point]:
        if not group:
            return [line[0]]
        far = max(group, key=lambda p: (cross(line[0], line[1], p), p))
        left = [p for p in group if cross(line[0], far, p) > 0]
        right = [p for p in group if cross(far, line[1], p) > 0]
        return find((line[0], far), left) + find((far, line[1]), right)

    upper = [p for p in pts if cross(a, b, p) > 0]
    lower = [p for p in pts if cross(b, a, p) > 0]
    return hull(find((a, b), upper) + find((b, a), lower))


def algorithm_6(points: Sequence[Point], chunk_size: int) -> list[Point]:
    """Algorithm 6: keep points outside the polygon, re-hull every ``chunk_size`` of them."""
    polygon: list[Point] = []
    pending: list[Point] = []
    for p in points:
        if not contains(polygon, p):
            pending.append(p)
        if len(pending) >= chunk_size:
            polygon = quickhull(pending + polygon)
            pending = []
    return quickhull(pending + polygon)


def turn(a: Point, b: Point, p: Point) -> int:
    """The sign of the turn a -> b -> p, exactly: 1 left, -1 right, 0 on the line."""
    ax, ay, bx, by, px, py = (Fraction(v) for v in (*a, *b, *p))
    det = (ax - px) * (by - py) - (ay - py) * (bx - px)
    return (det > 0) - (det < 0)


def covered(vertices: list[Point], p: Point) -> bool:
    """In the closed hull of ``vertices`` (counter-clockwise), and none of them; hulls of
    one point or a vertical segment cover nothing (the locator has no chain for them)."""
    if len(vertices) < 2 or vertices[0][0] == max(v[0] for v in vertices) or p in vertices:
        return False
    if len(vertices) == 2:
        (lx, _), (rx, _) = vertices
        return turn(vertices[0], vertices[1], p) == 0 and lx <= p[0] <= rx
    pairs = zip(vertices, vertices[1:] + vertices[:1], strict=True)
    return all(turn(a, b, p) >= 0 for a, b in pairs)
