"""Sheared frames (``edge_frames``, ``frame_orientation``) and the guide's sectors facing one
edge: samples of exact relations with simple slopes (``q = -p``, ``b = 2*a + 3``, ``ab =
|n|``, ``s = ab + 5`` rounded, ``t = a - 4 + 1``) lie on their hull's edges or within a
rounding of them; wherever the frame decides, its sign is the exact one, and the guide
discards only samples in the closed hull that are none of its vertices."""

from __future__ import annotations

import numpy as np
import pytest

from imrosc.infer.core import FloatArray
from imrosc.infer.polygon.guide import Guide
from imrosc.infer.polygon.hull import GroupSet, hulls
from imrosc.infer.polygon.predicates import edge_frames, frame_orientation
from tests.infer.polygon.reference import covered, turn


def _relation(kind: int, rng: np.random.Generator, n: int) -> tuple[FloatArray, FloatArray]:
    if kind == 0:  # exactly on a line of a simple slope
        slope = float(rng.choice([1.0, -1.0, 2.0, 0.5, -0.25, 4.0, 0.0]))
        shift = float(rng.choice([0.0, 3.0, 5.0, 0.1, -7.3]))
        xs = rng.uniform(-10, 10, n) * float(rng.choice([1.0, 1e-5, 1e5]))
        return xs, xs * slope + shift
    if kind == 1:
        xs = np.abs(rng.normal(size=n))
        return xs, xs + 5
    if kind == 2:
        xs = rng.uniform(-10, 10, n)
        return xs, xs - 4.0 + 1.0
    if kind == 3:
        xs = rng.normal(size=n)
        return (xs, 2 * xs + 3) if rng.random() < 0.5 else (2 * xs + 3, xs)
    if kind == 4:  # a slope of no simple form: the frame decides little, but right
        xs = rng.uniform(-1, 1, n)
        return xs, 0.1 * xs + 0.7
    value = rng.integers(-3, 4, (2, n)).astype(float)
    return value[0], value[1]


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_frame_orientation_is_exact_where_it_decides(seed: int) -> None:
    rng = np.random.default_rng(seed)
    decided_on_lines = 0
    on_lines = 0
    for trial in range(120):
        kind = trial % 6
        xs, ys = _relation(kind, rng, 300)
        i, j, k = rng.integers(0, 300, (3, 60))
        ax, ay, bx, by = xs[i], ys[i], xs[j], ys[j]
        px, py = xs[k], ys[k]
        if trial % 2:  # a rounding off the relation
            py = np.nextafter(py, float(rng.choice([-np.inf, np.inf])))
        frames = edge_frames(ax, ay, bx, by)
        sign, decided = frame_orientation(frames, px, py)
        assert not (decided & (frames[0] == 0)).any()
        for t in np.flatnonzero(decided).tolist():
            expected = turn((ax[t], ay[t]), (bx[t], by[t]), (px[t], py[t]))
            assert sign[t] == expected
        if kind in (0, 2, 3) and not trial % 2:
            on_lines += int((frames[0] > 0).sum())
            decided_on_lines += int((decided & (frames[0] > 0)).sum())
    assert decided_on_lines > 0.95 * on_lines  # exact relations are decided, not deferred


def test_nan_and_out_of_range_points_are_undecided() -> None:
    frames = edge_frames(
        np.array([0.0, 0.0]), np.array([0.0, 0.0]), np.array([1.0, 1.0]), np.array([1.0, 1.0])
    )
    sign, decided = frame_orientation(frames, np.array([np.nan, 1e300]), np.array([0.5, 1e300]))
    assert not decided.any() and not sign.any()


@pytest.mark.parametrize("seed", [0, 1])
def test_the_guide_discards_only_non_vertices_of_the_closed_hull(seed: int) -> None:
    rng = np.random.default_rng(seed)
    n = rng.normal(size=3000)
    a = rng.uniform(-10, 10, 3000)
    m = rng.choice(np.array([-1.0, 0.0, 2.0]), 3000)
    groups = [
        (n, np.abs(n)),
        (n, np.abs(n) + 5),
        (a, a - 2 * m + 1),
        (2 * a + 3, a - 2 * m + 1),
        (np.maximum(n, a / 10), n),
        (rng.integers(0, 100, 3000).astype(float), a),
    ]
    first = 1000  # the hull of the first rows guides; the others are tested against it
    pts = GroupSet(
        np.repeat(np.arange(len(groups)), first),
        np.concatenate([x[:first] for x, _ in groups]),
        np.concatenate([y[:first] for _, y in groups]),
        np.tile(np.arange(first), len(groups)),
    )
    hull = hulls(pts)
    guide = Guide(len(groups))
    guide.refresh(hull, np.arange(len(groups)))
    assert guide.ok.all()
    pair = np.repeat(np.arange(len(groups)), 3000 - first)
    x = np.concatenate([gx[first:] for gx, _ in groups])
    y = np.concatenate([gy[first:] for _, gy in groups])
    found = guide.inside(pair, x, y)
    vertices: dict[int, list[tuple[float, float]]] = {}
    for g, vx, vy in zip(hull.group.tolist(), hull.x.tolist(), hull.y.tolist(), strict=True):
        vertices.setdefault(g, []).append((vx, vy))
    for k in np.flatnonzero(found).tolist():
        assert covered(vertices[int(pair[k])], (float(x[k]), float(y[k])))
    # the edges of exact relations are full of samples the frames discard
    assert found.mean() > 0.9
