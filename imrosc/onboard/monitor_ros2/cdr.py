"""A blocked topic's values read from the CDR bytes it came in, for the ROS 2 monitor.

The monitor subscribes to a blocked topic raw (``create_subscription(..., raw=True)``):
rclpy hands over the serialised bytes, the relay publishes those same bytes (an rclpy
publisher takes ``bytes``), and no relayed message is decoded into a Python object or
encoded again. The values the invariants need are read from the bytes by :func:`reader`, a
plan made once from the message class (``get_fields_and_field_types``, which rclpy has from
Foxy on), in the CDR that ROS 2's DDS layers write: a 4-byte encapsulation header
(``00 01``: plain CDR, little-endian), then the fields in order, each primitive aligned to
its size counted from the end of the header, strings as a uint32 length (counting a
terminating NUL) and the bytes, sequences as a uint32 count and the elements, fixed arrays
and nested messages inline. Only the fields up to the last one the invariants read are
walked.

The values are those the generated flattener gives on the message rclpy would decode:
numbers as ``float``, strings as rclpy decodes them (UTF-8, bad bytes replaced, cut at a
NUL), elements and statistics through the same helpers (``onboard/flat.py``). A layout the
plan does not cover (``octet``, ``char``, ``wstring``, ``long double``, an element of an
array of strings, a field inside an array of messages, a string read as a number or the
reverse) gets no reader, and bytes the plan cannot read (another encapsulation, such as
big-endian CDR, or bytes cut short) raise: the node then deserialises the bytes with
rclpy and flattens the message as before. Python 3.8 syntax, no rclpy import.

>>> class Time:
...     @staticmethod
...     def get_fields_and_field_types():
...         return {"sec": "int32", "nanosec": "uint32"}
>>> class Stamped:
...     @staticmethod
...     def get_fields_and_field_types():
...         return {"stamp": "builtin_interfaces/Time", "frame": "string",
...                 "values": "sequence<double>", "flag": "boolean"}
>>> layout = [{"path": "frame", "type": "string"}, {"path": "values", "derived": "len"},
...           {"path": "values[1]"}, {"path": "flag"}]
>>> read = reader(Stamped, layout, {"builtin_interfaces/Time": Time}.get)
>>> data = struct.pack("<4siiI4sI4x2dB", b"\\0\\1\\0\\0", 1, 2, 4, b"map\\0", 2, 0.5, 2.5, 1)
>>> read(data)
['map', 2.0, 2.5, 1.0]
"""

from __future__ import annotations

import re
import struct
from typing import Any, Callable, Dict, List, Mapping, Optional, Sequence, Tuple

import numpy as np

from ..flat import Step, UnsupportedError, match, unless_unsupported, walker

Lookup = Callable[[str], Any]
"""A message type name (``pkg/Type`` or ``pkg/msg/Type``) -> its rclpy class, or ``None``."""
Reader = Callable[[bytes], Any]
"""The serialised bytes of a message -> its values in the layout's order."""

HEADER = b"\x00\x01"
"""The encapsulation the plan reads: plain CDR, little-endian."""
START = 4
"""Where the data starts, after the encapsulation header; alignment counts from there."""
_PRIMITIVES: Dict[str, str] = {
    "boolean": "?",
    "int8": "b",
    "uint8": "B",
    "int16": "h",
    "uint16": "H",
    "int32": "i",
    "uint32": "I",
    "int64": "q",
    "uint64": "Q",
    "float": "f",
    "double": "d",
}
"""IDL primitive -> its ``struct`` code (``octet``, ``char`` and ``long double`` are not
read: rclpy gives them as bytes, one-character strings or numpy's long double)."""
_SEQUENCE = re.compile(r"^sequence<(?P<base>.+?)(?:,\s*\d+)?>$")
_ARRAY = re.compile(r"^(?P<base>[^\[]+)\[(?P<count>\d+)\]$")
_STRING = re.compile(r"^string(?:<=\d+)?$")
_U32 = struct.Struct("<I")


Leaf = Tuple[str, str, str, Optional[int], Any]
"""``(path, kind, code, count, element)`` in serialisation order. Kinds: ``scalar`` (a
primitive, ``code`` its struct code), ``string``, ``array`` (of a primitive; ``count``
``None`` for a sequence), ``strings`` (an array of strings) and ``messages`` (an array of
messages, ``element`` the steps that walk one)."""


def _leaves(message_class: Any, lookup: Lookup, prefix: str, out: List[Leaf]) -> None:
    fields = getattr(message_class, "get_fields_and_field_types", None)
    if fields is None:
        raise UnsupportedError(f"{message_class!r} is not an rclpy message class")
    for name, kind in fields().items():
        path = prefix + name
        many = _SEQUENCE.match(kind) or _ARRAY.match(kind)
        base = many.group("base") if many else kind
        count = int(many.group("count")) if many and "count" in many.groupdict() else None
        if base in _PRIMITIVES:
            out.append((path, "array" if many else "scalar", _PRIMITIVES[base], count, None))
        elif _STRING.match(base):
            out.append((path, "strings" if many else "string", "", count, None))
        elif "/" not in base:
            raise UnsupportedError(f"field {path!r} of type {kind!r}")
        elif many is None:
            _leaves(_message(lookup, base), lookup, path + ".", out)
        else:
            inner: List[Leaf] = []
            _leaves(_message(lookup, base), lookup, "", inner)
            steps = [_dynamic(leaf, False) for leaf in inner]
            out.append((path, "messages", "", count, steps))


def _message(lookup: Lookup, name: str) -> Any:
    try:
        found = lookup(name)
    except (KeyError, LookupError, ValueError, ImportError) as error:
        raise UnsupportedError(f"no message class for {name}") from error
    if found is None:
        raise UnsupportedError(f"no message class for {name}")
    return found


def _reader(message_class: Any, variables: Sequence[Mapping[str, Any]], lookup: Lookup) -> Reader:
    leaves: List[Leaf] = []
    _leaves(message_class, lookup, "", leaves)
    wanted = match(variables, [(path, kind) for path, kind, _, _, _ in leaves])
    needed = sorted({leaf for leaf, _, _, _ in wanted})
    last = needed[-1] if needed else -1
    kept = set(needed)
    steps = [_dynamic(leaf, k in kept) for k, leaf in enumerate(leaves[: last + 1])]
    slot = {leaf: k for k, leaf in enumerate(needed)}
    if len(needed) == 1 and leaves[needed[0]][1:4] == ("array", "d", None):
        elements = [index for _, index, derived, _ in wanted]
        if elements == list(range(len(wanted))):
            return _doubles(steps[:-1], len(wanted))
    slots = [(slot[leaf], index, derived, text) for leaf, index, derived, text in wanted]
    return walker(steps, slots, _start)


reader = unless_unsupported(_reader)
"""The values of ``variables`` (the topic's layout) from a message's CDR bytes, or ``None``
when the plan cannot read them (the caller deserialises instead)."""


def _start(data: bytes) -> int:
    if data[:2] != HEADER:
        raise ValueError(f"encapsulation {bytes(data[:2])!r} is not plain little-endian CDR")
    return START


def _doubles(steps: Sequence[Step], count: int) -> Reader:
    """The layout is the first ``count`` elements of a float64 sequence, in order: the
    values are a read-only float64 array over the bytes themselves (the engine takes it as
    it is), NaN past the sequence's end as ``at_`` gives."""
    double = np.dtype("<f8")

    def doubles(data: bytes) -> Any:
        offset = _start(data)
        for step in steps:
            offset = step(data, offset, [])
        offset += (START - offset) % 4
        size = _U32.unpack_from(data, offset)[0]
        offset += 4
        offset += (START - offset) % 8
        if size >= count:
            return np.frombuffer(data, double, count, offset)
        values = np.full(count, np.nan)
        if size:
            values[:size] = np.frombuffer(data, double, size, offset)
        return values

    return doubles


def _length(data: bytes, offset: int, count: Optional[int]) -> Tuple[int, int]:
    """An array's length and where its elements start: ``count`` for a fixed array, else the
    uint32 (aligned to 4) before the elements."""
    if count is not None:
        return count, offset
    offset += (START - offset) % 4
    size: int = _U32.unpack_from(data, offset)[0]
    return size, offset + 4


def _text(raw: bytes) -> str:
    """A CDR string's bytes (its NUL included) as rclpy decodes them."""
    end = raw.find(b"\x00")
    return (raw if end < 0 else raw[:end]).decode("utf-8", "replace")


def _dynamic(leaf: Leaf, keep: bool) -> Step:
    """The step past one leaf, appending its value when ``keep``."""
    _, kind, code, count, element = leaf
    if kind == "scalar":
        unpack = struct.Struct("<" + code).unpack_from
        width = struct.calcsize(code)

        def scalar(data: bytes, offset: int, got: List[Any]) -> int:
            offset += (START - offset) % width
            if keep:
                got.append(unpack(data, offset)[0])
            return offset + width

        return scalar
    if kind == "string":

        def string(data: bytes, offset: int, got: List[Any]) -> int:
            size, offset = _length(data, offset, None)
            if keep:
                if offset + size > len(data):
                    raise ValueError("a string past the end of the message")
                got.append(_text(data[offset : offset + size]))
            return offset + size

        return string
    if kind == "array":
        width = struct.calcsize(code)

        def array(data: bytes, offset: int, got: List[Any]) -> int:
            size, offset = _length(data, offset, count)
            if size:
                offset += (START - offset) % width
            if keep:
                got.append(struct.unpack_from(f"<{size}{code}", data, offset))
            elif offset + size * width > len(data):
                raise ValueError("an array past the end of the message")
            return offset + size * width

        return array
    if kind == "strings":

        def strings(data: bytes, offset: int, got: List[Any]) -> int:
            size, offset = _length(data, offset, count)
            for _ in range(size):
                offset += (START - offset) % 4
                offset += 4 + _U32.unpack_from(data, offset)[0]
            return offset

        return strings
    inner: Sequence[Step] = element

    def messages(data: bytes, offset: int, got: List[Any]) -> int:
        size, offset = _length(data, offset, count)
        for _ in range(size):
            for step in inner:
                offset = step(data, offset, got)
        if offset > len(data):
            raise ValueError("messages past the end of the message")
        return offset

    return messages
