"""Conditions of conditional points: the expression tree on one sample's fields."""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import pytest

from imrosc.runtime.conditions import holds
from imrosc.translate.condition import evaluate_mask


def field(*path: Any) -> dict[str, Any]:
    return {"field": list(path)}


def value(v: Any) -> dict[str, Any]:
    return {"value": v}


def op(name: str, *args: dict[str, Any]) -> dict[str, Any]:
    return {"op": name, "args": list(args)}


STATE = field("state")
SPEED = field("twist", "linear", "x")
FRAME = field("frame")
FIELDS = {("state",): 4.0, ("twist", "linear", "x"): 1.5, ("frame",): "map", ("flag",): 1.0}


@pytest.mark.parametrize(
    ("expression", "expected"),
    [
        (op("==", STATE, value(4)), True),
        (op("!=", STATE, value(4)), False),
        (op("<", SPEED, value(2)), True),
        (op("<=", SPEED, value(1.5)), True),
        (op(">", SPEED, value(1.5)), False),
        (op(">=", SPEED, value(1.5)), True),
        (op("==", FRAME, value("map")), True),
        (op("!=", FRAME, value("odom")), True),
        (op("==", field("flag"), value(True)), True),
        (op("and", op("==", STATE, value(4)), op(">", SPEED, value(1))), True),
        (op("and", op("==", STATE, value(4)), op(">", SPEED, value(2))), False),
        (op("and", value(1), value(2), value(0)), False),
        (op("or", op("==", STATE, value(3)), op(">", SPEED, value(2))), False),
        (op("or", op("==", STATE, value(3)), op(">", SPEED, value(1)), value(0)), True),
        (op("not", op("==", STATE, value(3))), True),
        (op("not", STATE), False),
        (op("==", op("+", STATE, value(1)), value(5)), True),
        (op("==", op("-", STATE, SPEED), value(2.5)), True),
        (op("==", op("-", SPEED), value(-1.5)), True),
        (op("==", op("*", SPEED, value(2)), value(3)), True),
        (op("==", op("/", STATE, value(8)), value(0.5)), True),
        (op("==", op("%", STATE, value(3)), value(1)), True),
        (op("==", op("%", op("-", STATE), value(3)), value(2)), True),  # floor modulo
        (op("-", SPEED, SPEED), False),  # a number is true when it is not 0
        (op("+", SPEED, value(0)), True),
        (op("==", op("/", STATE, value(0)), value(math.inf)), True),  # IEEE, as numpy
        (op("==", op("/", op("-", STATE), value(-0.0)), value(math.inf)), True),
        (op("/", value(0), value(0)), False),  # NaN
        (op("not", op("<", op("%", STATE, value(0)), value(1))), True),  # NaN < 1 is false
        (STATE, True),
        (value(0), False),
        (value(math.nan), False),
    ],
)
def test_holds(expression: dict[str, Any], expected: bool) -> None:
    assert holds(expression, FIELDS) is expected


@pytest.mark.parametrize(
    "expression",
    [
        op("==", field("missing"), value(1)),
        op("!=", field("missing"), value(1)),  # a missing value holds nothing, negated or not
        op("not", field("missing")),
        op("or", field("missing"), value(1)),  # evaluation stops at the missing value
        op("<", FRAME, value(3)),  # str < int
        op("+", FRAME, value(1)),
        op("==", op("-", FRAME), value(1)),
        op("**", STATE, value(2)),  # not an operator of the language
        op("==", STATE, value(math.nan)),
        op("<", value(math.nan), STATE),
    ],
)
def test_what_cannot_be_evaluated_does_not_hold(expression: dict[str, Any]) -> None:
    assert holds(expression, FIELDS) is False


def test_short_circuit_skips_what_is_not_needed() -> None:
    assert holds(op("and", value(0), field("missing")), FIELDS) is False
    assert holds(op("or", value(1), field("missing")), FIELDS) is True


def test_a_nan_field_value_is_a_missing_number() -> None:
    fields = {("state",): math.nan}
    assert holds(op("==", STATE, value(4)), fields) is False
    assert holds(op("<", STATE, value(4)), fields) is False
    assert holds(STATE, fields) is False


@pytest.mark.parametrize(
    "expression",
    [
        op("==", STATE, value(4)),
        op("and", op(">=", STATE, value(2)), op("<", SPEED, value(1.5))),
        op("or", op("==", STATE, value(1)), op("not", op(">", SPEED, value(1)))),
        op("==", op("%", op("+", STATE, SPEED), value(2)), value(1.5)),
        op("not", op("!=", op("*", STATE, value(0.5)), value(2))),
        op("-", STATE, value(4)),
        # division by zero: IEEE results (inf, NaN) as numpy gives them, not "no value"
        op("not", op("<", op("/", STATE, SPEED), value(1))),
        op(">", op("/", op("-", SPEED, value(1)), op("-", STATE, value(2))), value(-1)),
        op("not", op("==", op("%", STATE, SPEED), value(1))),
        op("!=", op("/", SPEED, STATE), value(0.5)),
    ],
)
def test_agrees_with_the_translators_condition_columns(expression: dict[str, Any]) -> None:
    rng = np.random.default_rng(3)
    state = rng.choice([0.0, 1.0, 2.0, 3.0, 4.0, math.nan], 200)
    speed = rng.choice([0.0, 0.5, 1.0, 1.5, 2.0, math.nan], 200)
    names = {("state",): "s.state", ("twist", "linear", "x"): "s.speed"}
    with np.errstate(all="ignore"):
        mask = evaluate_mask(expression, names, {"s.state": state, "s.speed": speed})
    for k in range(200):
        fields = {("state",): float(state[k]), ("twist", "linear", "x"): float(speed[k])}
        assert holds(expression, fields) == bool(mask[k])
