"""Message types as flat variables: the field paths a program point extracts from a message.

A message flattens into dotted field paths (``pose.position.x``). Numbers, bools and strings
are variables as they are; ``builtin_interfaces/msg/Time`` and ``Duration`` are one float
variable in seconds; arrays keep their element type and say whether their length is fixed;
arrays of messages flatten to parallel arrays (``points[].x``); byte arrays
(``uint8[]``, ``char[]``) are blobs of which only the length is a variable.

>>> from rosbags.typesys import Stores, get_typestore
>>> store = get_typestore(Stores.ROS1_NOETIC)
>>> for spec in flatten(store, "sensor_msgs/msg/LaserScan")[:3]:
...     print(spec.path, spec.type, spec.array)
header.seq uint None
header.stamp time None
header.frame_id string None
>>> [(f.path, f.array) for f in flatten(store, "sensor_msgs/msg/LaserScan")[-2:]]
[('ranges', 'sequence'), ('intensities', 'sequence')]
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Literal

from rosbags.interfaces import Nodetype

VariableType = Literal["float", "int", "uint", "bool", "string", "time", "bytes"]

_BASE_TYPES: dict[str, VariableType] = {
    "float32": "float",
    "float64": "float",
    "int8": "int",
    "int16": "int",
    "int32": "int",
    "int64": "int",
    "uint16": "uint",
    "uint32": "uint",
    "uint64": "uint",
    "uint8": "uint",
    "byte": "uint",
    "char": "uint",
    "bool": "bool",
    "string": "string",
    "wstring": "string",
    "octet": "uint",
}
_TIME_TYPES = {"builtin_interfaces/msg/Time", "builtin_interfaces/msg/Duration"}
_BLOB_ELEMENTS = {"uint8", "byte", "char", "octet"}
MAX_DEPTH = 32


@dataclass(frozen=True)
class FieldSpec:
    """One variable of a message: its path, scalar type, and array kind (if an array)."""

    path: str
    type: VariableType
    array: Literal["fixed", "sequence"] | None = None
    length: int | None = None


def _join(prefix: str, name: str) -> str:
    return f"{prefix}.{name}" if prefix else name


def _walk(store: Any, msgtype: str, prefix: str, array: str | None, depth: int) -> list[FieldSpec]:
    if msgtype in _TIME_TYPES:
        return [FieldSpec(prefix, "time", array)]  # type: ignore[arg-type]
    if depth > MAX_DEPTH:
        return []
    _, fields = store.fielddefs[msgtype]
    found: list[FieldSpec] = []
    for name, (nodetype, detail) in fields:
        path = _join(prefix, name)
        if nodetype == Nodetype.BASE:
            found.append(FieldSpec(path, _BASE_TYPES.get(detail[0], "string"), array))  # type: ignore[arg-type]
        elif nodetype == Nodetype.NAME:
            found += _walk(store, detail, path, array, depth + 1)
        else:
            (element_kind, element_detail), length = detail
            kind: Literal["fixed", "sequence"] = (
                "fixed" if nodetype == Nodetype.ARRAY else "sequence"
            )
            size = length if length else None
            if array is not None:
                continue  # arrays of arrays have no flat form
            if element_kind == Nodetype.BASE and element_detail[0] in _BLOB_ELEMENTS:
                found.append(FieldSpec(path, "bytes", kind, size))
            elif element_kind == Nodetype.BASE:
                found.append(
                    FieldSpec(path, _BASE_TYPES.get(element_detail[0], "string"), kind, size)
                )
            else:
                found += [
                    FieldSpec(spec.path, spec.type, kind, size)
                    for spec in _walk(store, element_detail, path + "[]", kind, depth + 1)
                ]
    return found


def flatten(store: Any, msgtype: str) -> tuple[FieldSpec, ...]:
    """Every variable of ``msgtype`` (a name the typestore knows), in field order."""
    return tuple(_walk(store, msgtype, "", None, 0))
