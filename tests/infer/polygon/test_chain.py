"""The monotone chain that settles doubtful hulls: group by group in Python (``turn``, one
exact orientation at a time) against the lock-step one, and ``turn`` against fractions."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from imrosc.infer.polygon import hull
from imrosc.infer.polygon.hull import GroupSet, IntArray
from imrosc.infer.polygon.predicates import turn
from tests.infer.polygon.reference import cross, hull_with_first

EXTREMES = [0.0, -0.0, 5e-324, -5e-324, 2.0**-1000, 1e-300, 1e300, -1e308, 1.0, 0.1, 3.0]


def points(kind: str, n: int, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    """``n`` points of one shape: noise, an integer grid, exact and rounded lines, |x|,
    extreme magnitudes."""
    x = rng.normal(size=n)
    if kind == "grid":
        return rng.integers(0, 4, n).astype(float), rng.integers(-2, 2, n).astype(float)
    if kind == "line":
        return x, 2 * x
    if kind == "rounded":
        return x, 0.1 * x + 0.7
    if kind == "abs":
        return x, np.abs(x)
    if kind == "extreme":
        return rng.choice(EXTREMES, n), rng.choice(EXTREMES, n)
    if kind == "huge":
        return x * 1e300, rng.normal(size=n) * 1e-300
    return x, rng.normal(size=n)


KINDS = ["normal", "grid", "line", "rounded", "abs", "extreme", "huge"]


@st.composite
def groups(draw: st.DrawFn) -> GroupSet:
    """Up to 8 groups of distinct points (as the chain requires), firsts shuffled."""
    rng = np.random.default_rng(draw(st.integers(0, 2**32 - 1)))
    parts = []
    for g in range(draw(st.integers(1, 8))):
        x, y = points(draw(st.sampled_from(KINDS)), draw(st.integers(1, 40)), rng)
        seen: dict[tuple[float, float], int] = {}
        for k, place in enumerate(zip((x + 0.0).tolist(), (y + 0.0).tolist(), strict=True)):
            seen.setdefault(place, k)  # -0.0 and 0.0 are one place
        keep = np.array(sorted(seen.values()), np.int64)
        at = rng.permutation(len(keep)).astype(np.int64)
        parts.append(GroupSet(np.full(len(keep), g), x[keep], y[keep], at))
    return GroupSet.concat(parts)


def _rows(points: GroupSet) -> list[tuple[int, float, float, int]]:
    return list(
        zip(
            points.group.tolist(),
            points.x.tolist(),
            points.y.tolist(),
            points.at.tolist(),
            strict=True,
        )
    )


@settings(max_examples=60, deadline=None)
@given(groups())
def test_one_by_one_chain_equals_the_lock_step_and_the_reference(points: GroupSet) -> None:
    one_by_one = hull._chain(points)
    with pytest.MonkeyPatch.context() as patch:
        patch.setattr(hull, "_CHAIN_ONE_BY_ONE", 0)
        lock_step = hull._chain(points)
    assert _rows(one_by_one) == _rows(lock_step)
    # bit for bit, signed zeros included
    assert one_by_one.x.tobytes() == lock_step.x.tobytes()
    assert one_by_one.y.tobytes() == lock_step.y.tobytes()
    expected = []
    for g in np.unique(points.group).tolist():
        mine = points.take(np.flatnonzero(points.group == g).astype(np.int64))
        places = list(zip(mine.x.tolist(), mine.y.tolist(), strict=True))
        ats = dict(zip(places, mine.at.tolist(), strict=True))
        expected += [(g, x, y, ats[(x, y)]) for x, y, _ in hull_with_first(places)]
    assert _rows(one_by_one) == expected


def test_the_chain_goes_one_by_one_below_its_threshold(monkeypatch: pytest.MonkeyPatch) -> None:
    calls: list[int] = []
    original = hull._chains

    def counted(points: GroupSet) -> IntArray:
        calls.append(len(points))
        return original(points)

    monkeypatch.setattr(hull, "_chains", counted)
    square = GroupSet(
        np.zeros(5, np.int64),
        np.array([0.0, 1.0, 1.0, 0.0, 0.5]),
        np.array([0.0, 0.0, 1.0, 1.0, 0.5]),
        np.arange(5, dtype=np.int64),
    )
    out = hull._chain(square)
    assert calls == [5]
    assert list(zip(out.x.tolist(), out.y.tolist(), strict=True)) == [
        (0.0, 0.0),
        (1.0, 0.0),
        (1.0, 1.0),
        (0.0, 1.0),
    ]
    monkeypatch.setattr(hull, "_CHAIN_ONE_BY_ONE", 4)
    hull._chain(square)
    assert calls == [5]  # more points than the threshold: lock-step


coordinate = st.one_of(
    st.floats(-1e6, 1e6, allow_nan=False, width=64),
    st.sampled_from(EXTREMES),
    st.integers(-3, 3).map(float),
)


@settings(max_examples=300, deadline=None)
@given(st.lists(coordinate, min_size=6, max_size=6), st.booleans())
def test_turn_is_the_exact_sign(values: list[float], on_line: bool) -> None:
    ax, ay, bx, by, cx, cy = values
    if on_line:  # c on the line through a and b, up to rounding
        cy = ay + (by - ay) * 0.5 if abs(ay) < 1e300 and abs(by) < 1e300 else cy
        cx = ax + (bx - ax) * 0.5 if abs(ax) < 1e300 and abs(bx) < 1e300 else cx
    det = cross((cx, cy), (ax, ay), (bx, by))
    assert turn(ax, ay, bx, by, cx, cy) == (det > 0) - (det < 0)
