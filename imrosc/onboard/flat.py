"""Helpers of the generated flatteners (``flatteners.py`` of a monitor package).

A generated flattener reads every value of its topic's layout by straight-line field access
(``float(m.pose.position.x)``); array elements and statistics go through the functions
below. They compute
exactly what ``imrosc.runtime.flatten.make_flattener`` computes: an element past the end is
NaN, ``len`` is the array's
length, ``avg``/``std``/``min``/``max`` are numpy's (``std`` the population deviation), an
empty array has no statistic (NaN) and a value that is not numeric gives NaN. When a field is
missing or a value does not convert, the flattener falls back to :func:`careful`, which reads
each value on its own as ``make_flattener`` does.

The node switches numpy's floating-point warnings off (``np.seterr(all="ignore")``), so these
functions do not wrap their work in ``np.errstate``.

A blocked topic's values read from the bytes it came in (``monitor_ros1/wire.py``,
``monitor_ros2/cdr.py``) are the flattener's too: both byte readers match the topic's
variables to the message's fields with :func:`match` and give the values through
:func:`walker`, with the helpers above.

>>> avg_([1.0, 2.0, 6.0]), len_([]), max_([]) != max_([])
(3.0, 0.0, True)
>>> careful(object(), [(lambda m: m.x, False), (lambda m: m.name, True)])
[nan, '']
"""

from __future__ import annotations

import math
import re
from typing import Any, Callable, Dict, List, Mapping, Optional, Sequence, Tuple, TypeVar

import numpy as np

Field = Tuple[Callable[[Any], Any], bool]
"""How to read one value (raw) and whether it is a string."""


def number(value: Any) -> float:
    """``value`` as a float; NaN when it is not a number."""
    try:
        return float(value)
    except (TypeError, ValueError):
        return math.nan


def at_(array: Any, index: int) -> Any:
    """Element ``index`` of an array; NaN when the array is shorter."""
    return array[index] if index < len(array) else math.nan


def len_(array: Any) -> float:
    """The length of an array."""
    return float(len(array))


def _values(array: Any) -> Any:
    if not len(array):
        return None
    try:
        return np.asarray(array, dtype=np.float64)
    except (TypeError, ValueError):
        return None


def avg_(array: Any) -> float:
    """The mean of an array (NaN if empty or not numeric)."""
    values = _values(array)
    return math.nan if values is None else float(values.mean())


def std_(array: Any) -> float:
    """The population standard deviation of an array."""
    values = _values(array)
    return math.nan if values is None else float(values.std())


def min_(array: Any) -> float:
    """The smallest element of an array."""
    values = _values(array)
    return math.nan if values is None else float(values.min())


def max_(array: Any) -> float:
    """The largest element of an array."""
    values = _values(array)
    return math.nan if values is None else float(values.max())


def careful(message: Any, fields: Sequence[Field]) -> List[Any]:
    """Each value read on its own: a missing field gives NaN (or ``""`` for a string)."""
    values: List[Any] = []
    for read, text in fields:
        try:
            value = read(message)
        except (AttributeError, IndexError, TypeError):
            value = "" if text else math.nan
        values.append(str(value) if text else number(value))
    return values


STATISTICS: Dict[str, Callable[[Any], float]] = {
    "len": len_,
    "avg": avg_,
    "std": std_,
    "min": min_,
    "max": max_,
}
"""A derived variable's statistic of its array, by name."""
VARIABLE_PATH = re.compile(
    r"^(?P<fields>[A-Za-z][A-Za-z0-9_]*(?:\.[A-Za-z][A-Za-z0-9_]*)*)(?:\[(?P<index>\d+)\])?$"
)
"""A variable's path in its message: the fields, then an element's index."""


class UnsupportedError(Exception):
    """A byte reader's layout needs what its plan does not read (the ROS 1 wire reader's and
    the ROS 2 CDR reader's): the node decodes the message instead."""


Built = TypeVar("Built")


def unless_unsupported(build: Callable[..., Built]) -> Callable[..., Optional[Built]]:
    """``build`` giving ``None`` where it raises :class:`UnsupportedError`: a byte reader's
    plan (the ROS 1 wire reader's and the ROS 2 CDR reader's) that cannot read a topic's
    layout, whose node decodes the messages instead.

    >>> def plan(ok):
    ...     if not ok:
    ...         raise UnsupportedError("no field 'x'")
    ...     return "plan"
    >>> unless_unsupported(plan)(True), unless_unsupported(plan)(False)
    ('plan', None)
    """

    def built(*args: Any) -> Optional[Built]:
        try:
            return build(*args)
        except UnsupportedError:
            return None

    return built


Wanted = Tuple[int, Optional[int], Optional[str], bool]
"""A variable as a byte reader reads it: its leaf, its element's index, its statistic and
whether it is a string."""


def match(
    variables: Sequence[Mapping[str, Any]], leaves: Sequence[Tuple[str, str]]
) -> List[Wanted]:
    """Each variable of a topic's layout as the leaf a byte reader takes it from (the ROS 1
    wire reader's and the ROS 2 CDR reader's). ``leaves`` are the message's leaves in
    serialisation order, each its path and its kind: ``scalar`` (a number), ``string``,
    ``array`` (of numbers: its elements and statistics are variables), or any other kind, from
    which no variable is read. A variable the leaves do not give raises
    :class:`UnsupportedError`.

    >>> match([{"path": "values[1]"}, {"path": "frame", "type": "string"}],
    ...       [("frame", "string"), ("values", "array")])
    [(1, 1, None, False), (0, None, None, True)]
    """
    by_path = {path: k for k, (path, _) in enumerate(leaves)}
    wanted: List[Wanted] = []
    for variable in variables:
        path = str(variable.get("path", ""))
        found = VARIABLE_PATH.match(path)
        if found is None or found.group("fields") not in by_path:
            raise UnsupportedError(f"no field {path!r}")
        leaf = by_path[found.group("fields")]
        index = int(found.group("index")) if found.group("index") is not None else None
        derived = variable.get("derived")
        text = variable.get("type") == "string"
        kind = leaves[leaf][1]
        if derived is not None:
            if derived not in STATISTICS or index is not None or text or kind != "array":
                raise UnsupportedError(f"statistic {derived!r} of {kind} {path!r}")
        elif index is not None:
            if kind != "array" or text:
                raise UnsupportedError(f"element of {kind} {path!r}")
        elif kind != ("string" if text else "scalar"):
            raise UnsupportedError(f"{kind} {path!r} read as {variable.get('type')}")
        wanted.append((leaf, index, derived, text))
    return wanted


def converter(index: Optional[int], derived: Optional[str], text: bool) -> Callable[[Any], Any]:
    """What makes a byte reader's raw field a variable's value: its statistic, its element,
    or the field as a string or a number."""
    if derived is not None:
        return STATISTICS[derived]
    if index is not None:
        return lambda array: float(at_(array, index))
    return str if text else float


Step = Callable[[bytes, int, List[Any]], int]
"""One step of a byte reader's plan: reads from the bytes at an offset, appends what it keeps,
returns the next offset."""


def walker(
    steps: Sequence[Step], wanted: Sequence[Wanted], start: Callable[[bytes], int]
) -> Callable[[bytes], List[Any]]:
    """A byte reader: walk ``steps`` over a message's bytes from ``start(data)``, then give
    each variable its value as the generated flattener computes it (``wanted``'s leaf is the
    variable's slot among the values the steps keep).

    >>> def two(data, offset, got):
    ...     got.extend(data[offset:offset + 2])
    ...     return offset + 2
    >>> walker([two], [(1, None, None, False), (0, None, None, True)], lambda data: 1)(b"xAB")
    [66.0, '65']
    """
    pairs = [(converter(index, derived, text), slot) for slot, index, derived, text in wanted]

    def values(data: bytes) -> List[Any]:
        got: List[Any] = []
        offset = start(data)
        for step in steps:
            offset = step(data, offset, got)
        return [make(got[slot]) for make, slot in pairs]

    return values
