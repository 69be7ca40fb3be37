"""rospy messages as the monitor reads and fills them, without rospy: plain functions.

A message (anything with ``__slots__``: genpy's classes, and the stand-ins of the tests) as
JSON-like data (:func:`message_data`, which ``onboard``'s
:func:`~imrosc.onboard.monitor.call_values` turns into the values the engine reads), and an
action's YAML value filled into a message by its ``__slots__`` and ``_slot_types``
(:func:`fill`; each value checked by :mod:`imrosc.onboard.fill`). Python 3.8 syntax,
standard library only.

>>> message_data([(1, 2), "x"])
[[1, 2], 'x']
"""

from __future__ import annotations

from typing import Any, Callable, Mapping, Optional

from .. import fill as check
from ..fill import FillError

__all__ = ["FillError", "fill", "message_data"]

_INTEGER_RANGES = dict(check.INTEGER_RANGES, byte=(-(2**7), 2**8 - 1), char=(0, 2**8 - 1))
"""ROS 1's integer types: ``byte`` (int8, written from unsigned bytes too) and ``char``
(uint8) besides those both middlewares name alike."""


def message_data(message: Any) -> Any:
    """A ROS message (anything with ``__slots__``) as JSON-like data; times in seconds."""
    slots = getattr(message, "__slots__", None)
    if slots is None:
        if isinstance(message, (list, tuple)):
            return [message_data(item) for item in message]
        return message
    for seconds, nanos in (("secs", "nsecs"), ("sec", "nanosec")):
        if set(slots) == {seconds, nanos}:  # genpy.Time, builtin_interfaces/Time
            return float(getattr(message, seconds)) + float(getattr(message, nanos)) / 1e9
    return {name: message_data(getattr(message, name)) for name in slots}


def _scalar(kind: str, value: Any, where: str) -> Any:
    if kind == "bool":
        return check.boolean(value, where)
    if kind in _INTEGER_RANGES:
        return check.integer(kind, value, where, _INTEGER_RANGES)
    if kind in ("float32", "float64"):
        return check.number(value, where)
    if kind == "string":
        return check.text(value, where)
    raise FillError(f"{where}: cannot fill a field of type {kind}")


def _element_kind(kind: str) -> Optional[str]:
    at = kind.find("[")
    return kind[:at] if at >= 0 else None


def _convert(
    current: Any,
    kind: str,
    value: Any,
    where: str,
    message_class: Callable[[str], Any],
) -> Any:
    element = _element_kind(kind)
    if element is not None:
        if not isinstance(value, list):
            raise FillError(f"{where}: {value!r} is not a list")
        items = [
            _convert(None, element, item, f"{where}[{k}]", message_class)
            for k, item in enumerate(value)
        ]
        if element in ("uint8", "char"):
            return bytes(items)
        return items
    if isinstance(value, dict):
        if hasattr(current, "__slots__"):
            return fill(current, value, message_class, where + ".")
        if "/" in kind or kind == "Header":
            return fill(message_class(kind)(), value, message_class, where + ".")
        raise FillError(f"{where}: a mapping cannot fill a field of type {kind}")
    if kind in ("time", "duration"):
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise FillError(f"{where}: {value!r} is not a number of seconds")
        if current is not None and hasattr(type(current), "from_sec"):
            return type(current).from_sec(float(value))
        raise FillError(f"{where}: cannot build a {kind} here")
    if "/" in kind or kind in ("Header",):
        raise FillError(f"{where}: {value!r} is not a mapping of {kind}")
    return _scalar(kind, value, where)


def _kinds(message: Any) -> Mapping[str, str]:
    """The fields of a rospy message (``__slots__``) and their types (``_slot_types``, or
    the values' own where a class does not list them: ``genpy.Time``)."""
    slots = list(getattr(message, "__slots__", ()))
    types = list(getattr(message, "_slot_types", ()))
    if len(types) == len(slots):
        return dict(zip(slots, types))
    return {slot: _kind_of(getattr(message, slot)) for slot in slots}


fill = check.filler(_kinds, _convert)
"""Set the fields of a rospy message from an action value (``{linear: {x: 0.5}}``); return
the message (:func:`imrosc.onboard.fill.filler`)."""


def _kind_of(current: Any) -> str:
    """The field type of a value whose message does not list its types (``genpy.Time``)."""
    if isinstance(current, bool):
        return "bool"
    if isinstance(current, int):
        return "int64"
    if isinstance(current, float):
        return "float64"
    if isinstance(current, str):
        return "string"
    return ""
