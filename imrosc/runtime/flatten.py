"""Flattening one message into the values of its topic's layout.

The invariants file lists, per topic, its variables in order with their field path and
type (``pose.position.x``; ``ranges`` with ``derived`` ``len``/``avg``/``std``/``min``/
``max``; ``values[3]`` for an element of a short array). :func:`make_flattener` turns that
list into one function from a message object (rospy, rclpy or rosbags: they share field
names) to the list of values, in the same order: field access through
``operator.attrgetter`` (C speed), the statistics with numpy as the translator computes
them (``std`` is the population deviation; an empty array has no average).

>>> from types import SimpleNamespace as M
>>> flat = make_flattener([
...     {"name": "t.x", "path": "x", "type": "float", "derived": None},
...     {"name": "t.v[1]", "path": "v[1]", "type": "float", "derived": None},
...     {"name": "avg(t.v)", "path": "v", "type": "float", "derived": "avg"},
...     {"name": "t.frame", "path": "frame", "type": "string", "derived": None}])
>>> flat(M(x=1, v=[1.0, 3.0], frame="map"))
[1.0, 3.0, 2.0, 'map']
"""

from __future__ import annotations

import math
import operator
import re
from typing import Any, Callable, List, Mapping, Sequence

import numpy as np

_ELEMENT = re.compile(r"^(.*)\[(\d+)\]$")


def _number(value: Any) -> float:
    try:
        return float(value)
    except (TypeError, ValueError):
        return math.nan


def _statistic(kind: str) -> Callable[[Any], float]:
    def compute(array: Any) -> float:
        if kind == "len":
            return float(len(array))
        if not len(array):
            return math.nan
        try:
            values = np.asarray(array, dtype=np.float64)
        except (TypeError, ValueError):
            return math.nan
        with np.errstate(all="ignore"):
            if kind == "avg":
                return float(values.mean())
            if kind == "std":
                return float(values.std())
            return float(values.min() if kind == "min" else values.max())

    return compute


def _element(path: str, index: int) -> Callable[[Any], Any]:
    get = operator.attrgetter(path)

    def pick(message: Any) -> Any:
        array = get(message)
        return array[index] if index < len(array) else math.nan

    return pick


def _accessor(variable: Mapping[str, Any]) -> Callable[[Any], Any]:
    path = variable["path"]
    derived = variable.get("derived")
    if derived:
        get = operator.attrgetter(path)
        stat = _statistic(derived)
        return lambda message: stat(get(message))
    element = _ELEMENT.match(path)
    if element:
        return _element(element.group(1), int(element.group(2)))
    return operator.attrgetter(path)


def make_flattener(variables: Sequence[Mapping[str, Any]]) -> Callable[[Any], List[Any]]:
    """A function from a message to its values in ``variables`` order."""
    accessors = [_accessor(v) for v in variables]
    strings = [v["type"] == "string" for v in variables]

    def flatten(message: Any) -> List[Any]:
        values: List[Any] = []
        for access, text in zip(accessors, strings):
            try:
                value = access(message)
            except (AttributeError, IndexError, TypeError):
                value = "" if text else math.nan
            values.append(str(value) if text else _number(value))
        return values

    return flatten
