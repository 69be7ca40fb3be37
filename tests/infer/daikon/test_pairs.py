"""Equality sets and order relations."""

from __future__ import annotations

import math

import numpy as np

from imrosc.infer.core import Variable

from .support import infer, texts

NAN = math.nan


def floats(*names: str) -> tuple[Variable, ...]:
    return tuple(Variable(name, "float") for name in names)


def test_equality_set_reports_once_in_variable_order() -> None:
    variables = floats("a", "b", "c", "d")
    base = np.roll(np.linspace(-1, 1, 20), 7)
    rows = {"a": base, "b": base.copy(), "c": base + 1, "d": base.copy()}
    found = infer(variables, rows, ["equality"])
    assert texts(found) == ["a == b == d"]
    assert found[0].variables == ("a", "b", "d")
    assert found[0].kind == "=="
    assert found[0].samples == 20


def test_equality_skips_nan_rows_and_ignores_constants() -> None:
    variables = floats("a", "b", "k", "l")
    rows = {
        "a": [1.0, 2.0, NAN, 4.0, 5.0, 6.0, 7.0, 8.0, 9.0],
        "b": [1.0, 2.0, 3.0, 4.0, 5.0, 6.0, 7.0, 8.0, NAN],
        "k": [3.0] * 9,
        "l": [3.0] * 9,
    }
    found = infer(variables, rows, ["equality"])
    assert texts(found) == ["a == b"]
    assert found[0].samples == 7
    assert texts(infer(variables, {k: v[:6] for k, v in rows.items()}, ["equality"])) == []


def test_order_strict_and_weak() -> None:
    variables = floats("x", "y", "z")
    x = np.roll(np.linspace(0, 10, 30), 11)
    rows = {"x": x, "y": x + np.where(np.arange(30) % 3 == 0, 0.0, 0.5), "z": 10 - x}
    found = infer(variables, rows, ["order"])
    assert texts(found) == ["x <= y"]
    assert found[0].kind == "<="
    rows["y"] = x + 0.5
    found = infer(variables, rows, ["order"])
    assert texts(found) == ["x < y"]
    assert found[0].variables == ("x", "y")


def test_order_prints_the_smaller_variable_first() -> None:
    variables = floats("imu.mag_z", "imu.acc_x")
    acc = np.roll(np.linspace(-2, 2, 20), 5)
    rows = {"imu.mag_z": acc + 0.25, "imu.acc_x": acc}
    assert texts(infer(variables, rows, ["order"])) == ["imu.acc_x < imu.mag_z"]


def test_order_implied_by_bounds_is_suppressed() -> None:
    variables = floats("low", "high")
    rows = {"low": np.roll(np.linspace(0, 1, 20), 3), "high": np.roll(np.linspace(2, 3, 20), 9)}
    assert texts(infer(variables, rows, ["order", "bounds"])) == [
        "0 <= low <= 1",
        "2 <= high <= 3",
    ]
    assert texts(infer(variables, rows, ["order"])) == ["low < high"]


def test_order_relates_equality_leaders_only() -> None:
    variables = floats("x", "x_copy", "y")
    x = np.roll(np.linspace(0, 1, 20), 4)
    rows = {"x": x, "x_copy": x.copy(), "y": x + 0.5}
    assert texts(infer(variables, rows, ["order", "equality"])) == ["x == x_copy", "x < y"]


def test_order_needs_justified_joint_support() -> None:
    variables = floats("x", "y")
    rows = {"x": [1.0, 2.0, 3.0, 4.0, 5.0, 6.0], "y": [2.0, 3.0, 4.0, 5.0, 6.0, 7.0]}
    assert texts(infer(variables, rows, ["order"])) == []
    assert texts(infer(variables, rows, ["order"], confidence=0.9)) == ["x < y"]


def test_no_pairwise_not_equal() -> None:
    variables = floats("x", "y")
    rng = np.random.default_rng(3)
    rows = {"x": rng.normal(size=200), "y": rng.normal(size=200) + 100}
    found = infer(variables, rows, ["equality", "order"])
    assert all("!=" not in text for text in texts(found))
