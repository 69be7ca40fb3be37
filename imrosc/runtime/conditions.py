"""Conditions of conditional program points, evaluated on one sample.

A declared ``<condition>`` is an expression (the JSON tree of
``imrosc.schema.expression``) over fields of the condition topic's latest message; a
discovered condition is ``variable == value`` on the point's own sample.

One semantics with the translator's columns (``imrosc.translate.condition``, which inference
uses; a property test compares the two): a topic operand ``/a/b`` is the value at the path
``("/a/b",)``; integer literals are floats; booleans are 0 and 1 in arithmetic; strings take
no arithmetic, equal no number and have no order with one; NaN is false; every operand is
evaluated (no short circuit), and a condition that cannot be evaluated (a missing value, a
type error) does not hold.

>>> expression = {"op": "==", "args": [{"field": ["state"]}, {"value": 4}]}
>>> holds(expression, {("state",): 4.0}), holds(expression, {("state",): float("nan")})
(True, False)
"""

from __future__ import annotations

import math
import operator
from typing import Any, Callable, Dict, Mapping, Tuple

_COMPARE: Dict[str, Callable[[Any, Any], Any]] = {
    "==": operator.eq,
    "!=": operator.ne,
    "<": operator.lt,
    "<=": operator.le,
    ">": operator.gt,
    ">=": operator.ge,
}


def _divide(a: Any, b: Any) -> Any:
    """``a / b`` as the translator's numpy computes it: by zero, +-inf or NaN (so a
    condition such as ``not (x / y < 1)`` accepts the samples inference accepted)."""
    try:
        return operator.truediv(a, b)
    except ZeroDivisionError:
        a = float(a)
        if a == 0 or math.isnan(a):
            return math.nan
        return math.copysign(math.inf, a) * math.copysign(1.0, float(b))


def _modulo(a: Any, b: Any) -> Any:
    """``a % b`` as numpy computes it: NaN by zero."""
    try:
        return operator.mod(a, b)
    except ZeroDivisionError:
        return math.nan


_ARITHMETIC: Dict[str, Callable[[Any, Any], Any]] = {
    "+": operator.add,
    "-": operator.sub,
    "*": operator.mul,
    "/": _divide,
    "%": _modulo,
}


class _MissingValueError(Exception):
    """A value the condition needs is not there."""


def _truth(value: Any) -> bool:
    if isinstance(value, float) and math.isnan(value):
        return False
    return bool(value)


def _number(value: Any) -> Any:
    """A number for arithmetic (booleans are 0 and 1); strings take no arithmetic."""
    if isinstance(value, (str, bytes)):
        raise TypeError(f"no arithmetic on {value!r}")
    return value


def literal(value: Any) -> Any:
    """A literal as the evaluators take it: an integer is a float (too large for one, an
    infinity), as a message's numeric fields are; strings and booleans as they are."""
    if isinstance(value, int) and not isinstance(value, bool):
        try:
            return float(value)
        except OverflowError:
            return math.inf if value > 0 else -math.inf
    return value


def _value(node: Mapping[str, Any], fields: Mapping[Tuple[Any, ...], Any]) -> Any:
    if "value" in node:
        return literal(node["value"])
    if "field" in node or "topic" in node:
        key = tuple(node["field"]) if "field" in node else (node["topic"],)
        if key not in fields:
            raise _MissingValueError(key)
        return fields[key]
    op, args = node["op"], node["args"]
    values = [_value(a, fields) for a in args]  # every operand, as the translator's columns
    if op == "and":
        return all([_truth(v) for v in values])
    if op == "or":
        return any([_truth(v) for v in values])
    if op == "not":
        return not _truth(values[0])
    if op == "-" and len(values) == 1:
        return -_number(values[0])
    if op in _COMPARE:
        return _COMPARE[op](values[0], values[1])
    if op in _ARITHMETIC:
        return _ARITHMETIC[op](_number(values[0]), _number(values[1]))
    raise ValueError(f"unknown operator {op!r}")


def holds(expression: Mapping[str, Any], fields: Mapping[Tuple[Any, ...], Any]) -> bool:
    """Whether ``expression`` holds for the field values ``fields`` (path tuple -> value)."""
    try:
        return _truth(_value(expression, fields))
    except (_MissingValueError, TypeError, ValueError, ZeroDivisionError, OverflowError):
        return False
