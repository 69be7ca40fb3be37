"""Linear and ternary relations: planted ones with readable coefficients, noise not."""

from __future__ import annotations

import math

import numpy as np
import pytest

from imrosc.infer.core import Variable

from .support import infer, texts

NAN = math.nan


def floats(*names: str) -> tuple[Variable, ...]:
    return tuple(Variable(name, "float") for name in names)


def rng() -> np.random.Generator:
    return np.random.default_rng(11)


@pytest.mark.parametrize(
    ("slope", "intercept", "text"),
    [
        (2.0, 3.0, "b = 2*a + 3"),
        (-1.0, 0.0, "b = -a"),
        (3.0, 0.1, "b = 3*a + 0.1"),
        (-2.5, 7.0, "b = -2.5*a + 7"),
        (1e-3, 5.0, "b = 0.001*a + 5"),
    ],
)
def test_planted_linear_relation(slope: float, intercept: float, text: str) -> None:
    a = rng().uniform(-10, 10, 500)
    found = infer(floats("a", "b"), {"a": a, "b": slope * a + intercept}, ["linear"])
    assert texts(found) == [text]
    invariant = found[0]
    assert invariant.family == "linear"
    assert invariant.kind == "linear"
    assert invariant.variables == ("b", "a")
    assert invariant.params["a"] == slope
    assert invariant.params["b"] == intercept
    assert 0 < invariant.params["tolerance"] < 1e-7
    assert invariant.samples == 500


def test_linear_turns_round_unreadable_coefficients() -> None:
    a = rng().uniform(-10, 10, 500)
    found = infer(floats("a", "b"), {"a": a, "b": 0.5 * a - 1.25}, ["linear"])
    assert texts(found) == ["b = 0.5*a - 1.25"]
    found = infer(floats("a", "b"), {"a": a, "b": a / 3}, ["linear"])
    assert texts(found) == ["a = 3*b"]
    assert found[0].variables == ("a", "b")
    assert found[0].params["a"] == 3.0
    assert found[0].params["b"] == 0.0


def test_linear_puts_the_later_variable_first() -> None:
    y = rng().uniform(-10, 10, 300)
    found = infer(floats("x", "y"), {"x": 2 * y + 3, "y": y}, ["linear"])
    assert texts(found) == ["y = 0.5*x - 1.5"]


def test_linear_noise_and_near_relations_are_not_reported() -> None:
    r = rng()
    a = r.uniform(-10, 10, 2000)
    rows = {
        "a": a,
        "noisy": 2 * a + 3 + r.normal(scale=1e-6, size=2000),
        "other": r.uniform(-10, 10, 2000),
        "square": a * a,
    }
    assert texts(infer(floats(*rows), rows, ["linear", "ternary"], chunk_rows=256)) == []


def test_linear_equality_and_constants_are_not_linear() -> None:
    a = rng().uniform(-1, 1, 100)
    rows = {"a": a, "copy": a.copy(), "k": np.full(100, 2.0), "b": a * 4.0}
    found = infer(floats(*rows), rows, ["linear", "equality"])
    assert texts(found) == ["a == copy", "b = 4*a"]


def test_linear_needs_more_than_three_values() -> None:
    a = np.array([0.0, 1.0, 2.0] * 10)
    rows = {"a": a, "b": 2 * a + 1}
    assert texts(infer(floats("a", "b"), rows, ["linear"])) == []
    rows = {"a": np.append(a, 3.0), "b": np.append(2 * a + 1, 7.0)}
    assert texts(infer(floats("a", "b"), rows, ["linear"])) == ["b = 2*a + 1"]


def test_linear_skips_nan_rows_and_dies_on_inf() -> None:
    a = rng().uniform(0, 5, 60)
    b = 3 * a - 2
    a[5] = NAN
    b[9] = NAN
    assert texts(infer(floats("a", "b"), {"a": a, "b": b}, ["linear"])) == ["b = 3*a - 2"]
    found = infer(floats("a", "b"), {"a": a, "b": b}, ["linear"])
    assert found[0].samples == 58
    b[20] = math.inf
    assert texts(infer(floats("a", "b"), {"a": a, "b": b}, ["linear"])) == []


def test_planted_ternary_relation() -> None:
    r = rng()
    x, m = r.uniform(0, 10, 1000), r.uniform(-5, 5, 1000)
    rows = {"x": x, "m": m, "z": x - 2 * m + 1, "noise": r.uniform(0, 1, 1000)}
    found = infer(floats(*rows), rows, ["linear", "ternary"], chunk_rows=300)
    assert texts(found) == ["z = x - 2*m + 1"]
    assert found[0].variables == ("z", "x", "m")
    assert found[0].params["a"] == 1.0
    assert found[0].params["b"] == -2.0
    assert found[0].params["c"] == 1.0


def test_ternary_relates_linear_leaders_only() -> None:
    r = rng()
    x, m = r.uniform(0, 10, 500), r.uniform(-5, 5, 500)
    rows = {"x": x, "y": 2 * x + 3, "m": m, "z": x - 2 * m + 1}
    found = infer(floats(*rows), rows, ["linear", "ternary"])
    assert texts(found) == ["y = 2*x + 3", "z = x - 2*m + 1"]


def test_ternary_with_fractional_coefficients() -> None:
    r = rng()
    x, y = r.uniform(-3, 3, 400), r.uniform(0, 1, 400)
    rows = {"x": x, "y": y, "w": 0.25 * x - 1.5 * y + 0.125}
    assert texts(infer(floats(*rows), rows, ["ternary"])) == ["w = 0.25*x - 1.5*y + 0.125"]
    rows = {"x": x, "y": y, "w": (x - 6 * y + 0.5) / 4.2}
    assert texts(infer(floats(*rows), rows, ["ternary"])) == ["x = 6*y + 4.2*w - 0.5"]


def test_relations_survive_variables_constant_within_a_chunk() -> None:
    x = np.concatenate([np.full(300, 2.0), rng().uniform(0, 4, 300)])
    rows = {"x": x, "y": -3 * x + 1}
    assert texts(infer(floats("x", "y"), rows, ["linear"], chunk_rows=150)) == ["y = -3*x + 1"]


def test_huge_and_tiny_values_are_exact() -> None:
    a = rng().uniform(1, 2, 50) * 1e-200
    rows = {"a": a, "b": 4 * a}
    assert texts(infer(floats("a", "b"), rows, ["linear"])) == ["b = 4*a"]
    a = rng().uniform(1, 2, 50) * 1e200
    rows = {"a": a, "b": -a / 2}
    assert texts(infer(floats("a", "b"), rows, ["linear"])) == ["b = -0.5*a"]


def test_coefficients_beyond_the_float_range_are_no_relation() -> None:
    x = np.array([0.0, 5e-324, 1e-323, 1.5e-323, 2e-323] * 3)
    rows = {"x": x, "y": x / 5e-324 * 1e300}
    found = infer(floats("x", "y"), rows, ["linear", "ternary"])
    assert all("x" not in invariant.variables for invariant in found)
