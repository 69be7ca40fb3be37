"""Checking an action's value against a message field, for both monitor nodes.

An action (``<action><value>{data: 3}</value>``) fills a message the node publishes or a
request it sends. The walk over the value's fields is here (:func:`filler`); each middleware
says what a message's fields are and converts a field's value (``monitor_ros1/messages.py``:
rospy's ``__slots__`` and ``_slot_types``; ``monitor_ros2/logic.py``: rclpy's
``get_fields_and_field_types``); the value of one scalar field is checked here, alike for
both: an integer in the range of its type, a number, a bool, a string. Python 3.8 syntax,
standard library only.

>>> integer("uint8", 255.0, "data"), number(3, "x"), boolean(1, "b"), text(2.5, "s")
(255, 3.0, True, '2.5')
"""

from __future__ import annotations

import json
from typing import Any, Callable, Mapping, Protocol, Tuple

INTEGER_RANGES = {
    "int8": (-(2**7), 2**7 - 1),
    "int16": (-(2**15), 2**15 - 1),
    "int32": (-(2**31), 2**31 - 1),
    "int64": (-(2**63), 2**63 - 1),
    "uint8": (0, 2**8 - 1),
    "uint16": (0, 2**16 - 1),
    "uint32": (0, 2**32 - 1),
    "uint64": (0, 2**64 - 1),
}
"""The integer types both middlewares name alike, and their ranges."""


class FillError(ValueError):
    """An action value that does not fit its message."""


MessageClass = Callable[[str], Any]
"""A message type's name -> its class (the middleware's)."""
Convert = Callable[[Any, str, Any, str, MessageClass], Any]
"""``(current, kind, value, path, message_class)`` -> a field's new value."""


class Fill(Protocol):
    """A middleware's ``fill``, as :func:`filler` makes it."""

    def __call__(
        self,
        message: Any,
        values: Mapping[str, Any],
        message_class: MessageClass,
        where: str = "",
    ) -> Any: ...


def filler(kinds: Callable[[Any], Mapping[str, str]], convert: Convert) -> Fill:
    """A middleware's ``fill``: ``kinds(message)`` are a message's fields and their types,
    ``convert(current, kind, value, path, message_class)`` a field's new value (the
    middleware's; it fills a nested message with the ``fill`` made here).

    >>> class M:
    ...     data = 0
    >>> fill = filler(lambda m: {"data": "int8"}, lambda c, k, v, p, m: integer(k, v, p))
    >>> fill(M(), {"data": 3.0}, {}.get).data
    3
    """

    def fill(
        message: Any,
        values: Mapping[str, Any],
        message_class: MessageClass,
        where: str = "",
    ) -> Any:
        """Set the fields of ``message`` that an action value names (``{data: 3}``,
        ``{linear: {x: 0.5}}``, ``{header: {stamp: 1.5}}``); return the message.

        ``message_class(type_name)`` gives the class of a nested message. A field the
        message lacks, a value of the wrong kind, out of range or of the wrong length raises
        :class:`FillError`; a ``null`` value leaves the field at its default.
        """
        fields = kinds(message)
        for key, value in values.items():
            path = where + str(key)
            if key not in fields:
                raise FillError("{}: no such field (fields: {})".format(path, ", ".join(fields)))
            if value is None:
                continue
            current = getattr(message, key)
            setattr(message, key, convert(current, fields[key], value, path, message_class))
        return message

    return fill


def integer(
    kind: str, value: Any, where: str, ranges: Mapping[str, Tuple[int, int]] = INTEGER_RANGES
) -> int:
    """``value`` as an integer of type ``kind`` (a whole float is one), within its range.

    >>> integer("int8", 3.0, "data")
    3
    """
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise FillError(f"{where}: {value!r} is not an integer")
    if isinstance(value, float) and not value.is_integer():
        raise FillError(f"{where}: {value!r} is not an integer")
    low, high = ranges[kind]
    if not low <= int(value) <= high:
        raise FillError(f"{where}: {value!r} is out of range for {kind}")
    return int(value)


def number(value: Any, where: str) -> float:
    """``value`` as a float (an integer is one; a bool is not)."""
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise FillError(f"{where}: {value!r} is not a number")
    return float(value)


def boolean(value: Any, where: str) -> bool:
    """``value`` as a bool (``0`` and ``1`` are ones)."""
    if isinstance(value, bool) or value in (0, 1):
        return bool(value)
    raise FillError(f"{where}: {value!r} is not a bool")


def text(value: Any, where: str) -> str:
    """``value`` as a string: a string as it is, another scalar as its JSON text."""
    if isinstance(value, (dict, list)):
        raise FillError(f"{where}: {value!r} is not a string")
    return value if isinstance(value, str) else json.dumps(value)
