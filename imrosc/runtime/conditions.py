"""Conditions of conditional program points, evaluated on one sample.

A declared ``<condition>`` is an expression (the JSON tree of
``imrosc.schema.expression``) over fields of the condition topic's latest message; a
discovered condition is ``variable == value`` on the point's own sample. A condition that
cannot be evaluated (a missing value, a type error) does not hold, as in inference.

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


def _value(node: Mapping[str, Any], fields: Mapping[Tuple[Any, ...], Any]) -> Any:
    if "value" in node:
        return node["value"]
    if "field" in node:
        key = tuple(node["field"])
        if key not in fields:
            raise _MissingValueError(key)
        return fields[key]
    op, args = node["op"], node["args"]
    if op == "and":
        return all(_truth(_value(a, fields)) for a in args)
    if op == "or":
        return any(_truth(_value(a, fields)) for a in args)
    values = [_value(a, fields) for a in args]
    if op == "not":
        return not _truth(values[0])
    if op == "-" and len(values) == 1:
        return -values[0]
    if op in _COMPARE:
        return _COMPARE[op](values[0], values[1])
    if op in _ARITHMETIC:
        return _ARITHMETIC[op](values[0], values[1])
    raise ValueError(f"unknown operator {op!r}")


def holds(expression: Mapping[str, Any], fields: Mapping[Tuple[Any, ...], Any]) -> bool:
    """Whether ``expression`` holds for the field values ``fields`` (path tuple -> value)."""
    try:
        return _truth(_value(expression, fields))
    except (_MissingValueError, TypeError, ValueError, ZeroDivisionError, OverflowError):
        return False
