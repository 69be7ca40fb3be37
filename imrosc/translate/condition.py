"""Conditions over columns: the ``<value>`` expression evaluated on a whole chunk at once.

Names in a condition are field paths of the condition topic's message; the topic's last name
segment stands for the message itself, or for its only field when it has one
(``pump_control==1`` on ``/a/pump_control`` of type std_msgs/UInt8 means ``data == 1``;
docs/config.md, "Condition expressions").
A topic operand may only name the condition's own topic, and stands for its message the same
way. A row where the condition cannot be evaluated (a missing value) does not satisfy it; the
semantics are those of the runtime engine's ``imrosc.runtime.conditions`` (one sample at a
time), which a property test compares with these columns.

>>> import numpy as np
>>> expression = {"op": "==", "args": [{"field": ["pump_control"]}, {"value": 1}]}
>>> names = resolve_fields(expression, "/a/pump_control", "pump_control", ["pump_control.data"])
>>> evaluate_mask(expression, names, {"pump_control.data": np.array([0.0, 1.0, np.nan])}).tolist()
[False, True, False]
"""

from __future__ import annotations

import functools
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np
import numpy.typing as npt

from imrosc.runtime.conditions import literal


class ConditionError(ValueError):
    """A condition that names no field of its topic, or cannot be evaluated."""


def _paths(expression: Mapping[str, Any]) -> list[tuple[Any, ...]]:
    """The field paths of the expression; a topic operand ``/a/b`` is the path ``("/a/b",)``."""
    if "field" in expression:
        return [tuple(expression["field"])]
    if "topic" in expression:
        return [(expression["topic"],)]
    found: list[tuple[Any, ...]] = []
    for argument in expression.get("args", ()):
        found += _paths(argument)
    return found


def _dotted(path: Sequence[Any]) -> str:
    text = ""
    for part in path:
        text += f"[{part}]" if isinstance(part, int) else (f".{part}" if text else str(part))
    return text


def resolve_fields(
    expression: Mapping[str, Any], topic: str, short: str, variables: Sequence[str]
) -> dict[tuple[Any, ...], str]:
    """Map each field path of ``expression`` to a variable name of the condition topic."""
    last = topic.rstrip("/").rsplit("/", 1)[-1]
    known = set(variables)
    scalars = [v for v in variables if "(" not in v]
    resolved: dict[tuple[Any, ...], str] = {}
    for path in _paths(expression):
        if isinstance(path[0], str) and path[0].startswith("/"):  # a topic operand
            if path[0] != topic:
                raise ConditionError(
                    f"the topic operand {path[0]} is not the condition's topic {topic}"
                )
            rest: tuple[Any, ...] = ()
        else:
            rest = path[1:] if path and path[0] == last else path
        if not rest:
            if len(scalars) != 1:
                raise ConditionError(
                    f"'{_dotted(path)}' stands for the message of {topic}, which has "
                    f"{len(scalars)} fields; name one"
                )
            resolved[path] = scalars[0]
            continue
        name = f"{short}.{_dotted(rest)}"
        if name not in known:
            raise ConditionError(f"{topic} has no field '{_dotted(rest)}'")
        resolved[path] = name
    return resolved


_COMPARE = {
    "==": np.equal,
    "!=": np.not_equal,
    "<": np.less,
    "<=": np.less_equal,
    ">": np.greater,
    ">=": np.greater_equal,
}
_ARITHMETIC = {"+": np.add, "-": np.subtract, "*": np.multiply, "/": np.divide, "%": np.mod}


def _value(
    node: Mapping[str, Any], names: Mapping[tuple[Any, ...], str], columns: Mapping[str, Any]
) -> Any:
    if "value" in node:
        return literal(node["value"])
    if "field" in node:
        return columns[names[tuple(node["field"])]]
    if "topic" in node:
        return columns[names[(node["topic"],)]]
    op, args = node["op"], node["args"]
    values = [_value(arg, names, columns) for arg in args]
    with np.errstate(all="ignore"):
        if op == "not":
            return np.logical_not(_truth(values[0]))
        if op == "-" and len(values) == 1:
            return np.negative(_numbers(values[0]))
        if op == "and":
            return functools.reduce(np.logical_and, [_truth(v) for v in values])
        if op == "or":
            return functools.reduce(np.logical_or, [_truth(v) for v in values])
        if op in _COMPARE:
            return _compare(op, values[0], values[1])
        if op in _ARITHMETIC:
            return _ARITHMETIC[op](_numbers(values[0]), _numbers(values[1]))
    raise ConditionError(f"unknown operator {op!r}")


def _compare(op: str, left: Any, right: Any) -> Any:
    """A comparison as Python makes it: a string equals no number, and has no order with one."""
    text = [np.asarray(v).dtype.kind in "OUS" for v in (left, right)]
    if text[0] != text[1]:
        if op not in ("==", "!="):
            raise TypeError(f"'{op}' between a string and a number")
        shape = np.broadcast_shapes(np.shape(left), np.shape(right))
        return np.full(shape, op == "!=")
    if text[0]:  # strings compare as Python objects
        left, right = np.asarray(left, dtype=object), np.asarray(right, dtype=object)
    return _COMPARE[op](left, right)


def _numbers(value: Any) -> Any:
    """Numbers as the runtime evaluator has them, float64 (booleans 0 and 1, as Python's
    arithmetic takes them): an integer modulo or division by zero is then NaN there too, not
    numpy's integer 0; strings take no arithmetic."""
    array = np.asarray(value)
    if array.dtype.kind in "OUS":
        raise TypeError("no arithmetic on strings")
    return array.astype(np.float64) if array.dtype.kind in "biu" else value


def _truth(value: Any) -> Any:
    array = np.asarray(value)
    if array.dtype.kind in "OUS":
        return np.array([bool(v) for v in array.ravel()]).reshape(array.shape)
    return np.nan_to_num(array.astype(np.float64), nan=0.0) != 0


def evaluate_mask(
    expression: Mapping[str, Any],
    names: Mapping[tuple[Any, ...], str],
    columns: Mapping[str, npt.NDArray[Any]],
    rows: int | None = None,
) -> npt.NDArray[np.bool_]:
    """Where the condition holds, row by row (``rows``: how many, when no column says)."""
    if rows is None:
        rows = len(next(iter(columns.values()))) if columns else 0
    try:
        result = _value(expression, names, columns)
    except (TypeError, ValueError) as error:
        raise ConditionError(str(error)) from None
    mask: npt.NDArray[np.bool_] = np.broadcast_to(_truth(result), (rows,)).copy()
    return mask
