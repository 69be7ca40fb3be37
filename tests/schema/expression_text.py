"""The canonical text of an expression tree, for the parser's round-trip tests: printed
with the fewest parentheses, it parses back to the same tree."""

from __future__ import annotations

import math

from imrosc.schema.expression import (
    COMPARISON_OPS,
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
)

_OR, _AND, _NOT, _COMPARE, _ADD, _MULTIPLY, _NEGATE, _ATOM = range(1, 9)
_BINARY_PRECEDENCE = {
    **dict.fromkeys(COMPARISON_OPS, _COMPARE),
    "+": _ADD,
    "-": _ADD,
    "*": _MULTIPLY,
    "/": _MULTIPLY,
    "%": _MULTIPLY,
}


def _precedence(expr: Expr) -> int:
    if isinstance(expr, Logical):
        if len(expr.operands) == 1:
            return _precedence(expr.operands[0])
        return _OR if expr.op == "or" else _AND
    if isinstance(expr, Unary):
        return _NOT if expr.op == "not" else _NEGATE
    if isinstance(expr, Binary):
        return _BINARY_PRECEDENCE.get(expr.op, _ATOM)
    if isinstance(expr, Number) and _number_text(expr.value).startswith("-"):
        return _NEGATE
    return _ATOM


def _wrapped(expr: Expr, minimum: int) -> str:
    text = to_text(expr)
    return f"({text})" if _precedence(expr) < minimum else text


def _number_text(value: int | float) -> str:
    if isinstance(value, bool):
        return "1" if value else "0"
    if isinstance(value, int):
        return str(value)
    if math.isnan(value):
        raise ExpressionError("nan has no text form")
    if math.isinf(value):
        return "1e999" if value > 0 else "-1e999"
    return repr(value)


def _string_text(value: str) -> str:
    pieces = ['"']
    for char in value:
        if char == '"':
            pieces.append('\\"')
        elif char == "\\":
            pieces.append("\\\\")
        elif char == "\n":
            pieces.append("\\n")
        elif char == "\t":
            pieces.append("\\t")
        elif char == "\r":
            pieces.append("\\r")
        elif ord(char) < 0x20 or 0x7F <= ord(char) < 0xA0 or 0xD800 <= ord(char) < 0xE000:
            pieces.append(f"\\u{ord(char):04x}")
        else:
            pieces.append(char)
    pieces.append('"')
    return "".join(pieces)


def _field_text(path: tuple[str | int, ...]) -> str:
    pieces: list[str] = []
    for segment in path:
        if isinstance(segment, int):
            pieces.append(f"[{segment}]")
        else:
            pieces.append(f".{segment}" if pieces else segment)
    return "".join(pieces)


def to_text(expr: Expr) -> str:
    """Canonical text of an expression, with the fewest parentheses; it parses back to ``expr``.

    Operators are spelled ``and``, ``or`` and ``not``, binary operators are surrounded by
    spaces, strings use double quotes. A negative :class:`Number` (never built by the parser)
    prints as ``-3``, which parses as ``Unary("-", Number(3))``.
    """
    if isinstance(expr, Number):
        return _number_text(expr.value)
    if isinstance(expr, String):
        return _string_text(expr.value)
    if isinstance(expr, Bool):
        return "true" if expr.value else "false"
    if isinstance(expr, Field):
        return _field_text(expr.path)
    if isinstance(expr, Topic):
        return expr.name
    if isinstance(expr, Unary):
        if expr.op == "not":
            return "not " + _wrapped(expr.operand, _NOT)
        operand = _wrapped(expr.operand, _NEGATE)
        # A space keeps "- -x" readable; the lexer would accept "--x" as well.
        return "-" + (f" {operand}" if operand.startswith("-") else operand)
    if isinstance(expr, Binary):
        level = _BINARY_PRECEDENCE.get(expr.op, _ATOM)
        left_minimum = level + 1 if level == _COMPARE else level
        left = _wrapped(expr.left, left_minimum)
        right = _wrapped(expr.right, level + 1)
        return f"{left} {expr.op} {right}"
    if len(expr.operands) == 1:
        return to_text(expr.operands[0])
    level = _OR if expr.op == "or" else _AND
    return f" {expr.op} ".join(_wrapped(operand, level + 1) for operand in expr.operands)
