"""A blocked topic relayed as the bytes it came in, its values read from those bytes.

The monitor relays a blocked topic's clean messages unchanged. Decoding each message into
a rospy object and encoding it again for the relay costs more than checking a thousand
invariants on a cold cache, so a blocked topic is subscribed with :func:`raw_class`: rospy
hands over the serialised bytes, and the relay publishes those same bytes (what
``topic_tools relay`` does in C++). The subscription and the relay still carry the real
type and MD5 sum. A header is forwarded as it came: its ``seq`` is the publisher's, and a
blocked message leaves a gap in it.

The values the invariants need are read from the bytes by :func:`reader`, a plan made once
from the message class (genpy's ``__slots__`` and ``_slot_types``) in ROS 1's
serialisation: little-endian, strings and variable arrays after a uint32 length, fixed
arrays and nested messages inline. Fixed-size stretches of fields become one ``struct``
read (fields no invariant reads are skipped), strings and variable arrays move the offset.
The values are those the generated flattener gives on the decoded message: genpy decodes
with the same ``struct`` formats, a ``uint8[]`` or ``char[]`` is ``bytes``, a string is
UTF-8 with genpy's ``rosmsg`` error handler, and elements and statistics go through the same
helpers (:mod:`.flat`). A layout the plan does not cover (a time as a value, an element of an
array of strings, a value after a variable array of variable-size messages, a string read as
a number) gets no reader, and the node subscribes with the decoded class as before.

>>> class Point:
...     __slots__ = ["x", "y", "z"]
...     _slot_types = ["float64", "float64", "float64"]
>>> class Stamped:
...     __slots__ = ["frame", "point", "tags"]
...     _slot_types = ["string", "geometry_msgs/Point", "uint8[]"]
>>> layout = [{"path": "point.y", "type": "float", "derived": None},
...           {"path": "frame", "type": "string", "derived": None},
...           {"path": "tags", "type": "float", "derived": "len"}]
>>> read = reader(Stamped, layout, {"geometry_msgs/Point": Point}.__getitem__)
>>> data = struct.pack("<I3s3dI2s", 3, b"map", 1.0, 2.5, 3.0, 2, b"ab")
>>> read(data)
[2.5, 'map', 2.0]
"""

from __future__ import annotations

import codecs
import operator
import re
import struct
from typing import Any, Callable, Dict, List, Mapping, Optional, Sequence, Tuple

import numpy as np

from ..flat import Step, UnsupportedError, Wanted, match, unless_unsupported, walker

Lookup = Callable[[str], Any]
"""A message type name (``pkg/Type``) -> its genpy class."""
Reader = Callable[[bytes], List[Any]]
"""The serialised bytes of a message -> its values in the layout's order."""

_PRIMITIVES: Dict[str, str] = {
    "bool": "?",
    "int8": "b",
    "byte": "b",
    "uint8": "B",
    "char": "B",
    "int16": "h",
    "uint16": "H",
    "int32": "i",
    "uint32": "I",
    "int64": "q",
    "uint64": "Q",
    "float32": "f",
    "float64": "d",
}
"""ROS 1 primitive -> its ``struct`` code (genpy's: ``bool`` reads as ``?``, any nonzero
byte true)."""
_TIMES = {"time": "2I", "duration": "2i"}
_BYTES = ("uint8", "char")
"""Arrays of these are ``bytes`` in genpy."""
_ARRAY = re.compile(r"^(?P<base>[^\[]+)\[(?P<count>\d*)\]$")
_U32 = struct.Struct("<I")


def raw_class(message_class: Any) -> Any:
    """A class with ``message_class``'s type and MD5 sum that keeps the bytes rospy receives
    (``_buff``) and writes them back unchanged when published."""

    class Raw(message_class):  # type: ignore[misc]
        __slots__ = ("_buff",)
        _has_header = False  # rospy must not renumber the header of bytes it forwards

        def __init__(self) -> None:  # no fields: the bytes are the message
            self._buff = b""

        def deserialize(self, data: bytes) -> Any:
            self._buff = data
            return self

        def serialize(self, buff: Any) -> None:
            buff.write(self._buff)

    Raw.__name__ = Raw.__qualname__ = "Raw" + str(message_class.__name__)
    return Raw


# -- the message as a sequence of leaves -----------------------------------------------------

Leaf = Tuple[str, str, str, Optional[int]]
"""``(path, kind, code, count)`` in serialisation order. Kinds: ``scalar`` (a primitive,
``code`` its struct code), ``time`` (two 32-bit integers), ``string``, ``array`` (of a
primitive; ``count`` ``None`` when variable), ``bytes`` (``uint8``/``char`` arrays),
``strings`` (array of strings), ``messages`` (array of messages, ``code`` its static size
or empty when its size varies)."""


def _kind(base: str, array: bool) -> Optional[Tuple[str, str]]:
    """A field's leaf kind and struct code (``None``: a message)."""
    if array and base in _BYTES:
        return "bytes", ""
    if base in _PRIMITIVES:
        return ("array" if array else "scalar"), _PRIMITIVES[base]
    if base in _TIMES:
        return ("array" if array else "time"), _TIMES[base]
    if base == "string":
        return ("strings" if array else "string"), ""
    return None


def _numbers(kind: str, code: str) -> str:
    """A leaf's kind as :func:`.flat.match` reads it: ``bytes`` are an array of numbers, an
    array of times is not one (genpy gives its elements as ``Time`` objects)."""
    if kind == "bytes":
        return "array"
    if kind == "array" and code in _TIMES.values():
        return "times"
    return kind


def _leaves(message_class: Any, lookup: Lookup, prefix: str, out: List[Leaf]) -> None:
    for name, kind in zip(message_class.__slots__, message_class._slot_types):
        path = prefix + name
        array = _ARRAY.match(kind)
        base = array.group("base") if array else kind
        count = int(array.group("count")) if array and array.group("count") else None
        leaf = _kind(base, array is not None)
        if leaf is not None:
            out.append((path, leaf[0], leaf[1], count))
        elif array is None:
            _leaves(_message(lookup, base, kind), lookup, path + ".", out)
        else:
            size = _static_size(_message(lookup, base, kind), lookup)
            out.append((path, "messages", "" if size is None else str(size), count))


def _message(lookup: Lookup, base: str, kind: str) -> Any:
    name = base if "/" in base else ("std_msgs/Header" if base == "Header" else base)
    try:
        found = lookup(name)
    except (KeyError, LookupError, ValueError, ImportError) as error:
        raise UnsupportedError(f"no message class for {kind}") from error
    if found is None or not hasattr(found, "_slot_types"):
        raise UnsupportedError(f"no message class for {kind}")
    return found


def _static_size(message_class: Any, lookup: Lookup) -> Optional[int]:
    """Bytes of every message of this class, or ``None`` when the size varies."""
    leaves: List[Leaf] = []
    _leaves(message_class, lookup, "", leaves)
    size = 0
    for leaf in leaves:
        width = _static_width(leaf)
        if width is None:
            return None
        size += width
    return size


def _static_width(leaf: Leaf) -> Optional[int]:
    _, kind, code, count = leaf
    if kind in ("scalar", "time"):
        return struct.calcsize("<" + code)
    if count is None or kind == "strings" or (kind == "messages" and not code):
        return None
    if kind == "bytes":
        return count
    if kind == "messages":
        return count * int(code)
    return count * struct.calcsize("<" + code)


# -- the plan --------------------------------------------------------------------------------


def _reader(message_class: Any, variables: Sequence[Mapping[str, Any]], lookup: Lookup) -> Reader:
    leaves: List[Leaf] = []
    _leaves(message_class, lookup, "", leaves)
    wanted = match(variables, [(path, _numbers(kind, code)) for path, kind, code, _ in leaves])
    needed = sorted({leaf for leaf, _, _, _ in wanted})
    first = needed[0] if needed else 0
    if [leaf for leaf, _, _, _ in wanted] == list(range(first, first + len(wanted))) and all(
        leaves[leaf][1:3] == ("scalar", "d") and index is None and derived is None and not text
        for leaf, index, derived, text in wanted
    ):
        return _doubles(_skips(leaves[:first]), len(wanted))
    steps, order = _steps(leaves, needed)
    slot = {leaf: k for k, leaf in enumerate(order)}
    return _finish(
        steps,
        [(slot[leaf], index, derived, text) for leaf, index, derived, text in wanted],
        leaves,
        order,
    )


reader = unless_unsupported(_reader)
"""The values of ``variables`` (the topic's layout) from a message's bytes, or ``None``
when the plan cannot read them (the caller decodes instead)."""


def _steps(leaves: Sequence[Leaf], needed: Sequence[int]) -> Tuple[List[Step], List[int]]:
    """The steps that read the needed leaves, and the leaves in the order the steps append
    them."""
    wanted = set(needed)
    last = needed[-1] if needed else -1
    steps: List[Step] = []
    order: List[int] = []
    fmt = ""  # the struct format of the static stretch being gathered
    taken: List[int] = []
    for k, leaf in enumerate(leaves[: last + 1]):
        width = _static_width(leaf)
        _, kind, code, _ = leaf
        if width is not None and not (k in wanted and kind not in ("scalar",)):
            fmt += code if k in wanted else f"{width}x"
            if k in wanted:
                taken.append(k)
            continue
        lead = struct.calcsize("<" + fmt)
        if taken:
            steps.append(_block("<" + fmt, lead))
            order += taken
        elif lead:
            steps.append(_skip(lead))
        fmt, taken = "", []
        steps.append(_dynamic(leaf, k in wanted))
        if k in wanted:
            order.append(k)
    if taken:
        steps.append(_block("<" + fmt, struct.calcsize("<" + fmt)))
        order += taken
    return steps, order


def _skips(leaves: Sequence[Leaf]) -> List[Step]:
    """The steps past ``leaves``, reading nothing."""
    steps: List[Step] = []
    static = 0
    for leaf in leaves:
        width = _static_width(leaf)
        if width is not None:
            static += width
            continue
        if static:
            steps.append(_skip(static))
            static = 0
        steps.append(_dynamic(leaf, False))
    if static:
        steps.append(_skip(static))
    return steps


def _doubles(steps: Sequence[Step], count: int) -> Reader:
    """The layout is ``count`` float64 fields in a row: the values are the bytes themselves,
    as a read-only float64 array over them (the engine takes it as it is)."""
    double = np.dtype("<f8")

    def doubles(data: bytes) -> Any:
        offset = 0
        for step in steps:
            offset = step(data, offset, [])
        return np.frombuffer(data, double, count, offset)

    return doubles


def _block(fmt: str, size: int) -> Step:
    unpack = struct.Struct(fmt).unpack_from

    def block(data: bytes, offset: int, got: List[Any]) -> int:
        got += unpack(data, offset)
        return offset + size

    return block


def _skip(size: int) -> Step:
    def skip(data: bytes, offset: int, got: List[Any]) -> int:
        return offset + size

    return skip


def _length(data: bytes, offset: int, count: Optional[int]) -> Tuple[int, int]:
    """An array's length and where its elements start: ``count`` for a fixed array, else the
    uint32 before the elements."""
    if count is not None:
        return count, offset
    size: int = _U32.unpack_from(data, offset)[0]
    return size, offset + 4


def _dynamic(leaf: Leaf, keep: bool) -> Step:
    """A leaf whose size is read from the data (or a fixed array kept whole)."""
    _, kind, code, count = leaf
    if kind == "string":
        errors = _errors()

        def string(data: bytes, offset: int, got: List[Any]) -> int:
            size, offset = _length(data, offset, None)
            if keep:
                got.append(data[offset : offset + size].decode("utf-8", errors))
            return offset + size

        return string
    if kind == "bytes":

        def raw(data: bytes, offset: int, got: List[Any]) -> int:
            size, offset = _length(data, offset, count)
            if keep:
                got.append(data[offset : offset + size])
            return offset + size

        return raw
    if kind == "array":
        width = struct.calcsize("<" + code)

        def array(data: bytes, offset: int, got: List[Any]) -> int:
            size, offset = _length(data, offset, count)
            if keep:
                got.append(struct.unpack_from(f"<{size}{code}", data, offset))
            return offset + size * width

        return array
    if kind == "strings":

        def strings(data: bytes, offset: int, got: List[Any]) -> int:
            size, offset = _length(data, offset, count)
            for _ in range(size):
                offset += 4 + _length(data, offset, None)[0]
            return offset

        return strings
    if kind == "messages" and code:
        width = int(code)

        def messages(data: bytes, offset: int, got: List[Any]) -> int:
            size, offset = _length(data, offset, None)
            return offset + size * width

        return messages
    raise UnsupportedError(f"{kind} {leaf[0]!r} before a value the invariants read")


def _errors() -> str:
    """genpy's handler of bad UTF-8 (it logs once, then replaces), registered when genpy is
    imported; else what it does."""
    try:
        codecs.lookup_error("rosmsg")
    except LookupError:
        return "replace"
    return "rosmsg"


def _finish(
    steps: Sequence[Step],
    wanted: Sequence[Wanted],
    leaves: Sequence[Leaf],
    order: Sequence[int],
) -> Reader:
    """The reader: run the steps, then give each variable its value as the generated
    flattener computes it (numbers only: the values the steps keep, as they are or picked;
    else :func:`.flat.walker`'s)."""
    plain = all(index is None and derived is None for _, index, derived, _ in wanted)
    floats = all(leaves[leaf][2] in ("d", "f") for leaf in order)
    at = [slot for slot, _, _, _ in wanted]
    if plain and not any(text for _, _, _, text in wanted):
        if floats and at == list(range(len(order))):

            def values(data: bytes) -> List[Any]:
                got: List[Any] = []
                offset = 0
                for step in steps:
                    offset = step(data, offset, got)
                return got

            return values
        pick = operator.itemgetter(*at) if len(at) > 1 else (lambda got: (got[at[0]],))

        def numbers(data: bytes) -> List[Any]:
            got: List[Any] = []
            offset = 0
            for step in steps:
                offset = step(data, offset, got)
            return list(map(float, pick(got)))

        return numbers
    return walker(steps, wanted, _origin)


def _origin(data: bytes) -> int:
    """Where a ROS 1 message's fields start: at its first byte."""
    return 0
