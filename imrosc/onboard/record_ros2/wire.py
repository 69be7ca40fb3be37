"""What the bag tap sends imrosc, and the message definitions it sends with each topic.

The tap writes **frames** to a pipe imrosc gave it: a kind byte, the body's length (4
bytes, little endian) and the body.

* ``J``: an event, one JSON object with an ``event`` key (``topic``: a new connection with
  its type, definitions and QoS; ``ready``, ``warning``, ``stats``);
* ``M``: a message: the connection id (4 bytes), the receive time in nanoseconds since the
  epoch (8 bytes) and the CDR bytes as received.

A frame cut short (the tap killed while writing) ends the stream; the frames before it are
whole. Python 3.8 syntax, standard library only: the tap imports this under the ROS 2
Python, imrosc under its own.

>>> import io
>>> stream = io.BytesIO(event({"event": "ready"}) + message(3, 7, b"cdr") + b"M\\x09")
>>> [(kind, body[:9] if kind == EVENT else parse_message(body))
...  for kind, body in read_frames(stream)]
[(b'J', b'{"event":'), (b'M', (3, 7, b'cdr'))]
"""

from __future__ import annotations

import json
import re
import struct
from typing import IO, Any, Callable, Dict, Iterator, List, Mapping, Optional, Tuple

EVENT, MESSAGE = b"J", b"M"
_HEADER = struct.Struct("<cI")
_MESSAGE = struct.Struct("<IQ")
MAX_FRAME = 1 << 30
"""A frame longer than this is a broken stream, not a message."""

PRIMITIVES = frozenset(
    {
        "bool",
        "byte",
        "char",
        "float32",
        "float64",
        "int8",
        "uint8",
        "int16",
        "uint16",
        "int32",
        "uint32",
        "int64",
        "uint64",
        "string",
        "wstring",
    }
)
_BOUND = re.compile(r"(<=\d+)?(\[(<=)?\d*\])?$")


def frame(kind: bytes, body: bytes) -> bytes:
    """One frame."""
    return _HEADER.pack(kind, len(body)) + body


def event(document: Mapping[str, Any]) -> bytes:
    """An event frame (compact JSON)."""
    return frame(EVENT, json.dumps(dict(document), separators=(",", ":")).encode())


def message(connection: int, stamp: int, data: bytes) -> bytes:
    """A message frame: connection id, receive time (ns) and the CDR bytes."""
    return frame(MESSAGE, _MESSAGE.pack(connection, stamp) + bytes(data))


def parse_message(body: bytes) -> Tuple[int, int, bytes]:
    """``(connection, stamp, data)`` of a message frame's body."""
    connection, stamp = _MESSAGE.unpack_from(body)
    return connection, stamp, body[_MESSAGE.size :]


def _read_exactly(stream: IO[bytes], size: int) -> Optional[bytes]:
    chunks: List[bytes] = []
    left = size
    while left:
        chunk = stream.read(left)
        if not chunk:
            return None
        chunks.append(chunk)
        left -= len(chunk)
    return b"".join(chunks)


def read_frames(stream: IO[bytes]) -> Iterator[Tuple[bytes, bytes]]:
    """The frames of a stream, ``(kind, body)``, until it ends (or a frame is cut short)."""
    while True:
        header = _read_exactly(stream, _HEADER.size)
        if header is None:
            return
        kind, length = _HEADER.unpack(header)
        if length > MAX_FRAME:
            return
        body = _read_exactly(stream, length)
        if body is None:
            return
        yield kind, body


# -- message definitions ---------------------------------------------------------------------


def full_type(name: str, package: str) -> Optional[str]:
    """The full name (``pkg/msg/Name``) of a field type of a ``.msg`` in ``package``;
    ``None`` for a primitive. Bounds and array marks are dropped.

    >>> [full_type(t, "p") for t in ("float64[3]", "string<=5", "Point[]",
    ...                              "geometry_msgs/Point[<=2]", "std_msgs/msg/Header")]
    [None, None, 'p/msg/Point', 'geometry_msgs/msg/Point', 'std_msgs/msg/Header']
    """
    base = _BOUND.sub("", name)
    if base in PRIMITIVES:
        return None
    parts = base.split("/")
    if len(parts) == 1:
        return f"{package}/msg/{parts[0]}"
    return f"{parts[0]}/msg/{parts[-1]}"


def used_types(text: str, type_name: str) -> List[str]:
    """The message types the fields of a ``.msg`` use (constants and comments skipped).

    >>> used_types("# c\\nint32 A=1\\nHeader header\\nfloat64 x 0.5\\nPoint[] p  # c\\n",
    ...            "geometry_msgs/msg/Polygon")
    ['geometry_msgs/msg/Header', 'geometry_msgs/msg/Point']
    """
    package = type_name.split("/", maxsplit=1)[0]
    found: List[str] = []
    for line in text.splitlines():
        words = line.split("#", 1)[0].split()
        if len(words) < 2 or "=" in words[1] or "=" in words[0].replace("<=", ""):
            continue
        used = full_type(words[0], package)
        if used is not None and used not in found:
            found.append(used)
    return found


def definitions(
    type_name: str, lookup: Callable[[str], Optional[str]]
) -> Tuple[Dict[str, str], List[str]]:
    """The ``.msg`` texts of ``type_name`` and every type it uses, by full name, as
    ``lookup`` finds them; and the types it did not find.

    >>> texts = {"p/msg/A": "p/B b\\nC[] c", "p/msg/B": "int8 x", "p/msg/C": "q/D d"}
    >>> definitions("p/msg/A", texts.get)
    ({'p/msg/A': 'p/B b\\nC[] c', 'p/msg/B': 'int8 x', 'p/msg/C': 'q/D d'}, ['q/msg/D'])
    """
    found: Dict[str, str] = {}
    missing: List[str] = []
    todo = [type_name]
    while todo:
        name = todo.pop(0)
        if name in found or name in missing:
            continue
        text = lookup(name)
        if text is None:
            missing.append(name)
            continue
        found[name] = text
        todo += used_types(text, name)
    return found, missing
