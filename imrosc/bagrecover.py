"""Reading ROS 1 bags that were cut short or never indexed, up to their last whole record.

A ROS 1 bag (format 2.0) is a header, then chunks of records (connections and messages),
each followed by its index records, and at the end the index: the connections and one
chunk-info record per chunk, found through ``index_pos`` in the header. A recording that
was killed leaves no index (``index_pos`` 0) and maybe a last chunk half written; a copy cut
short loses the index and the chunks past the cut.

:class:`RecoveringReader` is rosbags' ROS 1 reader that, when the index cannot be read,
scans the records from the start instead, up to the last complete chunk or message record
(a chunk cut short gives the messages whose records it holds whole, decompressed as far as
its bytes go), and rebuilds the index in memory; messages are then read from the file
itself, as from any indexed bag. :attr:`RecoveringReader.recovery` says what was
recovered. ``rosbag reindex`` recovers the whole chunks only: of a recording killed after
7.2 s (``rosbag record --chunksize=16``, SIGKILL) it kept 1,212 messages where this reader
reads 1,432, the open chunk's whole records included (a single open chunk: 0 against
1,956). A file that does not begin as a ROS 1 bag is refused before anything else is read,
without quoting its bytes.
"""

from __future__ import annotations

import bz2
import os
import struct
from collections import defaultdict
from collections.abc import Callable
from dataclasses import dataclass
from io import BytesIO
from typing import BinaryIO

from lz4.frame import LZ4FrameDecompressor  # type: ignore[import-untyped]
from rosbags.interfaces import Connection
from rosbags.rosbag1.reader import (
    Chunk,
    ChunkInfo,
    Header,
    IndexData,
    Reader,
    ReaderError,
    RecordType,
    decompressors,
    read_uint32,
)

MAGIC = b"#ROSBAG V2.0\n"
_STOP = (ReaderError, ValueError, OSError, EOFError, LookupError)
"""What a damaged or cut record raises while it is parsed or decompressed."""


@dataclass(frozen=True)
class Recovery:
    """What a scan recovered from a bag whose index could not be read."""

    size: int
    """Bytes in the file."""
    ending: str
    """``truncated``: the file ends inside a record; ``damaged``: a record cannot be read;
    empty: all records are whole and only the index is missing or damaged."""
    stopped: int
    """The byte of the record where the scan stopped (``size``: none)."""
    messages: int
    seconds: float
    """From the first recovered message to the last."""
    indexed: bool
    """Whether the header points at an index (``index_pos`` is not 0)."""
    described: str = ""
    """What was wrong, when it is said in other words than where the scan stopped."""

    def what(self) -> str:
        """What was wrong with the bag, in a few words."""
        if self.described:
            return self.described
        if self.ending == "truncated":
            return f"truncated at byte {self.size:,}"
        if self.ending == "damaged":
            return f"damaged at byte {self.stopped:,}"
        if self.indexed:
            return "index damaged"
        return "not indexed (the recording was interrupted)"

    def text(self) -> str:
        """One line: what was wrong and how much was recovered."""
        return recovered_text(self.what(), self.messages, self.seconds)


def recovered_text(what: str, messages: int, seconds: float) -> str:
    """The one line of a recovered bag: ``what`` was wrong, then how much was recovered.

    >>> recovered_text("truncated at byte 1,024", 12, 0.11)
    'truncated at byte 1,024; recovered 12 messages of the first 0.110 s'
    """
    plural = "s" * (messages != 1)
    return f"{what}; recovered {messages:,} message{plural} of the first {seconds:.3f} s"


def _partial(compression: str) -> Callable[[bytes], bytes]:
    """A decompressor that gives what a cut compressed stream holds up to its cut."""
    if compression == "none":
        return lambda data: data
    if compression == "bz2":
        return lambda data: bz2.BZ2Decompressor().decompress(data)
    if compression == "lz4":
        return lambda data: bytes(LZ4FrameDecompressor().decompress(data))
    raise ReaderError(f"chunk compression {compression!r} is not supported")


def check_magic(start: bytes) -> None:
    """Refuse a file whose first bytes (``start``, as many as :data:`MAGIC` has) do not
    begin a ROS 1 bag of format 2.0; its bytes are not quoted."""
    if start == MAGIC:
        return
    if not start:
        raise ReaderError("the file is empty")
    if MAGIC.startswith(start):
        raise ReaderError(f"truncated at byte {len(start)}, in its header")
    if start.startswith(b"#ROSBAG V") and start.endswith(b"\n"):
        version = start[len("#ROSBAG V") : -1].decode("ascii", "replace")
        raise ReaderError(f"format {version} of ROS 1 bags is not supported (only 2.0)")
    raise ReaderError("not a ROS 1 bag: the file does not begin with #ROSBAG V2.0")


class RecoveringReader(Reader):
    """rosbags' ROS 1 reader; a bag whose index cannot be read is scanned instead."""

    recovery: Recovery | None = None

    def open(self) -> None:
        with self.path.open("rb") as stream:
            check_magic(stream.read(len(MAGIC)))
        try:
            super().open()
        except ReaderError as error:
            if "encryption" in str(error) or "not supported" in str(error):
                raise
        except (AssertionError, ValueError, EOFError, LookupError):
            pass  # a damaged index trips rosbags' asserts and struct errors
        else:
            return
        self.bio = self.path.open("rb")
        try:
            self.recovery = self._scan(self.bio)
        except BaseException:
            self.bio.close()
            self.bio = None
            raise

    def _connection(self, stream: BinaryIO) -> Connection:
        """A connection record read from ``stream`` (rosbags reads from ``self.bio``)."""
        bio, self.bio = self.bio, stream
        try:
            return self.read_connection()
        finally:
            self.bio = bio

    def _scan(self, bio: BinaryIO) -> Recovery:
        size = os.fstat(bio.fileno()).st_size
        bio.seek(len(MAGIC))
        try:
            header = Header.read(bio, RecordType.BAGHEADER)
            index_pos = header.get_uint64("index_pos")
            bio.seek(read_uint32(bio), os.SEEK_CUR)
        except (ReaderError, ValueError) as error:
            if _runs_past(bio, len(MAGIC), size):
                raise ReaderError(f"truncated at byte {size:,}, in its header") from error
            raise ReaderError("its header record is damaged") from error
        if bio.tell() > size:
            raise ReaderError(f"truncated at byte {size:,}, in its header")
        connections: dict[int, Connection] = {}
        indexes: dict[int, list[IndexData]] = defaultdict(list)
        end = bio.tell()
        stopped: int | None = None
        while end < size and stopped is None:
            stopped = end
            try:
                header = Header.read(bio)
                op = header.get_uint8("op")
                length = read_uint32(bio)
            except (ReaderError, ValueError):
                break
            start = bio.tell()
            whole = start + length <= size
            if op == RecordType.CONNECTION and whole:
                bio.seek(end)
                try:
                    found = self._connection(bio)
                except _STOP:
                    break
                connections.setdefault(found.id, found)
            elif op == RecordType.CHUNK:
                if length == 0 and start < size:  # rosbag record writes the sizes last
                    whole, length = False, size - start
                read = min(length, size - start)
                if not self._chunk(bio, header, end, start, read, connections, indexes) or (
                    not whole
                ):
                    break
            elif op not in (RecordType.IDXDATA, RecordType.CHUNK_INFO) or not whole:
                break
            stopped = None
            end = start + length
            bio.seek(end)
        self.connections = list(connections.values())
        self.indexes = {c.id: sorted(indexes[c.id]) for c in self.connections}
        self.connections = [
            Connection(*c[0:5], len(self.indexes[c.id]), *c[6:]) for c in self.connections
        ]
        times = [entry.time for entries in self.indexes.values() for entry in entries]
        cut = stopped is not None and _runs_past(bio, stopped, size)
        ending = "truncated" if cut else "damaged" if stopped is not None else ""
        if not times and ending:
            at = size if cut else stopped
            raise ReaderError(f"{ending} at byte {at:,}, before its first whole message")
        span = (max(times) - min(times)) / 1e9 if times else 0.0
        return Recovery(size, ending, stopped or size, len(times), span, index_pos != 0)

    def _chunk(
        self,
        bio: BinaryIO,
        header: Header,
        pos: int,
        start: int,
        length: int,
        connections: dict[int, Connection],
        indexes: dict[int, list[IndexData]],
    ) -> bool:
        """Index the whole records of the chunk at ``pos`` (its data: ``length`` bytes from
        ``start``); whether the chunk was whole."""
        try:
            compression = header.get_string("compression")
            decompress = _partial(compression)
            bio.seek(start)
            data = decompress(bio.read(length))
        except _STOP:
            return False
        counts: dict[int, int] = defaultdict(int)
        times: list[int] = []
        offset = 0
        while offset < len(data):
            parsed = _fields(data, offset)
            if parsed is None:
                break
            fields, after = parsed
            op = fields.get(b"op", b"")
            if op == _CONNECTION:
                try:
                    found = self._connection(BytesIO(data[offset:after]))
                except _STOP:
                    break
                connections.setdefault(found.id, found)
            elif op == _MSGDATA and len(fields.get(b"conn", b"")) == 4:
                conn = _UINT32.unpack(fields[b"conn"])[0]
                stamp = fields.get(b"time", b"")
                if len(stamp) != 8:
                    break
                seconds, nanoseconds = _TIME.unpack(stamp)
                time = seconds * 1_000_000_000 + nanoseconds
                if conn in connections:
                    indexes[conn].append(IndexData(time, pos, offset))
                    counts[conn] += 1
                    times.append(time)
            else:
                break
            offset = after
        whole = offset == len(data) == _declared(header) and compression in decompressors
        if times:
            self.chunks[pos] = Chunk(
                length, start, decompressors[compression] if whole else decompress
            )
            self.chunk_infos.append(ChunkInfo(pos, min(times), max(times) + 1, dict(counts)))
        return whole


_UINT32 = struct.Struct("<I")
_TIME = struct.Struct("<II")
_CONNECTION = bytes([RecordType.CONNECTION])
_MSGDATA = bytes([RecordType.MSGDATA])


def _fields(data: bytes, offset: int) -> tuple[dict[bytes, bytes], int] | None:
    """The header fields of the record at ``offset`` of a chunk's data and the offset after
    its data; None when the record is not whole or not well formed (rosbags'
    ``Header.read`` does the same, slower: the scan reads every record)."""
    end = len(data)
    if offset + 4 > end:
        return None
    header_end = offset + 4 + _UINT32.unpack_from(data, offset)[0]
    if header_end + 4 > end:
        return None
    after = header_end + 4 + _UINT32.unpack_from(data, header_end)[0]
    if after > end:
        return None
    fields: dict[bytes, bytes] = {}
    at = offset + 4
    while at < header_end:
        size = _UINT32.unpack_from(data, at)[0] if at + 4 <= header_end else header_end
        at += 4
        if at + size > header_end:
            return None
        field = data[at : at + size]
        name, sep, value = field.partition(b"=")
        if not sep:
            return None
        fields[name] = value
        at += size
    return fields, after


def _runs_past(bio: BinaryIO, pos: int, size: int) -> bool:
    """Whether the record at ``pos`` declares more bytes than the file has from there (or
    its lengths are cut): the file was cut in it, rather than it being damaged."""
    bio.seek(pos)
    head = bio.read(4)
    if len(head) < 4:
        return True
    header_length: int = struct.unpack("<I", head)[0]
    if pos + 8 + header_length > size:
        return True
    bio.seek(pos + 4 + header_length)
    data_length: int = struct.unpack("<I", bio.read(4))[0]
    chunk_open = data_length == 0 and pos + 8 + header_length < size
    return chunk_open or pos + 8 + header_length + data_length > size


def _declared(header: Header) -> int:
    """The uncompressed size a chunk's header declares (-1 when it does not say)."""
    try:
        return header.get_uint32("size")
    except ReaderError:
        return -1
