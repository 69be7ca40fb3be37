"""Exact point location (``Locator.covered``) against exact rational arithmetic: a sample is
covered when it lies in its group's closed hull and is none of the hull's vertices; hulls
of exactly collinear points (segments), of few integers and of scattered floats alike."""

from __future__ import annotations

from itertools import pairwise

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from imrosc.infer.polygon.hull import GroupSet, hulls
from imrosc.infer.polygon.locate import Locator
from tests.infer.polygon.reference import covered


@st.composite
def _group(draw: st.DrawFn) -> list[tuple[float, float]]:
    shape = draw(st.sampled_from(["segment", "integers", "floats"]))
    count = draw(st.integers(1, 12))
    if shape == "segment":  # y = s*x + c, rounded: on the line or within a rounding of it
        slope = draw(st.sampled_from([-1.0, 2.0, 0.5, 3.0, 0.0]))
        shift = draw(st.sampled_from([0.0, 3.0, 0.1]))
        xs = draw(st.lists(st.floats(-10, 10), min_size=count, max_size=count))
        return [(x, slope * x + shift) for x in xs]
    if shape == "integers":
        value = st.integers(-3, 3).map(float)
        return draw(st.lists(st.tuples(value, value), min_size=count, max_size=count))
    value = st.floats(-10, 10)
    return draw(st.lists(st.tuples(value, value), min_size=count, max_size=count))


@settings(max_examples=80, deadline=None)
@given(st.lists(_group(), min_size=1, max_size=4), st.data())
def test_covered_is_the_closed_hull_less_its_vertices(
    groups: list[list[tuple[float, float]]], data: st.DataObject
) -> None:
    points = [(g, x, y) for g, group in enumerate(groups) for x, y in group]
    group = np.asarray([p[0] for p in points], dtype=np.int64)
    xs = np.asarray([p[1] for p in points])
    ys = np.asarray([p[2] for p in points])
    hull = hulls(GroupSet(group, xs, ys, np.arange(len(points), dtype=np.int64)))
    vertices: dict[int, list[tuple[float, float]]] = {}
    for g, x, y in zip(hull.group.tolist(), hull.x.tolist(), hull.y.tolist(), strict=True):
        vertices.setdefault(g, []).append((x, y))
    locator = Locator.build(hull, len(groups))
    # the groups' own points, the midpoints of pairs of them, and a few others
    queries = [(g, x, y) for g, x, y in points]
    for g, group_points in enumerate(groups):
        for (x1, y1), (x2, y2) in pairwise(group_points):
            queries.append((g, (x1 + x2) / 2, (y1 + y2) / 2))
    other = st.tuples(st.integers(0, len(groups) - 1), st.floats(-11, 11), st.floats(-11, 30))
    queries += data.draw(st.lists(other, max_size=10))
    pair = np.asarray([q[0] for q in queries], dtype=np.int64)
    qx = np.asarray([q[1] for q in queries])
    qy = np.asarray([q[2] for q in queries])
    found = locator.covered(pair, qx, qy).tolist()
    expected = [covered(vertices.get(g, []), (x, y)) for g, x, y in queries]
    assert found == expected


def test_many_samples_per_hull_locate_as_few_do() -> None:
    """Samples sorted by group, many per hull (each chain's edges found by one search per
    chain): the same answers as the same samples in shuffled order (a binary search across
    all chains), and as rational arithmetic on edges full of samples (``ab = |n|``, a
    rounded line ``b = 2*a + 3``) and inside scattered hulls."""
    rng = np.random.default_rng(4)
    n = rng.normal(0, 1, 400)
    a = rng.uniform(-10, 10, 400)
    u, v = rng.uniform(-10, 10, (2, 400))
    groups = [(n, np.abs(n)), (a, 2 * a + 3), (u, v)]
    points = [(g, x, y) for g, (xs, ys) in enumerate(groups) for x, y in zip(xs, ys, strict=True)]
    group = np.asarray([p[0] for p in points], dtype=np.int64)
    xs = np.asarray([p[1] for p in points])
    ys = np.asarray([p[2] for p in points])
    hull = hulls(GroupSet(group, xs, ys, np.arange(len(points), dtype=np.int64)))
    locator = Locator.build(hull, len(groups))
    vertices: dict[int, list[tuple[float, float]]] = {}
    for g, x, y in zip(hull.group.tolist(), hull.x.tolist(), hull.y.tolist(), strict=True):
        vertices.setdefault(g, []).append((x, y))
    in_order = locator.covered(group, xs, ys)
    shuffled = rng.permutation(len(points))
    assert locator.covered(group[shuffled], xs[shuffled], ys[shuffled]).tolist() == (
        in_order[shuffled].tolist()
    )
    expected = [covered(vertices[g], (x, y)) for g, x, y in points]
    assert in_order.tolist() == expected
    assert sum(expected[:400]) > 390  # the V's samples lie on its edges


@settings(max_examples=30, deadline=None)
@given(
    st.sampled_from([2.0, 1.0, -0.5, 0.0, 3.0]),
    st.sampled_from([3.0, 5.0, 0.1, 0.0]),
    st.integers(0, 2**32 - 1),
)
def test_a_band_holds_only_points_strictly_inside_and_spares_most_of_a_line(
    slope: float, shift: float, seed: int
) -> None:
    """Samples of a line ``y = slope*x + shift`` (exact or rounded): whatever a hull's band
    takes is in the closed hull and none of its vertices (exact rationals), and the band
    takes most later samples of an exact line."""
    rng = np.random.default_rng(seed)
    xs = rng.uniform(-10, 10, 300)
    ys = slope * xs + shift
    hull = hulls(GroupSet(np.zeros(300, np.int64), xs, ys, np.arange(300, dtype=np.int64)))
    vertices = list(zip(hull.x.tolist(), hull.y.tolist(), strict=True))
    locator = Locator.build(hull, 1)
    qx = np.concatenate([rng.uniform(-10, 10, 200), xs])
    qy = np.concatenate([slope * qx[:200] + shift, ys])
    qy[:20] += rng.normal(0, 1e-14, 20)  # a few just off the line
    slot = np.zeros(len(qx), np.int64)
    banded = locator.band.inside(slot, qx, qy)
    assert all(covered(vertices, (x, y)) for x, y in zip(qx[banded], qy[banded], strict=True))
    assert locator.covered(slot, qx, qy).tolist() == [
        covered(vertices, p) for p in zip(qx.tolist(), qy.tolist(), strict=True)
    ]
    if len(vertices) == 2 and slope in (2.0, 1.0, -0.5, 0.0) and shift == 0.0:
        assert banded.sum() > len(qx) // 2  # an exact line: its samples on the open segment
