"""The messages of a rosbag2 sqlite3 database whose b-tree sqlite cannot walk, page by page.

A database cut short loses its last pages; the interior pages of the ``messages`` table's
b-tree are written where the file ended when the tree grew a level, so a cut can leave the
first messages' leaves in the file and the pages that lead to them outside it: sqlite then
reads none of them. :func:`scan_messages` reads the leaves themselves, as sqlite's
``.recover`` does: every whole page of the file that is a table leaf (type 13) is parsed,
and each cell whose record is a rosbag2 message (``id`` the rowid, ``topic_id`` and
``timestamp`` integers, ``data`` a blob: no other table of the schema has that shape) is
kept, its data's bytes located in the page and its overflow pages (a message whose chain
leaves the file is dropped). The messages kept are those of rowids 1, 2, ... up to the first
one missing: the messages written first, as many as the file still holds whole.

The format: https://www.sqlite.org/fileformat2.html (b-tree pages, cells, records, overflow).
"""

from __future__ import annotations

import struct
from dataclasses import dataclass
from typing import BinaryIO

__all__ = ["PageMessage", "last_rowid", "read_data", "scan_messages"]

_TABLE_LEAF = 13
_HEADER = b"SQLite format 3\x00"


@dataclass(frozen=True)
class PageMessage:
    """One message found in a table leaf: its row, topic, time and where its data is."""

    rowid: int
    topic: int
    time: int
    segments: tuple[tuple[int, int], ...]
    """(byte offset in the file, length) of the data's pieces, in order."""


def _varint(data: bytes, at: int) -> tuple[int, int]:
    """An sqlite varint at ``at``: its value and the offset after it."""
    value = 0
    for i in range(8):
        byte = data[at + i]
        value = (value << 7) | (byte & 0x7F)
        if byte < 0x80:
            return value, at + i + 1
    return (value << 8) | data[at + 8], at + 9


_INT_SIZES = {1: 1, 2: 2, 3: 3, 4: 4, 5: 6, 6: 8}


def _integer(data: bytes, at: int, serial: int) -> int | None:
    if serial in (8, 9):
        return serial - 8
    size = _INT_SIZES.get(serial)
    if size is None:
        return None
    return int.from_bytes(data[at : at + size], "big", signed=True)


def _size(serial: int) -> int:
    if serial in _INT_SIZES:
        return _INT_SIZES[serial]
    if serial == 7:
        return 8
    if serial >= 12:
        return (serial - 12) // 2 if serial % 2 == 0 else (serial - 13) // 2
    return 0


class _File:
    def __init__(self, stream: BinaryIO, size: int, page_size: int, usable: int) -> None:
        self.stream, self.size, self.page_size, self.usable = stream, size, page_size, usable
        self.pages = size // page_size

    def page(self, number: int) -> bytes:
        self.stream.seek((number - 1) * self.page_size)
        return self.stream.read(self.page_size)


def _open(stream: BinaryIO, size: int) -> _File | None:
    stream.seek(0)
    header = stream.read(100)
    if len(header) < 100 or not header.startswith(_HEADER):
        return None
    (page_size,) = struct.unpack(">H", header[16:18])
    page_size = 65536 if page_size == 1 else page_size
    if page_size < 512:
        return None
    return _File(stream, size, page_size, page_size - header[20])


def last_rowid(stream: BinaryIO, size: int) -> int:
    """The greatest rowid of a message in the table leaves of a database file (0: none),
    from each leaf's last cell: cheap, to tell whether :func:`scan_messages` would find
    more than sqlite reads."""
    file = _open(stream, size)
    greatest = 0
    for number in range(2, file.pages + 1 if file else 0):
        assert file is not None
        page = file.page(number)
        if page[0] != _TABLE_LEAF:
            continue
        try:
            for message in _leaf(file, number, page, last=True):
                greatest = max(greatest, message.rowid)
        except (IndexError, ValueError, struct.error):
            continue
    return greatest


def scan_messages(stream: BinaryIO, size: int) -> list[PageMessage]:
    """The messages of rowids 1, 2, ... found whole in the table leaves of a database file
    (empty when the file is not an sqlite3 database or holds none)."""
    file = _open(stream, size)
    if file is None:
        return []
    found: dict[int, PageMessage] = {}
    for number in range(2, file.pages + 1):
        page = file.page(number)
        if page[0] != _TABLE_LEAF:
            continue
        try:
            for message in _leaf(file, number, page):
                found.setdefault(message.rowid, message)
        except (IndexError, ValueError, struct.error):
            continue  # not a page of the table after all (a freed page, garbage)
    kept = []
    for rowid in range(1, len(found) + 1):
        if rowid not in found:
            break
        kept.append(found[rowid])
    return kept


def _leaf(file: _File, number: int, page: bytes, last: bool = False) -> list[PageMessage]:
    """The message cells of a table leaf page (``last``: of its last cell only)."""
    start = (number - 1) * file.page_size
    (cells,) = struct.unpack(">H", page[3:5])
    out = []
    for index in range(cells - 1 if last else 0, cells):
        (pointer,) = struct.unpack(">H", page[8 + 2 * index : 10 + 2 * index])
        if pointer < 8 or pointer >= file.usable:
            continue
        payload, at = _varint(page, pointer)
        rowid, at = _varint(page, at)
        local = _local(payload, file.usable)
        pieces = [(start + at, local)]
        if local < payload:  # the rest is in overflow pages: 4 bytes (the next), then data
            (following,) = struct.unpack(">I", page[at + local : at + local + 4])
            rest = payload - local
            while rest > 0:
                if not 2 <= following <= file.pages:
                    break
                overflow = file.page(following)
                take = min(rest, file.usable - 4)
                pieces.append(((following - 1) * file.page_size + 4, take))
                rest -= take
                (following,) = struct.unpack(">I", overflow[:4])
            if rest > 0:
                continue  # its chain leaves the file
        message = _message(rowid, pieces, page[at : at + local], payload)
        if message is not None:
            out.append(message)
    return out


def _local(payload: int, usable: int) -> int:
    """How many bytes of a payload a table leaf cell holds itself."""
    most = usable - 35
    if payload <= most:
        return payload
    least = (usable - 12) * 32 // 255 - 23
    local = least + (payload - least) % (usable - 4)
    return local if local <= most else least


def _message(
    rowid: int, pieces: list[tuple[int, int]], head: bytes, payload: int
) -> PageMessage | None:
    """The record as a rosbag2 message (None: a row of another shape): a header of four
    serial types, NULL (the rowid's alias), two integers and a blob."""
    if len(head) < 5:
        return None
    header_size, zero, topic_type, time_type = head[0], head[1], head[2], head[3]
    if header_size > len(head) or zero or not 1 <= topic_type <= 9 or not 1 <= time_type <= 9:
        return None  # integers are types 1 to 6, 8 and 9 (0 and 1 held in the type itself)
    blob, end = _varint(head, 4)
    if end != header_size or blob < 12 or blob % 2:
        return None
    time_at = header_size + _size(topic_type)
    data_at = time_at + _size(time_type)
    length = (blob - 12) // 2
    topic = _integer(head, header_size, topic_type)
    time = _integer(head, time_at, time_type)
    if topic is None or time is None or data_at > len(head) or data_at + length != payload:
        return None
    return PageMessage(rowid, topic, time, _slice(pieces, data_at, length))


def _slice(pieces: list[tuple[int, int]], skip: int, length: int) -> tuple[tuple[int, int], ...]:
    """The file segments of ``length`` bytes after the first ``skip`` of ``pieces``."""
    out = []
    for offset, size in pieces:
        if skip >= size:
            skip -= size
            continue
        take = min(size - skip, length)
        out.append((offset + skip, take))
        length -= take
        skip = 0
        if not length:
            break
    return tuple(out)


def read_data(stream: BinaryIO, message: PageMessage) -> bytes:
    """A message's data from its segments."""
    parts = []
    for offset, size in message.segments:
        stream.seek(offset)
        parts.append(stream.read(size))
    return b"".join(parts)
