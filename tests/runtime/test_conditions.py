"""Conditions of conditional points: the expression tree on one sample's fields."""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from imrosc.runtime.conditions import holds
from imrosc.schema.expression import (
    ARITHMETIC_OPS,
    COMPARISON_OPS,
    UNARY_OPS,
    Binary,
    Bool,
    Expr,
    Field,
    Logical,
    Number,
    String,
    Topic,
    Unary,
    parse_expression,
    to_json,
)
from imrosc.translate.condition import ConditionError, evaluate_mask, resolve_fields
from tests.schema.expression_text import to_text


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


def test_every_operand_is_evaluated_as_in_the_translators_columns() -> None:
    assert holds(op("and", value(0), field("missing")), FIELDS) is False
    assert holds(op("or", value(1), field("missing")), FIELDS) is False
    assert holds(op("or", STATE, op("-", FRAME)), FIELDS) is False  # a type error anywhere


def test_a_topic_operand_is_the_value_at_its_path() -> None:
    topic = {"topic": "/a/subject_ctrl_state"}
    fields = {("/a/subject_ctrl_state",): 4.0}
    assert holds(op("==", topic, value(4)), fields) is True
    assert holds(op("==", topic, value(3)), fields) is False
    assert holds(op("==", topic, value(4)), {}) is False


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


# -- one semantics: the runtime evaluator against the translator's masks, on random trees ----

_NUMBERS = [0.0, 1.0, -1.0, 2.5, 4.0, math.nan, math.inf, -math.inf, -0.0]
_TOPIC = "/a/state"
_NAMES = {("state",): "s.state", ("speed",): "s.speed", ("frame",): "s.frame", (_TOPIC,): "s.state"}
_LEAVES = st.one_of(
    st.sampled_from([Field(("state",)), Field(("speed",)), Field(("frame",)), Topic(_TOPIC)]),
    st.one_of(st.integers(-5, 5), st.sampled_from([0.5, 2.5, 1e300, 10**30, 2**63, 10**400])).map(
        Number
    ),
    st.booleans().map(Bool),
    st.sampled_from(["map", ""]).map(String),
)


def _grow(children: st.SearchStrategy[Expr]) -> st.SearchStrategy[Expr]:
    unary = st.builds(Unary, st.sampled_from(sorted(UNARY_OPS)), children)
    ops = sorted(ARITHMETIC_OPS | COMPARISON_OPS)
    binary = st.builds(Binary, st.sampled_from(ops), children, children)
    logical = st.builds(
        Logical,
        st.sampled_from(["and", "or"]),
        st.lists(children, min_size=2, max_size=3).map(tuple),
    )
    return st.one_of(unary, binary, logical)


@settings(max_examples=400, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(st.recursive(_LEAVES, _grow, max_leaves=8), st.integers(0, 2**32 - 1))
def test_the_runtime_evaluator_and_the_translators_masks_agree(expr: Expr, seed: int) -> None:
    expression = to_json(expr)
    rng = np.random.default_rng(seed)
    rows = 16
    state, speed = rng.choice(_NUMBERS, rows), rng.choice(_NUMBERS, rows)
    frame = np.array(rng.choice(["map", "odom", ""], rows).tolist(), dtype=object)
    columns = {"s.state": state, "s.speed": speed, "s.frame": frame}
    try:
        with np.errstate(all="ignore"):
            mask = evaluate_mask(expression, _NAMES, columns, rows)
    except ConditionError:  # the translator keeps no row of a condition it cannot evaluate
        mask = np.zeros(rows, dtype=bool)
    for k in range(rows):
        fields = {
            ("state",): float(state[k]),
            ("speed",): float(speed[k]),
            ("frame",): frame[k],
            (_TOPIC,): float(state[k]),
        }
        assert holds(expression, fields) is bool(mask[k]), (to_text(expr), fields)


def test_a_constant_condition_gives_a_mask_of_every_row() -> None:
    assert evaluate_mask(to_json(Bool(True)), {}, {}, 3).tolist() == [True] * 3
    one_is_one = Binary("==", Number(1), Number(1))
    assert evaluate_mask(to_json(one_is_one), {}, {}, 2).tolist() == [True] * 2


def test_a_topic_operand_resolves_to_the_conditions_own_topic_only() -> None:
    expression = to_json(parse_expression("/a/subject_ctrl_state == 4"))
    variables = ["subject_ctrl_state.data"]
    names = resolve_fields(expression, "/a/subject_ctrl_state", "subject_ctrl_state", variables)
    assert names == {("/a/subject_ctrl_state",): "subject_ctrl_state.data"}
    with pytest.raises(ConditionError, match="not the condition's topic"):
        resolve_fields(expression, "/a/other", "other", ["other.data"])


def test_a_modulo_of_booleans_by_zero_is_nan_in_both_evaluators() -> None:
    """``state != false % false``: NaN (numpy's float modulo by zero), so the field differs,
    in the runtime evaluator and in the translator's masks alike (numpy's integer modulo gave
    0 there)."""
    expression = {
        "op": "!=",
        "args": [{"field": ["state"]}, {"op": "%", "args": [{"value": False}, {"value": False}]}],
    }
    columns = {"s.state": np.array([0.0, 1.0])}
    with np.errstate(all="ignore"):
        mask = evaluate_mask(expression, _NAMES, columns, 2)
    assert mask.tolist() == [True, True]
    assert holds(expression, {("state",): 0.0}) is True
