"""Exact sums, exact residuals and the shortest coefficients."""

from __future__ import annotations

from fractions import Fraction

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from imrosc.infer.daikon.exact import (
    SCALE,
    Fit,
    Moments,
    dyadic,
    exact_dots,
    exact_sums,
    rounded,
    significant_digits,
)
from imrosc.infer.daikon.relation import relation_text

finite = st.floats(allow_nan=False, allow_infinity=False)
rows = st.lists(finite, min_size=0, max_size=30)


def scaled(values: list[float]) -> Fraction:
    total: Fraction = sum((Fraction(v) for v in values), Fraction(0))
    return total * Fraction(2) ** SCALE


@settings(max_examples=200, deadline=None)
@given(rows, rows)
def test_exact_sums_and_dots(first: list[float], second: list[float]) -> None:
    size = min(len(first), len(second))
    left = np.array(first[:size], dtype=np.float64).reshape(1, size)
    right = np.array(second[:size], dtype=np.float64).reshape(1, size)
    assert Fraction(exact_sums(left)[0]) == scaled(first[:size])
    expected = sum(
        (Fraction(a) * Fraction(b) for a, b in zip(first, second, strict=False)), Fraction(0)
    )
    assert Fraction(exact_dots(left, right)[0]) == expected * 2**SCALE


def test_exact_sums_of_many_rows_and_extremes() -> None:
    rng = np.random.default_rng(2)
    matrix = rng.normal(size=(5, 5000)) * 10.0 ** rng.integers(-300, 300, size=(5, 5000))
    matrix[0, :3] = [1.7976931348623157e308, 1.7976931348623157e308, 5e-324]
    for row, total in zip(matrix, exact_sums(matrix), strict=True):
        assert Fraction(total) == scaled(list(row))


def test_exact_sums_of_rows_that_settle_after_different_passes() -> None:
    """Rows done at once (zeros, small integers), after a few passes (floats over a wide
    range) or summed by exponent groups (near overflow), side by side in one matrix."""
    rng = np.random.default_rng(7)
    matrix = np.zeros((6, 3000))
    matrix[1] = rng.integers(-50, 50, 3000)
    matrix[2] = rng.normal(size=3000) * 2.0 ** rng.integers(-60, 60, size=3000)
    matrix[3] = rng.uniform(-10, 10, 3000)
    matrix[4] = rng.normal(size=3000) * 1e300
    matrix[5] = -matrix[2]
    for row, total in zip(matrix, exact_sums(matrix), strict=True):
        assert Fraction(total) == scaled(list(row))


def test_exact_sums_consume_only_a_float64_temporary() -> None:
    """``consume`` works on the caller's C-contiguous float64 matrix in place (the same
    sums); another layout is copied and left as it was."""
    rng = np.random.default_rng(9)
    matrix = rng.normal(size=(4, 2000)) * 2.0 ** rng.integers(-80, 80, size=(4, 2000))
    matrix[3] = 1e300 * rng.normal(size=2000)  # summed by exponent groups
    want = [Fraction(total) for total in exact_sums(matrix)]
    assert want == [scaled(list(row)) for row in matrix]
    strided = matrix.T.copy().T  # Fortran order: copied even when consumable
    assert [Fraction(t) for t in exact_sums(strided, consume=True)] == want
    assert np.array_equal(strided, matrix)
    temporary = matrix.copy()
    assert [Fraction(t) for t in exact_sums(temporary, consume=True)] == want


@settings(max_examples=100, deadline=None)
@given(st.lists(st.tuples(finite, finite), min_size=1, max_size=12), finite, finite, finite)
def test_residual_is_exact(points: list[tuple[float, float]], a: float, b: float, c: float) -> None:
    x = np.array([p[0] for p in points]).reshape(1, -1)
    y = np.array([p[1] for p in points]).reshape(1, -1)
    moments = Moments(2)
    moments.add(
        {
            (0, 0): exact_dots(x, x)[0],
            (0, 1): exact_dots(x, y)[0],
            (1, 1): exact_dots(y, y)[0],
            (0, 2): exact_sums(x)[0],
            (1, 2): exact_sums(y)[0],
        },
        len(points),
    )
    weights = [dyadic(a), dyadic(b), dyadic(c)]
    mantissa, exponent = moments.residual(weights)
    expected = sum(
        (Fraction(a) * Fraction(px) + Fraction(b) * Fraction(py) + Fraction(c)) ** 2
        for px, py in points
    )
    assert Fraction(mantissa) * Fraction(2) ** exponent == expected


def pair_moments(x: list[float], y: list[float]) -> Moments:
    left = np.array(x).reshape(1, -1)
    right = np.array(y).reshape(1, -1)
    moments = Moments(2)
    moments.add(
        {
            (0, 0): exact_dots(left, left)[0],
            (0, 1): exact_dots(left, right)[0],
            (1, 1): exact_dots(right, right)[0],
            (0, 2): exact_sums(left)[0],
            (1, 2): exact_sums(right)[0],
        },
        len(x),
    )
    return moments


def test_fit_finds_short_coefficients_and_rejects_misfits() -> None:
    x = [float(v) for v in range(-5, 6)]
    y = [0.1 * v + 0.7 for v in x]
    spread = [10.0, max(y) - min(y)]
    magnitude = [5.0, max(abs(v) for v in y)]
    fit = Fit(pair_moments(x, y), 1, [0], spread, magnitude)
    assert fit.accepted
    assert fit.coefficients == (0.1, 0.7)
    bent = [*y[:-1], y[-1] + 1e-6]
    assert not Fit(pair_moments(x, bent), 1, [0], spread, magnitude).accepted


def test_significant_digits_and_rounding() -> None:
    assert [significant_digits(v) for v in (0.0, 2.0, 1000.0, 0.125, 1234.5, 1.5e-5)] == [
        0,
        1,
        1,
        3,
        5,
        2,
    ]
    assert rounded(2.0000000000000004, 1) == 2.0
    assert rounded(0.123456, 3) == 0.123
    assert rounded(5.5, 0) == 0.0


def test_relation_text() -> None:
    assert relation_text("z", [(1.0, "x"), (-2.0, "m")], 1.0) == "z = x - 2*m + 1"
    assert relation_text("y", [(-1.0, "x")], 0.0) == "y = -x"
    assert relation_text("y", [(0.5, "x")], -1.5) == "y = 0.5*x - 1.5"
    assert relation_text("y", [(1e-5, "x")], 2.0) == "y = 1e-05*x + 2"
