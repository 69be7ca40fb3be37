"""The fast exact paths of the polygon family on data with exact relations.

Columns related exactly (``q = -p``, ``b = 2*a + 3``, ``ab = |n|``, ``mx = max(n1, n2)``,
``t = a - 2*m + 1`` over a 3-valued float ``m``), integer-valued and constant columns put
many samples on the edges of their hulls, where only exact arithmetic decides: the
vectorised stage D, the parallel shortcut, float columns with few values grouped like
discrete ones and the location of candidates in their current hull must all give the
reference hull (slow, exact monotone chain) bit for bit, first occurrences included.
"""

from __future__ import annotations

import functools
import math
from fractions import Fraction

import numpy as np
import pytest

from bench.infer import planted
from imrosc.infer.core import FinalizeContext, FloatArray, Variable
from imrosc.infer.polygon import PolygonState, orientation
from imrosc.infer.polygon.predicates import exact_sum_signs
from imrosc.ir import Tunables
from tests.infer.polygon.reference import hull_with_first
from tests.infer.polygon.support import state_of


def _vertices(state: PolygonState) -> dict[tuple[str, str], list[tuple[float, float, int]]]:
    found: dict[tuple[str, str], list[tuple[float, float, int]]] = {}
    for pair, (i, j) in enumerate(zip(state.pi.tolist(), state.pj.tolist(), strict=True)):
        mine = state.hull.group == pair
        found[(state.names[i], state.names[j])] = list(
            zip(
                state.hull.x[mine].tolist(),
                state.hull.y[mine].tolist(),
                state.hull.at[mine].tolist(),
                strict=True,
            )
        )
    return found


def _planted_columns(rows: int, names: tuple[str, ...]) -> dict[str, FloatArray]:
    _, data, every = planted(rows, groups=1, seed=5)
    return {n: data[every.index(n)] for n in names}


_NAMES = ("a0", "b0", "k0", "m0", "t0", "p0", "q0", "n10", "mx0", "ab0", "s0", "i0")


@functools.cache
def _reference() -> dict[tuple[str, str], list[tuple[float, float, int]]]:
    columns = _planted_columns(900, _NAMES)
    found = {}
    for k, x in enumerate(_NAMES):
        for y in _NAMES[k + 1 :]:
            points = list(zip(columns[x].tolist(), columns[y].tolist(), strict=True))
            found[(x, y)] = hull_with_first(points)
    return found


@pytest.mark.parametrize("chunk", [97, 400, 900])
def test_exact_relations_give_the_reference_hulls(chunk: int) -> None:
    """Every pair of one planted group: collinear (``q = -p``), rounded lines
    (``b = 2*a + 3``, ``s = ab + 5``), edges full of samples (``ab = |n1|``, ``mx``, ``t``),
    an integer-valued and a 3-valued float column, a constant."""
    columns = _planted_columns(900, _NAMES)
    got = _vertices(state_of(columns, {}, chunk))
    assert got == _reference()


def test_a_float_column_with_few_values_folds_like_a_discrete_one() -> None:
    """The grouped path (per value, the partner's ends) is taken by a float column with 3
    values as by an int one: same vertices, same first occurrences."""
    names = ("a0", "m0", "t0", "n10", "i0")
    columns = _planted_columns(3000, names)
    as_float = _vertices(state_of(columns, {}, 512))
    as_int = _vertices(state_of(columns, {"m0": "int"}, 512))
    assert as_float == as_int


def test_lines_explained_by_the_linear_family_give_no_polygon() -> None:
    """``b = 2*a + 3`` and ``q = -p`` are lines: their hull is a segment or a sliver, which
    the linear family reports; no polygon. A V (``ab = |n1|``) and a band (``t``) are
    polygons."""
    names = ("a0", "b0", "p0", "q0", "n10", "ab0", "m0", "t0")
    columns = _planted_columns(2000, names)
    state = state_of(columns, {}, 700)
    variables = tuple(Variable(n, "float") for n in names)
    found = state.finalize(FinalizeContext(Tunables(), variables, "p"))
    pairs = {inv.variables for inv in found}
    assert ("a0", "b0") not in pairs and ("p0", "q0") not in pairs
    assert ("n10", "ab0") in pairs and ("a0", "t0") in pairs


def _exact_sign(row: list[float]) -> int:
    total = sum((Fraction(v) for v in row), Fraction(0))
    return (total > 0) - (total < 0)


def test_exact_sum_signs_match_rational_sums() -> None:
    """Rows that cancel exactly, nearly, or not at all, over wide magnitudes."""
    rng = np.random.default_rng(3)
    base = rng.normal(0, 1, (3000, 8)) * 2.0 ** rng.integers(-80, 80, (3000, 8))
    rows = np.concatenate([base, -base[:, ::-1]], axis=1)
    rows[:1000, 5] += rng.normal(0, 1, 1000) * 2.0 ** rng.integers(-300, -100, 1000)
    rows[1000:1500] = rng.normal(0, 1, (500, 16))
    got = exact_sum_signs(rows)
    want = [_exact_sign(row) for row in rows.tolist()]
    assert got.tolist() == want
    assert exact_sum_signs(np.zeros((0, 16))).tolist() == []


def _reference_orientation(
    a: tuple[float, float], b: tuple[float, float], c: tuple[float, float]
) -> int:
    ax, ay, bx, by, cx, cy = (Fraction(v) for v in (*a, *b, *c))
    det = (ax - cx) * (by - cy) - (ay - cy) * (bx - cx)
    return (det > 0) - (det < 0)


@pytest.mark.parametrize(
    "relation",
    [
        lambda x: -x,
        lambda x: x,
        lambda x: 4 * x,
        lambda x: -0.125 * x,
        lambda x: x + 0.5,
        np.abs,
        lambda x: 2 * x + 3,
        lambda x: x / 3,
    ],
)
def test_orientation_of_samples_of_exact_relations_is_exact(relation: object) -> None:
    """Collinear in exact arithmetic (power-of-two slopes: the parallel shortcut) or within
    rounding of a line (the other stages): the sign is the rational one."""
    rng = np.random.default_rng(8)
    x = rng.uniform(-50, 50, (3, 2000)) * 2.0 ** rng.integers(-20, 20, (3, 2000))
    y = np.asarray(relation(x), dtype=np.float64)  # type: ignore[operator]
    got = orientation(x[0], y[0], x[1], y[1], x[2], y[2])
    want = [
        _reference_orientation((x[0, k], y[0, k]), (x[1, k], y[1, k]), (x[2, k], y[2, k]))
        for k in range(x.shape[1])
    ]
    assert got.tolist() == want
    assert math.isfinite(float(y.sum()))


@pytest.mark.parametrize("open_share", [0.0, 0.3, 0.6, 0.9, 0.97, 1.0])
def test_orientation_is_exact_whatever_share_of_elements_the_float_stage_leaves_open(
    open_share: float,
) -> None:
    """Elements stage A decides (points well off the line) mixed with exactly collinear
    ones (``y = -x``: the parallel shortcut) and ones within rounding of a line
    (``y = x / 3``: stages B to D), in proportions on both sides of where the later stages
    stop gathering the open elements and run on all of them."""
    rng = np.random.default_rng(11)
    size = 3000
    x = rng.uniform(-50, 50, (3, size))
    y = np.where(np.arange(size) % 2 == 0, -x, x / 3)
    open_ = rng.random(size) < open_share
    y[2] = np.where(open_, y[2], y[2] + rng.uniform(1, 5, size))  # off the line: decided
    got = orientation(x[0], y[0], x[1], y[1], x[2], y[2])
    want = [
        _reference_orientation((x[0, k], y[0, k]), (x[1, k], y[1, k]), (x[2, k], y[2, k]))
        for k in range(size)
    ]
    assert got.tolist() == want
