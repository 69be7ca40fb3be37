"""Polygon family: Algorithm 10's drop, containment, degeneracy, exact hulls and merging."""

from __future__ import annotations

import itertools
import pickle
from fractions import Fraction
from typing import Any

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from imrosc.infer.core import FinalizeContext, FloatArray, Invariant, Samples, Variable
from imrosc.infer.polygon import (
    GroupSet,
    PolygonState,
    guide,
    half_planes,
    hulls,
    make_states,
    orientation,
    polygon_text,
    polygon_variables,
)
from imrosc.infer.polygon.locate import Locator
from imrosc.ir import Tunables
from tests.infer.polygon.reference import algorithm_6, contains, hull_with_first
from tests.infer.polygon.support import state_of

U = Variable("UAV.y", "float", topic="/uav", path="pose.y")
R = Variable("iRobot.y", "float", topic="/irobot", path="pose.y", trigger=False)


def frame(columns: dict[str, Any], start: int = 0, stop: int | None = None) -> Samples:
    names = list(columns)
    variables = tuple(Variable(n, "float", topic="/a", path=n) for n in names)
    arrays = {n: np.asarray(columns[n], dtype=np.float64)[start:stop] for n in names}
    rows = len(next(iter(arrays.values())))
    return Samples("p", 0, np.arange(rows, dtype=np.float64), arrays, variables)


def state_for(columns: dict[str, Any], chunk: int | None = None) -> PolygonState:
    names = list(columns)
    variables = tuple(Variable(n, "float", topic="/a", path=n) for n in names)
    state = PolygonState(variables, batch=0)  # each chunk folded as it comes
    rows = len(np.asarray(columns[names[0]]))
    step = chunk or max(rows, 1)
    for first in range(0, rows, step):
        state.update(frame(columns, first, first + step))
    state.end_run()
    return state


def context(**tunables: Any) -> FinalizeContext:
    return FinalizeContext(Tunables(**tunables), (U, R), "p")


def polygons(state: PolygonState, **tunables: Any) -> list[Invariant]:
    return state.finalize(context(**tunables))


def vertices_of(state: PolygonState, pair: int) -> list[tuple[float, float, int]]:
    mine = state.hull.group == pair
    return list(
        zip(
            state.hull.x[mine].tolist(),
            state.hull.y[mine].tolist(),
            state.hull.at[mine].tolist(),
            strict=True,
        )
    )


# --- Algorithm 10 ----------------------------------------------------------------------


def test_independent_uniform_variables_fill_their_box_and_are_dropped() -> None:
    rng = np.random.default_rng(1)
    state = state_for({"a": rng.uniform(-1, 1, 20000), "b": rng.uniform(0, 5, 20000)})
    assert polygons(state) == []
    assert polygons(state, drop_ratio=1.0)[0].params["ratio"] > 0.9


def test_a_disc_and_a_diamond_are_kept() -> None:
    rng = np.random.default_rng(2)
    angle = rng.uniform(0, 2 * np.pi, 5000)
    radius = np.sqrt(rng.uniform(0, 1, 5000))
    u, v = rng.uniform(-1, 1, (2, 5000))
    state = state_for(
        {
            "dx": radius * np.cos(angle),
            "dy": radius * np.sin(angle),
            "rx": u + v,
            "ry": u - v,
        },
        chunk=1500,
    )
    found = {inv.variables: inv for inv in polygons(state)}
    assert found[("dx", "dy")].params["ratio"] == pytest.approx(np.pi / 4, abs=0.02)
    assert found[("rx", "ry")].params["ratio"] == pytest.approx(0.5, abs=0.02)
    assert found[("dx", "dy")].kind == "hull"
    for inv in found.values():
        assert inv.params["area"] == pytest.approx(inv.params["ratio"] * inv.params["box_area"])


def test_the_drop_ratio_is_configurable() -> None:
    rng = np.random.default_rng(3)
    u, v = rng.uniform(-1, 1, (2, 4000))
    state = state_for({"rx": u + v, "ry": u - v})
    assert len(polygons(state, drop_ratio=0.9)) == 1
    assert polygons(state, drop_ratio=0.4) == []


# --- the invariant ---------------------------------------------------------------------


@pytest.mark.parametrize(
    ("offset", "scale"), [(0.0, 1.0), (1e6, 1.0), (-3e9, 1e3), (0.0, 1e-7), (1e6, 1e-3)]
)
def test_the_polygon_contains_every_sample(offset: float, scale: float) -> None:
    rng = np.random.default_rng(4)
    x = rng.normal(0, 1, 6000)
    y = 0.3 * x + rng.normal(0, 0.2, 6000) + np.sin(3 * x)
    xs = offset + scale * x
    ys = -offset / 7 + scale * y
    state = state_for({"x": xs, "y": ys}, chunk=1000)
    (found,) = polygons(state, drop_ratio=1.0)
    normals = np.array(found.params["A"])
    b = np.array(found.params["b"])
    points = np.stack([xs, ys])
    # the margin is inside b: every sample passes the float64 check with no tolerance
    assert np.all(normals @ points <= b[:, None])
    assert np.all(np.einsum("ij,jk->ik", normals, points) <= b[:, None])
    for a_i, b_i, c_i in zip(normals[:, 0], normals[:, 1], b, strict=True):
        assert np.all(a_i * xs + b_i * ys <= c_i)
    # and it is tight: each half-plane is (nearly) touched by a vertex
    verts = np.array(found.params["vertices"])
    slack = b[:, None] - normals @ verts.T
    size = np.abs(normals) @ np.abs(verts).max(axis=0)
    assert np.all(slack.min(axis=1) <= 1e-14 * size)


def test_half_planes_of_a_square() -> None:
    square = np.array([[0.0, 0.0], [2.0, 0.0], [2.0, 1.0], [0.0, 1.0]])
    normals, offsets, tight = half_planes(square)
    assert normals.tolist() == [[0.0, -1.0], [1.0, 0.0], [0.0, 1.0], [-1.0, 0.0]]
    assert tight.tolist() == [0.0, 2.0, 1.0, 0.0]
    assert np.all(offsets > tight) and offsets == pytest.approx(tight, abs=1e-14)


def test_params_and_support() -> None:
    rng = np.random.default_rng(5)
    t = rng.uniform(0, 2 * np.pi, 3000)
    state = state_for({"a": np.cos(t), "b": 2 * np.sin(t) + 0.1 * rng.normal(size=3000)})
    (inv,) = polygons(state)
    assert inv.family == "polygon"
    assert inv.variables == ("a", "b")
    assert inv.params["x"] == "a" and inv.params["y"] == "b"
    assert set(inv.params) >= {"x", "y", "vertices", "A", "b", "area", "box_area"}
    assert len(inv.params["A"]) == len(inv.params["b"]) == len(inv.params["vertices"])
    assert inv.samples == 3000
    assert inv.confidence > 0.99
    count = len(inv.params["vertices"])
    assert inv.text.startswith("(a, b) inside [(")
    assert inv.text.endswith(f"] ({count} vertices)")


# --- degenerate hulls and justification --------------------------------------------------


def test_lines_points_and_thin_slivers_are_not_polygons() -> None:
    x = np.linspace(-1, 1, 500)
    state = state_for(
        {
            "x": x,
            "twice": 2 * x,  # exactly collinear: two vertices
            "const": np.full(500, 3.0),
            "rounded": 0.3 * x + 0.1,  # collinear up to rounding: a sliver of ~1e-17
        }
    )
    assert polygons(state, drop_ratio=1.0) == []
    assert len(vertices_of(state, 0)) == 2  # (x, twice)
    assert len(vertices_of(state, 1)) == 2  # (x, const)


def test_justification_counts_samples_since_the_hull_changed() -> None:
    rng = np.random.default_rng(6)
    a, b = rng.normal(size=(2, 50))
    late = np.concatenate([a, [40.0]]), np.concatenate([b, [40.0]])
    state = state_for({"a": late[0], "b": late[1]})
    assert polygons(state, drop_ratio=1.0) == []  # the hull changed on the last sample
    again = np.concatenate([late[0], np.zeros(7)]), np.concatenate([late[1], np.zeros(7)])
    state = state_for({"a": again[0], "b": again[1]})
    (inv,) = polygons(state, drop_ratio=1.0)
    assert inv.confidence == 1 - 2**-8  # the changing sample counts as 1, then 7 more
    few = state_for({"a": [0.0, 1.0, 0.0, 1.0], "b": [0.0, 0.0, 1.0, 1.0]})
    assert polygons(few, drop_ratio=1.0) == []  # 1 sample since the last vertex


def test_nan_and_infinite_rows_are_skipped() -> None:
    rng = np.random.default_rng(7)
    a, b = rng.normal(size=(2, 3000))
    a_gaps, b_gaps = a.copy(), b.copy()
    a_gaps[::7] = np.nan
    b_gaps[3::11] = np.inf
    a_gaps[:300] = np.nan  # an input topic not heard from yet
    clean = np.isfinite(a_gaps) & np.isfinite(b_gaps)
    gappy = state_for({"a": a_gaps, "b": b_gaps}, chunk=700)
    dense = state_for({"a": a[clean], "b": b[clean]})
    assert vertices_of(gappy, 0) == vertices_of(dense, 0)
    assert gappy.count.tolist() == [int(clean.sum())]


def test_make_states_pairs_numeric_non_derived_variables_of_every_topic() -> None:
    variables = (
        U,
        R,
        Variable("stamp", "time", topic="/uav", path="header.stamp"),
        Variable("avg(scan.ranges)", "float", topic="/uav", derived="avg"),
        Variable("frame", "string", topic="/uav"),
        Variable("mode", "int", topic="/uav", path="mode"),
    )
    assert [v.name for v in polygon_variables(variables)] == ["UAV.y", "iRobot.y", "mode"]
    (state,) = make_states(variables, Tunables(), {"polygon", "bounds"})
    assert state.family == "polygon"
    assert len(state.pi) == 3
    assert make_states(variables, Tunables(), {"bounds"}) == []
    assert make_states((U,), Tunables(), {"polygon"}) == []


def test_thesis_example_uav_against_irobot() -> None:
    rng = np.random.default_rng(8)
    robot = np.cumsum(rng.normal(0, 0.05, 4000))
    uav = robot + rng.uniform(-0.3, 0.3, 4000)  # the UAV follows the robot
    state = PolygonState((U, R))
    state.update(Samples("land", 0, np.arange(4000.0), {"UAV.y": uav, "iRobot.y": robot}, (U, R)))
    (inv,) = state.finalize(context())
    assert inv.variables == ("UAV.y", "iRobot.y")
    assert "UAV.y" in inv.text and "iRobot.y" in inv.text


def test_discrete_and_identical_columns() -> None:
    rng = np.random.default_rng(9)
    mode = rng.integers(0, 5, 5000).astype(float)
    flag = rng.integers(0, 2, 5000).astype(float)
    level = rng.normal(size=5000)
    columns = {"mode": mode, "flag": flag, "level": level, "copy": level.copy()}
    names = list(columns)
    variables = (
        Variable("mode", "int"),
        Variable("flag", "bool"),
        Variable("level", "float"),
        Variable("copy", "float"),
    )
    state = PolygonState(variables, batch=0)
    for first in range(0, 5000, 1200):
        state.update(
            Samples(
                "p",
                0,
                np.arange(first, min(first + 1200, 5000), dtype=float),
                {n: columns[n][first : first + 1200] for n in names},
                variables,
            )
        )
    for pair, (i, j) in enumerate(zip(state.pi.tolist(), state.pj.tolist(), strict=True)):
        points = list(zip(columns[names[i]].tolist(), columns[names[j]].tolist(), strict=True))
        assert vertices_of(state, pair) == hull_with_first(points)


def test_few_polar_sectors_when_a_point_has_very_many_pairs(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    monkeypatch.setattr(guide, "BUCKETS", 16)
    rng = np.random.default_rng(10)
    t = rng.uniform(0, 2 * np.pi, 6000)
    columns = {
        "a": np.cos(t) * rng.uniform(0.9, 1, 6000),
        "b": np.sin(t),
        "c": rng.normal(size=6000),
        "d": 0.5 * np.cos(t) + 0.01 * rng.normal(size=6000),
    }
    state = state_for(columns, chunk=997)
    assert state.guide.buckets == 16
    names = list(columns)
    for pair, (i, j) in enumerate(zip(state.pi.tolist(), state.pj.tolist(), strict=True)):
        points = list(zip(columns[names[i]].tolist(), columns[names[j]].tolist(), strict=True))
        assert vertices_of(state, pair) == hull_with_first(points)
    assert guide._buckets(10**6) == 16 and guide._buckets(1540) == 16


# --- exactness -------------------------------------------------------------------------


coordinates = st.one_of(
    st.floats(-1e6, 1e6, allow_nan=False, width=64),
    st.sampled_from([0.0, 1.0, -1.0, 0.1, 0.2, 0.3, 1e-300, 3.0]),
    # both sides of stage D's safe range [2**-400, 2**400)
    st.sampled_from([1e200, -1e125, 2.0**400, 2.0**-400, -(2.0**-401), 1e-150, 7e119]),
    st.integers(-3, 3).map(float),
)


@settings(max_examples=200, deadline=None)
@given(st.lists(st.floats(-1e3, 1e3, allow_nan=False, width=64), min_size=3, max_size=60))
def test_orientation_is_exact_on_rounded_lines(xs: list[float]) -> None:
    """Stage D's ground: points of ``y = 0.1 x + 0.7`` rounded to floats."""
    x = np.array(xs)
    y = 0.1 * x + 0.7
    n = len(x)
    a, b, c = np.arange(n), np.roll(np.arange(n), 1), np.roll(np.arange(n), 2)
    got = orientation(x[a], y[a], x[b], y[b], x[c], y[c])
    for k in range(n):
        fx = [Fraction(x[i]) for i in (a[k], b[k], c[k])]
        fy = [Fraction(y[i]) for i in (a[k], b[k], c[k])]
        det = (fx[0] - fx[2]) * (fy[1] - fy[2]) - (fy[0] - fy[2]) * (fx[1] - fx[2])
        assert got[k] == (det > 0) - (det < 0)


@settings(max_examples=200, deadline=None)
@given(st.lists(st.tuples(coordinates, coordinates, coordinates), min_size=1, max_size=40))
def test_orientation_is_exact(triples: list[tuple[float, float, float]]) -> None:
    a = np.array([t[0] for t in triples])
    b = np.array([t[1] for t in triples])
    c = np.array([t[2] for t in triples])
    # near-collinear on purpose: c on the line through (a, b) and (b, a), up to rounding
    cx = c
    cy = (a + b) - c
    got = orientation(a, b, b, a, cx, cy)
    for k in range(len(triples)):
        det = (Fraction(a[k]) - Fraction(cx[k])) * (Fraction(a[k]) - Fraction(cy[k])) - (
            Fraction(b[k]) - Fraction(cy[k])
        ) * (Fraction(b[k]) - Fraction(cx[k]))
        assert got[k] == (det > 0) - (det < 0)


def clouds() -> st.SearchStrategy[tuple[FloatArray, FloatArray]]:
    """Small point clouds of many kinds: continuous, grids, lines, rounded lines, gaps."""

    @st.composite
    def make(draw: st.DrawFn) -> tuple[FloatArray, FloatArray]:
        n = draw(st.integers(1, 150))
        seed = draw(st.integers(0, 2**32 - 1))
        kind = draw(st.sampled_from(["normal", "grid", "line", "rounded", "drift", "tiny"]))
        rng = np.random.default_rng(seed)
        x = rng.normal(size=n)
        if kind == "normal":
            y = rng.normal(size=n) * draw(st.sampled_from([1.0, 1e-9, 1e9]))
        elif kind == "grid":
            x = rng.integers(0, 4, n).astype(float)
            y = rng.integers(-2, 2, n).astype(float)
        elif kind == "line":
            y = 2 * x
        elif kind == "rounded":
            y = 0.1 * x + 0.7
        elif kind == "drift":
            x = np.cumsum(rng.normal(size=n))
            y = np.sin(x) + 1e3
        else:
            x = (1e6 + rng.integers(0, 3, n) * 2.0**-30).astype(np.float64)
            y = rng.normal(size=n)
        gaps = draw(st.sampled_from([0.0, 0.0, 0.1, 0.5]))
        x[rng.random(n) < gaps] = np.nan
        return x, y

    return make()


def _split(length: int, points: list[int]) -> list[tuple[int, int]]:
    edges = sorted({0, length, *[p % (length + 1) for p in points]})
    return list(itertools.pairwise(edges))


def _snapshot(state: PolygonState) -> tuple[Any, ...]:
    h = state.hull
    return (h.group.tolist(), h.x.tolist(), h.y.tolist(), h.at.tolist(), state.count.tolist())


@settings(max_examples=40, deadline=None)
@given(
    st.lists(clouds(), min_size=2, max_size=4),
    st.lists(st.integers(0, 600), max_size=3),
    st.lists(st.integers(0, 600), max_size=6),
    st.booleans(),
    st.sampled_from([0, 1500, 1 << 22]),
)
def test_fold_merge_rechunk_and_brute_force_agree_exactly(
    columns: list[tuple[FloatArray, FloatArray]],
    run_points: list[int],
    chunk_points: list[int],
    copied: bool,
    batch: int,
) -> None:
    """``copied``: each run's states are pickled between runs, as a worker's answer is (a
    copy has no guide: merged as it is, rebuilt if samples come again). ``batch``: the
    folded state folds each chunk as it comes, or holds chunks back until that many values
    are pending (some chunks, or whole runs)."""
    length = min(len(x) for x, _ in columns)
    data = {}
    for k, (x, y) in enumerate(columns):
        data[f"x{k}"] = x[:length]
        data[f"y{k}"] = y[:length]
    names = list(data)
    variables = tuple(Variable(n, "float") for n in names)

    def run(first: int, stop: int, cuts: list[int]) -> list[Samples]:
        out = []
        for a, b in _split(stop - first, cuts):
            rows = slice(first + a, first + b)
            out.append(
                Samples(
                    "p",
                    0,
                    np.arange(first + a, first + b, dtype=float),
                    {n: data[n][rows] for n in names},
                    variables,
                )
            )
        return out

    runs = _split(length, run_points)
    folded = PolygonState(variables, batch=batch)
    merged = PolygonState(variables)
    for a, b in runs:
        for chunk in run(a, b, chunk_points):
            folded.update(chunk)
        folded.end_run()
        alone = PolygonState(variables)
        for chunk in run(a, b, []):
            alone.update(chunk)
        alone.end_run()
        if copied:
            folded, alone = pickle.loads(pickle.dumps((folded, alone)))
        merged.merge(alone)
    assert _snapshot(folded) == _snapshot(merged)
    ctx = FinalizeContext(Tunables(drop_ratio=1.0), variables, "p")
    assert folded.finalize(ctx) == merged.finalize(ctx)
    for pair, (i, j) in enumerate(zip(folded.pi.tolist(), folded.pj.tolist(), strict=True)):
        x, y = data[names[i]], data[names[j]]
        ok = np.isfinite(x) & np.isfinite(y)
        points = list(zip(x[ok].tolist(), y[ok].tolist(), strict=True))
        assert vertices_of(folded, pair) == hull_with_first(points)
        assert int(folded.count[pair]) == len(points)


def test_held_back_chunks_are_folded_before_anything_reads_the_state() -> None:
    """Chunks held back (``batch``) are folded before the hulls, the counts or the guide are
    read, before a copy or a merge, and at the end of a run: the state then equals one
    that folded each chunk as it came, and a copy or merge of either gives the same."""
    rng = np.random.default_rng(21)
    n = 3000
    walk = np.cumsum(rng.normal(0, 0.05, n))
    columns = {"w": walk, "noise": rng.normal(size=n), "line": 2 * walk + 3}
    columns["noise"][rng.random(n) < 0.02] = np.nan
    names = list(columns)
    variables = tuple(Variable(name, "float") for name in names)
    chunks = [
        Samples(
            "p", 0, np.arange(a, b, dtype=float), {k: columns[k][a:b] for k in names}, variables
        )
        for a, b in _split(n, list(range(700, n, 700)))
    ]
    eager = PolygonState(variables, batch=0)
    for chunk in chunks:
        eager.update(chunk)
    lazy = PolygonState(variables, batch=1 << 30)
    for chunk in chunks[:2]:
        lazy.update(chunk)
    assert lazy._pending  # held back, not folded yet
    early = PolygonState(variables, batch=0)
    for chunk in chunks[:2]:
        early.update(chunk)
    assert _snapshot(lazy) == _snapshot(early)  # reading the hulls folds them
    assert not lazy._pending
    for chunk in chunks[2:]:
        lazy.update(chunk)
    copied = pickle.loads(pickle.dumps(lazy))  # a copy carries no held-back chunks
    assert not copied._pending and _snapshot(copied) == _snapshot(eager)
    second = PolygonState(variables, batch=1 << 30)
    second.update(chunks[1])
    first = PolygonState(variables, batch=1 << 30)
    first.update(chunks[0])
    first.merge(second)  # both sides' held-back chunks folded, ours before theirs
    assert _snapshot(first) == _snapshot(early)
    ctx = FinalizeContext(Tunables(drop_ratio=1.0), variables, "p")
    fresh = PolygonState(variables, batch=1 << 30)
    for chunk in chunks:
        fresh.update(chunk)
    assert fresh.finalize(ctx) == eager.finalize(ctx)
    fresh.end_run()
    assert not fresh._pending


def test_the_values_held_back_are_bounded_for_the_whole_process() -> None:
    """Each state alone stays under its batch, but together they pass it: the state whose
    update finds that folds its own chunks, and the result is the same."""
    rng = np.random.default_rng(22)
    variables = (Variable("x", "float"), Variable("y", "float"))
    parts = [
        Samples(
            "p",
            0,
            np.arange(k * 100.0, k * 100 + 100),
            dict(zip("xy", rng.normal(size=(2, 100)), strict=True)),
            variables,
        )
        for k in range(3)
    ]
    first = PolygonState(variables, batch=500)  # 200 values per chunk: 400 alone stays under
    second = PolygonState(variables, batch=500)
    first.update(parts[0])
    second.update(parts[1])
    assert first._pending and second._pending
    first.update(parts[2])  # 400 + 200 held back in all: the first one folds its chunks
    assert not first._pending and second._pending
    eager = PolygonState(variables, batch=0)
    for part in (parts[0], parts[2]):
        eager.update(part)
    assert _snapshot(first) == _snapshot(eager)
    del second  # a state that is gone holds nothing back
    third = PolygonState(variables, batch=500)
    third.update(parts[1])
    third.update(parts[0])  # 400: with the second one's 200 it would have folded
    assert third._pending


@settings(max_examples=40, deadline=None)
@given(clouds(), st.integers(1, 25))
def test_algorithm_6_gives_the_same_polygon(
    cloud: tuple[FloatArray, FloatArray], size: int
) -> None:
    x, y = cloud
    ok = np.isfinite(x) & np.isfinite(y)
    points = list(zip(x[ok].tolist(), y[ok].tolist(), strict=True))
    state = state_for({"x": x, "y": y}, chunk=size * 3)
    got = [(vx, vy) for vx, vy, _ in vertices_of(state, 0)]
    assert got == algorithm_6(points, size)


@settings(max_examples=60, deadline=None)
@given(st.lists(clouds(), min_size=1, max_size=5))
def test_grouped_hulls_equal_the_reference(groups: list[tuple[FloatArray, FloatArray]]) -> None:
    parts = []
    expected = []
    for g, (x, y) in enumerate(groups):
        ok = np.isfinite(x) & np.isfinite(y)
        at = np.arange(len(x))[ok] * 3 % 1000  # arbitrary, unique first occurrences
        parts.append(GroupSet(np.full(int(ok.sum()), g), x[ok], y[ok], at.astype(np.int64)))
        firsts: dict[tuple[float, float], int] = {}
        for px, py, pa in zip(x[ok].tolist(), y[ok].tolist(), at.tolist(), strict=True):
            firsts[(px, py)] = min(pa, firsts.get((px, py), pa))
        expected += [
            (g, vx, vy, firsts[(vx, vy)])
            for vx, vy, _ in hull_with_first(list(zip(x[ok].tolist(), y[ok].tolist(), strict=True)))
        ]
    out = hulls(GroupSet.concat(parts))
    got = list(
        zip(out.group.tolist(), out.x.tolist(), out.y.tolist(), out.at.tolist(), strict=True)
    )
    assert got == expected


# --- the filters: exact location, blocks, head starts, few-valued columns ----------------


@settings(max_examples=60, deadline=None)
@given(clouds(), st.integers(0, 2**32 - 1))
def test_location_discards_exactly_the_non_vertex_points_of_the_closed_hull(
    cloud: tuple[FloatArray, FloatArray], seed: int
) -> None:
    x, y = cloud
    ok = np.isfinite(x) & np.isfinite(y)
    group = np.zeros(int(ok.sum()), np.int64)
    hull = hulls(GroupSet(group, x[ok], y[ok], group.copy()))
    vertices = list(zip(hull.x.tolist(), hull.y.tolist(), strict=True))
    rng = np.random.default_rng(seed)
    # the cloud's own points, jittered ones, points on the lines through vertex pairs
    picks = rng.integers(0, max(len(vertices), 1), (2, 40))
    if vertices:
        vx, vy = hull.x[picks], hull.y[picks]
        t = rng.choice([0.0, 0.5, 1.0, 1.5, -0.5, rng.uniform()], 40)
        line_x, line_y = vx[0] + t * (vx[1] - vx[0]), vy[0] + t * (vy[1] - vy[0])
    else:
        line_x = line_y = np.zeros(0)
    qx = np.concatenate([x[ok], x[ok] * (1 + 1e-12), line_x, rng.normal(size=20)])
    qy = np.concatenate([y[ok], y[ok], line_y, rng.normal(size=20)])
    got = Locator.build(hull, 1).covered(np.zeros(len(qx), np.int64), qx, qy)
    usable = len(vertices) >= 2 and min(vertices)[0] < max(vertices)[0]
    for k, p in enumerate(zip(qx.tolist(), qy.tolist(), strict=True)):
        expected = contains(vertices, p) and p not in vertices
        if got[k] or usable:
            assert bool(got[k]) == expected, (p, vertices)


def _assert_reference(state: PolygonState, columns: dict[str, FloatArray]) -> None:
    names = list(columns)
    for pair, (i, j) in enumerate(zip(state.pi.tolist(), state.pj.tolist(), strict=True)):
        x, y = columns[names[i]], columns[names[j]]
        ok = np.isfinite(x) & np.isfinite(y)
        points = list(zip(x[ok].tolist(), y[ok].tolist(), strict=True))
        assert vertices_of(state, pair) == hull_with_first(points), (names[i], names[j])
        assert int(state.count[pair]) == len(points)


def test_walks_lines_and_noise_over_many_chunks_match_the_reference() -> None:
    """Random walks drifting into new ground (head starts, blocks), a walk and its exact
    linear copy (a sliver located exactly), noise (crosses), gaps, odd chunk sizes."""
    rng = np.random.default_rng(11)
    n = 4000
    walk = np.cumsum(rng.normal(0, 0.01, (3, n)), axis=1)
    columns = {
        "w0": walk[0],
        "w1": walk[1].copy(),
        "line": 2 * walk[0] + 3,
        "tilted": 0.1 * walk[2] + 0.7,
        "w2": walk[2],
        "noise": rng.normal(size=n),
    }
    columns["w1"][rng.random(n) < 0.01] = np.nan
    columns["noise"][:700] = np.nan
    state = state_of(columns, {}, chunk=1111)
    _assert_reference(state, columns)
    # the sliver pairs have no table: they are located exactly
    assert state.guide.locator.slot.max() >= 0


def test_few_valued_columns_with_gaps_and_ties_match_the_reference() -> None:
    """Modes and flags against continuous, tied, constant and gappy partners: the ends of
    each value come from the partners' tails, or from all rows when a tail misses one."""
    rng = np.random.default_rng(12)
    n = 6000
    columns = {
        "mode": rng.integers(0, 6, n).astype(float),
        "flag": rng.integers(0, 2, n).astype(float),
        "rare": np.where(rng.random(n) < 0.002, 7.0, 1.0),  # a value often missing from tails
        "level": rng.normal(size=n),
        "steps": np.round(rng.normal(size=n) * 2),  # many ties
        "const": np.full(n, 1.5),
        "gappy": rng.normal(size=n),
    }
    columns["gappy"][rng.random(n) < 0.05] = np.nan
    columns["mode"][rng.random(n) < 0.02] = np.nan
    columns["const"][:50] = np.nan
    kinds = {"mode": "int", "flag": "bool", "rare": "int", "steps": "int"}
    state = state_of(columns, kinds, chunk=1700)
    _assert_reference(state, columns)


@settings(max_examples=12, deadline=None)
@given(st.integers(0, 2**32 - 1), st.integers(100, 700), st.sampled_from([0.0, 0.03]))
def test_smooth_and_discrete_columns_fold_exactly(seed: int, chunk: int, gaps: float) -> None:
    rng = np.random.default_rng(seed)
    n = 700
    walk = np.cumsum(rng.normal(0, 0.05, (2, n)), axis=1)
    columns = {
        "a": walk[0],
        "b": walk[1],
        "c": -3 * walk[0] + 0.1,
        "mode": rng.integers(0, 4, n).astype(float),
        "d": rng.normal(size=n),
    }
    for name in ("b", "mode"):
        columns[name][rng.random(n) < gaps] = np.nan
    state = state_of(columns, {"mode": "int"}, chunk=chunk)
    _assert_reference(state, columns)


def test_finalize_gives_each_polygon_its_half_planes_and_text() -> None:
    rng = np.random.default_rng(13)
    t = rng.uniform(0, 2 * np.pi, 4000)
    columns = {
        "a": np.cos(t) * 1e3 + 5e5,
        "b": 2 * np.sin(t) + 0.1 * rng.normal(size=4000),
        "c": rng.normal(size=4000) * 1e-6,
    }
    state = state_for(columns, chunk=1500)
    found = polygons(state, drop_ratio=1.0)
    assert len(found) == 3
    for inv in found:
        normals, offsets, _ = half_planes(np.array(inv.params["vertices"]))
        assert inv.params["A"] == normals.tolist()
        assert inv.params["b"] == offsets.tolist()
        assert inv.text == polygon_text(inv.params["x"], inv.params["y"], inv.params["vertices"])


def test_hulls_of_values_whose_products_overflow_match_the_reference() -> None:
    """Quickhull's float distances overflow near 1e300: such groups are settled exactly."""
    rng = np.random.default_rng(14)
    n = 1500
    columns = {
        "big": rng.normal(size=n) * 1e300,
        "walk": np.cumsum(rng.normal(size=n)) * 1e305,
        "small": rng.normal(size=n),
        "tiny": rng.normal(size=n) * 1e-310,
    }
    state = state_of(columns, {}, chunk=600)
    _assert_reference(state, columns)
