"""Tests for condition value expressions."""

from __future__ import annotations

import math
import string

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from imrosc.schema.expression import (
    MAX_HEIGHT,
    MAX_NESTING,
    Binary,
    Bool,
    Expr,
    ExpressionError,
    Field,
    Logical,
    Number,
    String,
    Topic,
    Unary,
    fields,
    parse_expression,
    to_json,
)
from tests.schema.expression_text import to_text


def f(*path: str | int) -> Field:
    return Field(path)


@pytest.mark.parametrize(
    ("text", "tree"),
    [
        ("pump_control==1", Binary("==", f("pump_control"), Number(1))),
        ("pump_control == 1", Binary("==", f("pump_control"), Number(1))),
        ("/a/pump_control == 1", Binary("==", Topic("/a/pump_control"), Number(1))),
        ("x / 2", Binary("/", f("x"), Number(2))),
        ("x/y", Binary("/", f("x"), f("y"))),
        ("/a/b / /c", Binary("/", Topic("/a/b"), Topic("/c"))),
        ("(/a)", Topic("/a")),
        ("ranges[0]", f("ranges", 0)),
        ("pose.position.x", f("pose", "position", "x")),
        ("a.b[2][3].c_d", f("a", "b", 2, 3, "c_d")),
        ("2.5", Number(2.5)),
        (".5", Number(0.5)),
        ("1e3", Number(1000.0)),
        ("1E-3", Number(0.001)),
        ("1.", Number(1.0)),
        ("-3", Unary("-", Number(3))),
        ("'it\\'s'", String("it's")),
        ('"a\\n\\t\\\\\\"\\u00e9"', String('a\n\t\\"é')),
        ("true", Bool(True)),
        ("False", Bool(False)),
        ("not a", Unary("not", f("a"))),
        ("!a", Unary("not", f("a"))),
        ("! !a", Unary("not", Unary("not", f("a")))),
        ("a != b", Binary("!=", f("a"), f("b"))),
        ("a and b && c", Logical("and", (f("a"), f("b"), f("c")))),
        ("a || (b or c)", Logical("or", (f("a"), f("b"), f("c")))),
        (
            "a or b and c",
            Logical("or", (f("a"), Logical("and", (f("b"), f("c"))))),
        ),
        ("not a == b", Unary("not", Binary("==", f("a"), f("b")))),
        (
            "1 + 2 * 3 - 4",
            Binary("-", Binary("+", Number(1), Binary("*", Number(2), Number(3))), Number(4)),
        ),
        ("a - (b - c)", Binary("-", f("a"), Binary("-", f("b"), f("c")))),
        ("-a % 2", Binary("%", Unary("-", f("a")), Number(2))),
        ("(a < b) == true", Binary("==", Binary("<", f("a"), f("b")), Bool(True))),
        ("a<=b", Binary("<=", f("a"), f("b"))),
        ("a>=-1", Binary(">=", f("a"), Unary("-", Number(1)))),
        ("trueish", f("trueish")),
    ],
)
def test_parse_known_answers(text: str, tree: Expr) -> None:
    assert parse_expression(text) == tree


@pytest.mark.parametrize(
    ("text", "canonical"),
    [
        ("pump_control==1", "pump_control == 1"),
        ("a&&b||!c", "a and b or not c"),
        ("(a or b) and c", "(a or b) and c"),
        ("((a))", "a"),
        ("(1+2)*3", "(1 + 2) * 3"),
        ("1+(2*3)", "1 + 2 * 3"),
        ("-(-x)", "- -x"),
        ("-(a+b)", "-(a + b)"),
        ("not (a and b)", "not (a and b)"),
        ("'x'", '"x"'),
        ("a [ 0 ] . b", "a[0].b"),
        ("1e999", "1e999"),
        ("(a<b)==(c<d)", "(a < b) == (c < d)"),
    ],
)
def test_to_text_is_canonical(text: str, canonical: str) -> None:
    assert to_text(parse_expression(text)) == canonical


@pytest.mark.parametrize(
    ("text", "offset", "message"),
    [
        ("", 0, "expression is empty"),
        ("  ", 0, "expression is empty"),
        ("a < b < c", 6, "comparisons cannot be chained"),
        ("a == b != c", 7, "comparisons cannot be chained"),
        ("(a", 0, "unbalanced '('"),
        ("a)", 1, "unbalanced ')'"),
        ("()", 1, "unexpected ')'"),
        ("a =b", 2, "unexpected '='"),
        ("a & b", 2, "unexpected '&'"),
        ("a | b", 2, "unexpected '|'"),
        ("a +", 3, "expression ends where an operand is expected"),
        ("a b", 2, "missing operator before 'b'"),
        ("(a b)", 3, "expected ')'"),
        ("1abc", 0, "invalid number"),
        ("1.2.3", 0, "invalid number"),
        ("a.", 2, "expected a field name after '.'"),
        ("a.1", 2, "expected a field name after '.'"),
        ("a.and", 2, "expected a field name after '.'"),
        ("a[", 2, "expected a non-negative integer index"),
        ("a[-1]", 2, "expected a non-negative integer index"),
        ("a[1.5]", 2, "expected a non-negative integer index"),
        ("a[1", 3, "expected ']'"),
        ("/", 0, "topic name '/' is the root namespace"),
        ("/a//b == 1", 3, "topic name '/a//b' has an empty token"),
        ("x == /a/", 7, "topic name '/a/' ends with '/'"),
        ("'abc", 0, "unterminated string"),
        ('"a\\q"', 2, "unknown escape"),
        ('"\\u12"', 1, "'\\u' needs four hexadecimal digits"),
        ("a @ b", 2, "unexpected character '@'"),
        ("a == ", 5, "expression ends where an operand is expected"),
        ("1" * 5000, 0, "integer literal is too long"),
        ("not", 3, "expression ends where an operand is expected"),
    ],
)
def test_errors_have_messages_and_offsets(text: str, offset: int, message: str) -> None:
    with pytest.raises(ExpressionError) as caught:
        parse_expression(text)
    assert caught.value.offset == offset
    assert caught.value.message.startswith(message)


def test_nesting_is_limited() -> None:
    ok = "(" * MAX_NESTING + "a" + ")" * MAX_NESTING
    assert parse_expression(ok) == f("a")
    for deep in (
        "(" * (MAX_NESTING + 1) + "a" + ")" * (MAX_NESTING + 1),
        "-" * (MAX_NESTING + 1) + "a",
        "not " * (MAX_NESTING + 1) + "a",
        "(" * 100000,
    ):
        with pytest.raises(ExpressionError) as caught:
            parse_expression(deep)
        assert "nested deeper" in caught.value.message


def test_tree_height_is_limited() -> None:
    parse_expression("+".join(["1"] * (MAX_HEIGHT - 1)))
    with pytest.raises(ExpressionError) as caught:
        parse_expression("+".join(["1"] * 100000))
    assert "nested deeper" in caught.value.message
    # Flat and/or chains do not grow the tree.
    assert isinstance(parse_expression(" or ".join(["a"] * 10000)), Logical)


def test_fields() -> None:
    tree = parse_expression("pose.x > 1 and ranges[0] < pose.x or not /a/b and armed")
    assert fields(tree) == frozenset({("pose", "x"), ("ranges", 0), ("armed",)})
    assert fields(parse_expression("1 + 2")) == frozenset()


def test_to_json_shapes() -> None:
    tree = parse_expression("pump_control == 1 and not -pose.x < 2.5 or /a/b != 'on'")
    assert to_json(tree) == {
        "op": "or",
        "args": [
            {
                "op": "and",
                "args": [
                    {"op": "==", "args": [{"field": ["pump_control"]}, {"value": 1}]},
                    {
                        "op": "not",
                        "args": [
                            {
                                "op": "<",
                                "args": [
                                    {"op": "-", "args": [{"field": ["pose", "x"]}]},
                                    {"value": 2.5},
                                ],
                            }
                        ],
                    },
                ],
            },
            {"op": "!=", "args": [{"topic": "/a/b"}, {"value": "on"}]},
        ],
    }
    assert to_json(parse_expression("ranges[3] == true")) == {
        "op": "==",
        "args": [{"field": ["ranges", 3]}, {"value": True}],
    }


# -- properties --------------------------------------------------------------------------------

_KEYWORDS = {"and", "or", "not", "true", "false", "True", "False"}
_identifiers = st.from_regex(r"[A-Za-z_][A-Za-z0-9_]{0,6}", fullmatch=True).filter(
    lambda name: name not in _KEYWORDS
)
_topic_names = st.lists(
    st.from_regex(r"[A-Za-z][A-Za-z0-9_]{0,5}", fullmatch=True), min_size=1, max_size=3
).map(lambda tokens: "/" + "/".join(tokens))
_numbers = st.one_of(
    st.integers(min_value=0, max_value=10**30),
    st.floats(min_value=0.0, allow_nan=False).filter(lambda value: math.copysign(1, value) > 0),
)
_leaves: st.SearchStrategy[Expr] = st.one_of(
    _numbers.map(Number),
    st.text(max_size=8).map(String),
    st.booleans().map(Bool),
    st.tuples(_identifiers, st.lists(st.one_of(_identifiers, st.integers(0, 99)), max_size=3)).map(
        lambda parts: Field((parts[0], *parts[1]))
    ),
    _topic_names.map(Topic),
)


def _logical(op: str, operands: list[Expr]) -> Expr:
    flat: list[Expr] = []
    for operand in operands:
        if isinstance(operand, Logical) and operand.op == op:
            flat.extend(operand.operands)
        else:
            flat.append(operand)
    return Logical(op, tuple(flat))


_ARITHMETIC_AND_COMPARISON = ["+", "-", "*", "/", "%", "==", "!=", "<", "<=", ">", ">="]


def _extend(children: st.SearchStrategy[Expr]) -> st.SearchStrategy[Expr]:
    return st.one_of(
        st.tuples(st.sampled_from(["-", "not"]), children).map(lambda t: Unary(t[0], t[1])),
        st.tuples(st.sampled_from(_ARITHMETIC_AND_COMPARISON), children, children).map(
            lambda t: Binary(t[0], t[1], t[2])
        ),
        st.tuples(st.sampled_from(["and", "or"]), st.lists(children, min_size=2, max_size=3)).map(
            lambda t: _logical(t[0], t[1])
        ),
    )


expressions: st.SearchStrategy[Expr] = st.recursive(_leaves, _extend, max_leaves=12)

_expression_chars = st.text(st.sampled_from("ab1.0[]()/'\"\\=<>!&|+-*% ntoe_"), max_size=30)


@settings(deadline=None)
@given(st.one_of(st.text(), _expression_chars))
def test_parse_never_raises_anything_else(text: str) -> None:
    try:
        tree = parse_expression(text)
    except ExpressionError as error:
        assert 0 <= error.offset <= len(text)
        assert error.message
    else:
        assert parse_expression(to_text(tree)) == tree


@settings(deadline=None)
@given(expressions)
def test_generated_expressions_round_trip_through_text(tree: Expr) -> None:
    text = to_text(tree)
    assert parse_expression(text) == tree
    assert to_text(parse_expression(text)) == text


def test_identifier_alphabet_is_ascii() -> None:
    with pytest.raises(ExpressionError):
        parse_expression("é == 1")
    assert parse_expression(string.ascii_letters) == Field((string.ascii_letters,))
