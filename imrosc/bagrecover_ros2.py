"""Reading ROS 2 bags cut short, or left without ``metadata.yaml``, up to their last whole record.

A ROS 2 bag is a folder: ``metadata.yaml`` (written when the recorder closes the bag) and
one or more storage files, sqlite3 (``.db3``) or MCAP (``.mcap``). A recorder that was
killed leaves no ``metadata.yaml``; a copy cut short leaves a storage file whose end is
missing. The readers here are rosbags' own, reading what is left:

* :class:`RecoveringMcapReader`: an MCAP file without its summary and footer (or with them
  cut) is scanned from its start, record by record, up to the last whole message record;
  a chunk cut short gives the messages it holds whole (zstd and lz4 chunks decompressed as
  far as their bytes go), a chunk whose checksum or size is wrong stops the scan.
* :class:`RecoveringSqlite3Reader`: a database shorter than its header says, or one sqlite
  calls malformed, is read with sqlite's own reader (``writable_schema``, which opens a
  database shorter than its header says) in the order the messages were written, up to the
  first message sqlite cannot read; when the table's leaves hold more than its b-tree
  reaches, they are read page by page (:mod:`imrosc.bagrecover_sqlite`).
* :class:`RecoveringDirectoryReader`: a bag folder whose ``metadata.yaml`` is missing or
  cannot be read is read from its storage files alone (topics, types, message definitions
  and counts are in them); counts and times of a bag whose storage was recovered are the
  messages recovered, not the ones ``metadata.yaml`` lists.

Each says what it recovered in :attr:`recovery` (``None``: the bag was whole), in the form
of ROS 1 bags (:mod:`imrosc.bagrecover`): ``truncated at byte N; recovered M messages of
the first S s``. The files are never changed.
"""

from __future__ import annotations

import os
import re
import struct
import sys
from binascii import crc32
from collections import OrderedDict, defaultdict
from collections.abc import Collection, Generator, Mapping
from contextlib import ExitStack
from dataclasses import dataclass
from io import BytesIO
from pathlib import Path
from typing import TYPE_CHECKING, NamedTuple

import apsw
from lz4.frame import LZ4FrameDecompressor  # type: ignore[import-untyped]
from rosbags.interfaces import (
    Connection,
    ConnectionExtRosbag2,
    MessageDefinition,
    MessageDefinitionFormat,
)
from rosbags.rosbag2 import Reader as Ros2Reader
from rosbags.rosbag2 import ReaderError
from rosbags.rosbag2.metadata import ReaderMetadata, parse_qos
from rosbags.rosbag2.reader import DirectoryReader
from rosbags.rosbag2.storage_mcap import (
    Channel,
    McapReader,
    Schema,
    get_msgdef,
    get_qos,
    read_bytes,
    read_string,
)
from rosbags.rosbag2.storage_sqlite3 import Sqlite3Reader

from imrosc.bagrecover import Recovery, recovered_text
from imrosc.bagrecover_sqlite import PageMessage, last_rowid, read_data, scan_messages

if TYPE_CHECKING:
    from rosbags.rosbag2.reader import ReaderProtocol

if sys.version_info >= (3, 14):
    from compression import zstd
else:
    from backports import zstd

__all__ = [
    "METADATA",
    "STORAGE_SUFFIXES",
    "BagRecovery",
    "RecoveringDirectoryReader",
    "RecoveringMcapReader",
    "RecoveringReader2",
    "RecoveringSqlite3Reader",
    "storage_files",
]

METADATA = "metadata.yaml"
STORAGE_SUFFIXES = {".db3": "sqlite3", ".mcap": "mcap"}
_NO_TIME = 2**63 - 1
_EMPTY = ReaderMetadata(0, _NO_TIME, 0, 0, None, None, None, None)


@dataclass(frozen=True)
class BagRecovery:
    """What was recovered of a ROS 2 bag, as a whole."""

    what: str
    messages: int
    seconds: float

    def text(self) -> str:
        """One line: what was wrong and how much was recovered."""
        return recovered_text(self.what, self.messages, self.seconds)


def _metadata(count: int, start: int, end: int) -> ReaderMetadata:
    """rosbags' metadata of ``count`` messages from ``start`` to ``end`` (the last's time)."""
    if not count:
        return _EMPTY
    return _EMPTY._replace(
        duration=end - start + 1, start_time=start, end_time=end + 1, message_count=count
    )


def _seconds(metadata: ReaderMetadata) -> float:
    return (metadata.duration - 1) / 1e9 if metadata.message_count else 0.0


# --- MCAP ---------------------------------------------------------------------------------

_MAGIC = b"\x89MCAP0\r\n"
_FOOTER, _SCHEMA, _CHANNEL, _MESSAGE, _CHUNK, _DATA_END = 0x02, 0x03, 0x04, 0x05, 0x06, 0x0F
_RECORD = struct.Struct("<BQ")
_MESSAGE_HEAD = struct.Struct("<HIQQ")
_CHUNK_HEAD = struct.Struct("<QQQI")
_STOP = (ReaderError, ValueError, struct.error, UnicodeDecodeError, LookupError, zstd.ZstdError)
"""What a damaged or cut record raises while it is parsed or decompressed."""


class _Block(NamedTuple):
    """The data of a chunk: ``length`` bytes of the file from ``start``."""

    start: int
    length: int
    compression: str
    whole: bool
    """Whether the chunk is whole (else its data is decompressed as far as it goes)."""


class _Entry(NamedTuple):
    """Where one recovered message is: ``size`` bytes at ``offset`` of a chunk's data
    (``block`` its index) or of the file (``block`` -1)."""

    time: int
    order: int
    channel: int
    block: int
    offset: int
    size: int


def _decompress(compression: str, data: bytes, whole: bool) -> bytes:
    """A chunk's data; of a chunk cut short, what its compressed stream holds up to the cut."""
    if compression == "":
        return data
    if compression == "zstd":
        return zstd.decompress(data) if whole else zstd.ZstdDecompressor().decompress(data)
    if compression == "lz4":
        return bytes(LZ4FrameDecompressor().decompress(data))
    raise ReaderError(f"chunk compression {compression!r} is not supported")


class RecoveringMcapReader(McapReader):
    """rosbags' MCAP reader; a file without its summary and footer is scanned instead."""

    recovery: Recovery | None = None
    _blocks: list[_Block]
    _entries: list[_Entry]

    def _open(self) -> None:
        try:
            super()._open()
        except (*_STOP, TypeError, AssertionError, IndexError) as error:
            if not self.data_start:  # the file's own header: not an MCAP bag of ROS 2
                self._refuse_header(error)
            self._recover()

    def _refuse_header(self, error: BaseException) -> None:
        assert self.bio
        size = os.fstat(self.bio.fileno()).st_size
        self.bio.seek(0)
        start = self.bio.read(len(_MAGIC))
        if start == _MAGIC or (size < len(_MAGIC) and _MAGIC.startswith(start) and start):
            raise ReaderError(f"truncated at byte {size:,}, in its header") from error
        raise error

    def _recover(self) -> None:
        assert self.bio
        bio = self.bio
        size = os.fstat(bio.fileno()).st_size
        for table in (self.schemas, self.channels):
            table.clear()
        self.chunks.clear()
        self.connections.clear()
        self.statistics = None
        self._blocks, self._entries = [], []
        pos, stopped, ended = self.data_start, None, False
        while pos < size:
            bio.seek(pos)
            head = bio.read(_RECORD.size)
            if len(head) < _RECORD.size:
                stopped = pos
                break
            op, length = _RECORD.unpack(head)
            start = pos + _RECORD.size
            whole = start + length <= size
            if op in (_DATA_END, _FOOTER):
                ended = True
                break
            if op == _CHUNK:
                if not self._chunk(start, min(length, size - start), whole) or not whole:
                    stopped = pos
                    break
            elif not whole or op == 0 or 0x10 <= op < 0x80:  # cut, or not a record at all
                stopped = pos
                break
            elif op in (_SCHEMA, _CHANNEL, _MESSAGE):
                try:
                    self._record(op, bio.read(length), -1, start)
                except _STOP:
                    stopped = pos
                    break
            pos = start + length
        cut = stopped is not None and _mcap_runs_past(bio, stopped, size)
        if ended and not cut:  # every data record whole: was the summary after them cut?
            bio.seek(max(size - len(_MAGIC), 0))
            cut = bio.read() != _MAGIC
            stopped = size if cut else None
        ending = "truncated" if cut else "damaged" if stopped is not None else ""
        self._entries.sort()
        counts: dict[int, int] = defaultdict(int)
        for entry in self._entries:
            counts[entry.channel] += 1
        if not self._entries and ending:
            at = size if cut else stopped
            raise ReaderError(f"{ending} at byte {at:,}, before its first whole message")
        self.connections[:] = [c._replace(msgcount=counts[c.id]) for c in self.connections]
        count = len(self._entries)
        first = self._entries[0].time if count else 0
        last = max((e.time for e in self._entries), default=0)
        self.metadata = _metadata(count, first, last)
        seconds = _seconds(self.metadata)
        self.recovery = Recovery(size, ending, stopped or size, count, seconds, ended)

    def _chunk(self, start: int, length: int, whole: bool) -> bool:
        """Index the whole records of the chunk whose record's data is ``length`` bytes from
        ``start``; whether the chunk was whole and sound."""
        assert self.bio
        self.bio.seek(start)
        body = BytesIO(self.bio.read(length))
        try:
            _, _, size, crc = _CHUNK_HEAD.unpack(body.read(_CHUNK_HEAD.size))
            compression = read_string(body)
            (compressed,) = struct.unpack("<Q", body.read(8))
            at = start + body.tell()
            available = min(compressed, length - body.tell())
            sound = whole and available == compressed
            raw = body.read(available)
            data = _decompress(compression, raw, sound)
            if sound and (len(data) != size or (crc and crc32(data) != crc)):
                return False  # damaged: its records cannot be trusted
        except _STOP:
            return False
        block = len(self._blocks)
        offset, found = 0, False
        while offset + _RECORD.size <= len(data):
            op, record_length = _RECORD.unpack_from(data, offset)
            begin = offset + _RECORD.size
            if begin + record_length > len(data):
                break
            if op in (_SCHEMA, _CHANNEL, _MESSAGE):
                try:
                    found |= self._record(op, data[begin : begin + record_length], block, begin)
                except _STOP:
                    break
            offset = begin + record_length
        if found:
            self._blocks.append(_Block(at, available, compression, sound))
        return sound and offset == len(data)

    def _record(self, op: int, record: bytes, block: int, start: int) -> bool:
        """Note a schema, channel or message record (``start``: where it is in ``block``, or
        in the file); whether it was a message."""
        if op == _MESSAGE:
            if len(record) < _MESSAGE_HEAD.size:
                raise ReaderError("message record too short")
            channel, _, time, _ = _MESSAGE_HEAD.unpack_from(record)
            if channel in self.channels:
                size = len(record) - _MESSAGE_HEAD.size
                order = len(self._entries)
                offset = start + _MESSAGE_HEAD.size
                self._entries.append(_Entry(time, order, channel, block, offset, size))
                return True
            return False
        rec = BytesIO(record)
        (key,) = struct.unpack("<H", rec.read(2))
        if op == _SCHEMA:
            self.schemas[key] = Schema(key, read_string(rec), read_string(rec), read_string(rec))
            return False
        (schema_id,) = struct.unpack("<H", rec.read(2))
        schema = self.schemas.get(schema_id)
        name = schema.name if schema else "__schemaless__"
        channel = Channel(key, name, read_string(rec), read_string(rec), read_bytes(rec))
        if key not in self.channels:
            ext = ConnectionExtRosbag2(channel.message_encoding, get_qos(channel.metadata))
            self.connections.append(
                Connection(key, channel.topic, name, get_msgdef(schema), "", 0, ext, self)
            )
        self.channels[key] = channel
        return False

    def messages(
        self,
        connections: Collection[Connection],
        start: int | None = None,
        stop: int | None = None,
    ) -> Generator[tuple[Connection, int, bytes], None, None]:
        """The messages of rosbags' reader; of a recovered file, the ones recovered."""
        if self.recovery is None:
            yield from super().messages(connections, start, stop)
            return
        assert self.bio
        wanted = {c.id: c for c in connections}
        low, high = (0 if start is None else start), (_NO_TIME if stop is None else stop)
        cache: OrderedDict[int, bytes] = OrderedDict()
        for entry in self._entries:
            if entry.channel not in wanted or not low <= entry.time < high:
                continue
            if entry.block < 0:
                self.bio.seek(entry.offset)
                data = self.bio.read(entry.size)
            else:
                data = self._block(entry.block, cache)[entry.offset : entry.offset + entry.size]
            yield wanted[entry.channel], entry.time, data

    def _block(self, index: int, cache: OrderedDict[int, bytes]) -> bytes:
        """A chunk's data, decompressed (the last few kept)."""
        if index in cache:
            cache.move_to_end(index)
            return cache[index]
        assert self.bio
        block = self._blocks[index]
        self.bio.seek(block.start)
        raw = self.bio.read(block.length)
        cache[index] = _decompress(block.compression, raw, block.whole)
        if len(cache) > 4:
            cache.popitem(last=False)
        return cache[index]


def _mcap_runs_past(bio: object, pos: int, size: int) -> bool:
    """Whether the MCAP record at ``pos`` declares more bytes than the file has from there."""
    assert hasattr(bio, "seek") and hasattr(bio, "read")
    bio.seek(pos)
    head = bio.read(_RECORD.size)
    if len(head) < _RECORD.size:
        return True
    _, length = _RECORD.unpack(head)
    return bool(pos + _RECORD.size + length > size)


# --- sqlite3 ------------------------------------------------------------------------------


def _sqlite_short(path: Path) -> int | None:
    """The size of a database file shorter than its header says it is (None: it is not)."""
    with path.open("rb") as stream:
        header = stream.read(100)
        size = os.fstat(stream.fileno()).st_size
    if len(header) < 100 or not header.startswith(b"SQLite format 3\x00"):
        return None
    (page_size,) = struct.unpack(">H", header[16:18])
    page_size = 65536 if page_size == 1 else page_size
    changes, pages, valid_for = (struct.unpack(">I", header[at : at + 4])[0] for at in (24, 28, 92))
    declared = pages * page_size if pages and changes == valid_for else 0
    return size if size < declared or size % page_size else None


class RecoveringSqlite3Reader(Sqlite3Reader):
    """rosbags' sqlite3 reader; a database cut short or malformed is read as far as sqlite
    can read it, in the order its messages were written."""

    recovery: Recovery | None = None
    _rows = 0
    """Rows read through the b-tree, in the order they were written (of every topic)."""
    _ordered = True
    _pages: list[PageMessage] | None = None
    """The messages found in the table's leaves, in time order, when they are more than
    the b-tree reaches (:mod:`imrosc.bagrecover_sqlite`)."""

    def open(self) -> None:
        short = _sqlite_short(Path(str(self.path)))
        if short is None:
            try:
                super().open()
            except ReaderError as error:
                if not isinstance(error.__cause__, apsw.CorruptError):
                    raise
            else:
                return
        try:
            self._recover(short)
        except BaseException:
            if self.dbconn is not None:
                self.dbconn.close()
                self.dbconn = None
            raise

    def _recover(self, short: int | None) -> None:
        self.dbconn = apsw.Connection(
            f"file:{self.path}?immutable=1", flags=apsw.SQLITE_OPEN_READONLY | apsw.SQLITE_OPEN_URI
        )
        self.dbconn.execute("PRAGMA writable_schema=ON")  # opens a file shorter than it says
        size = os.path.getsize(str(self.path))
        what = f"truncated at byte {size:,}" if short is not None else "database damaged"
        try:
            self.connections = self._topics()
        except apsw.Error as error:
            raise ReaderError(f"{what}, before its first whole message") from error
        times, damaged = self._walk()
        if damaged or short is not None:  # the leaves may hold more than the tree reaches
            with Path(str(self.path)).open("rb") as stream:
                more = last_rowid(stream, size) > self._rows  # rosbag2's rowids: 1, 2, ...
                pages = scan_messages(stream, size) if more else []
            if len(pages) > len(times):
                self._pages = sorted(pages, key=lambda m: (m.time, m.rowid))
                times = [(m.topic, m.time) for m in pages]
        if not times and (damaged or short is not None):
            raise ReaderError(f"{what}, before its first whole message")
        counts: dict[int, int] = defaultdict(int)
        for topic, _ in times:
            counts[topic] += 1
        ids = {c.id for c in self.connections}
        self.connections = [c._replace(msgcount=counts[c.id]) for c in self.connections]
        kept = [time for topic, time in times if topic in ids]
        self.metadata = _metadata(len(kept), min(kept, default=0), max(kept, default=0))
        ending = "truncated" if short is not None else "damaged"
        seconds = _seconds(self.metadata)
        self.recovery = Recovery(size, ending, size, len(kept), seconds, True, described=what)

    def _walk(self) -> tuple[list[tuple[int, int]], bool]:
        """The topic and time of every row sqlite reads through the table's b-tree, in the
        order they were written, up to the first it cannot read; whether it met one."""
        assert self.dbconn
        found: list[tuple[int, int]] = []
        previous = -1
        scan = "SELECT topic_id, timestamp, length(substr(data, -1)) FROM messages NOT INDEXED"
        try:
            for topic, time, data in self.dbconn.execute(f"{scan} ORDER BY id"):
                if not (isinstance(topic, int) and isinstance(time, int) and data is not None):
                    return found, True  # a row of a damaged page: not a message
                found.append((topic, time))
                self._rows += 1
                self._ordered &= time >= previous
                previous = time
        except apsw.Error:
            return found, True
        return found, False

    def _topics(self) -> list[Connection]:
        """The topics table (and message definitions, if any can be read) as connections."""
        assert self.dbconn
        columns = {row[1] for row in self.dbconn.execute("PRAGMA table_info(topics)")}
        qos = "offered_qos_profiles" if "offered_qos_profiles" in columns else "''"
        digest = "type_description_hash" if "type_description_hash" in columns else "''"
        definitions: dict[str, MessageDefinition] = {}
        formats = {"ros2msg": MessageDefinitionFormat.MSG, "ros2idl": MessageDefinitionFormat.IDL}
        try:
            for name, encoding, text in self.dbconn.execute(
                "SELECT topic_type, encoding, encoded_message_definition FROM message_definitions"
            ):
                if encoding in formats:
                    definitions.setdefault(name, MessageDefinition(formats[encoding], text))
        except apsw.Error:
            pass  # no such table (older schemas), or damaged: the default types stand in
        none = MessageDefinition(MessageDefinitionFormat.NONE, "")
        return [
            Connection(
                cid,
                topic,
                msgtype,
                definitions.get(msgtype, none),
                hash_ or "",
                0,
                ConnectionExtRosbag2(serialization, parse_qos(profiles or "")),
                self,
            )
            for cid, topic, msgtype, serialization, profiles, hash_ in self.dbconn.execute(
                f"SELECT id, name, type, serialization_format, {qos}, {digest} FROM topics "
                "ORDER BY id"
            )
        ]

    def messages(
        self,
        connections: Collection[Connection],
        start: int | None = None,
        stop: int | None = None,
    ) -> Generator[tuple[Connection, int, bytes], None, None]:
        """The messages of rosbags' reader; of a recovered database, the ones recovered."""
        if self.recovery is None:
            yield from super().messages(connections, start, stop)
            return
        if self._pages is not None:
            yield from self._page_messages(connections, start, stop)
            return
        assert self.dbconn
        ids = sorted({c.id for c in connections})
        low, high = (0 if start is None else start), (_NO_TIME if stop is None else stop)
        wanted = f"topic_id IN ({','.join('?' * len(ids))}) AND timestamp >= ? AND timestamp < ?"
        # LIMIT: sqlite stops at the last row read before, not stepping into the damage
        rows = (
            f"SELECT id, topic_id, timestamp, CASE WHEN {wanted} THEN data END AS data "
            "FROM messages NOT INDEXED ORDER BY id LIMIT ?"
        )
        args = [*ids, low, high, self._rows]
        if not self._ordered:
            rows = f"SELECT * FROM ({rows}) WHERE data IS NOT NULL ORDER BY timestamp, id"
        by_id = {c.id: c for c in self.connections}
        for _, topic, time, data in self.dbconn.execute(rows, args):
            if data is not None:
                yield by_id[topic], time, data

    def _page_messages(
        self, connections: Collection[Connection], start: int | None, stop: int | None
    ) -> Generator[tuple[Connection, int, bytes], None, None]:
        """The messages found in the table's leaves, read from the file."""
        assert self._pages is not None
        wanted = {c.id: c for c in connections}
        low, high = (0 if start is None else start), (_NO_TIME if stop is None else stop)
        with Path(str(self.path)).open("rb") as stream:
            for message in self._pages:
                if message.topic in wanted and low <= message.time < high:
                    yield wanted[message.topic], message.time, read_data(stream, message)


# --- the bag folder -----------------------------------------------------------------------

_SPLIT = re.compile(r"_(\d+)$")
_ZSTD_MAGIC = b"\x28\xb5\x2f\xfd"
_METADATA_PROBLEMS = (
    "Could not read metadata",
    "Could not load YAML",
    "A metadata key",
    "Invalid bag metadata",
)
"""How rosbags' errors about a bag's metadata.yaml begin."""


def storage_files(folder: Path) -> list[Path]:
    """The storage files of a bag folder, in the order the recorder split them."""

    def split_order(path: Path) -> tuple[str, int, str]:
        match = _SPLIT.search(path.stem)
        stem = path.stem[: match.start()] if match else path.stem
        return stem, int(match.group(1)) if match else -1, path.name

    try:
        found = [p for p in folder.iterdir() if p.suffix in STORAGE_SUFFIXES]
    except OSError:
        return []
    return sorted((p for p in found if not p.name.startswith(".") and p.is_file()), key=split_order)


class RecoveringDirectoryReader(DirectoryReader):
    """rosbags' reader of a bag folder, with recovering storage readers; a folder whose
    ``metadata.yaml`` is missing or unreadable is read from its storage files."""

    STORAGE_PLUGINS: Mapping[str, type[ReaderProtocol]] = {
        "mcap": RecoveringMcapReader,
        "sqlite3": RecoveringSqlite3Reader,
    }
    recovery: BagRecovery | None = None

    def __init__(self, path: Path) -> None:  # rosbags' refuses a folder without metadata.yaml
        self.path = path
        self.connections = []
        self.metadata = _EMPTY
        self.files = []
        self.storages = []
        self.stack = None

    def open(self) -> None:
        problem = None
        if not (self.path / METADATA).exists():
            problem = f"{METADATA} missing"
        else:
            try:
                super().open()
            except ReaderError as error:
                if not str(error).startswith(_METADATA_PROBLEMS):
                    raise
                problem = f"{METADATA} unreadable"
        if problem is not None:
            self._open_storages()
        notes = [problem] if problem else []
        several = len(self.storages) > 1
        for storage in self.storages:
            recovery = getattr(storage, "recovery", None)
            if recovery is not None:
                name = Path(str(getattr(storage, "path", ""))).name
                notes.append(f"{name} {recovery.what()}" if several else recovery.what())
        if not notes:
            return
        if problem is None:  # metadata.yaml counts messages the storage no longer holds
            self._count_from_storages()
        seconds = _seconds(self.metadata)
        self.recovery = BagRecovery(", ".join(notes), self.metadata.message_count, seconds)

    def _open_storages(self) -> None:
        files = storage_files(Path(str(self.path)))
        if not files:
            raise ReaderError(f"no {METADATA} and no storage file (.db3, .mcap)")
        self.stack = ExitStack()
        try:
            for path in files:
                storage = self.STORAGE_PLUGINS[STORAGE_SUFFIXES[path.suffix]](path)
                storage.open()
                self.stack.callback(storage.close)
                self.storages.append(storage)
            self.connections = []
            for storage in self.storages:
                for found in storage.connections:
                    if not any(_same(found, known) for known in self.connections):
                        ide = len(self.connections) + 1
                        self.connections.append(found._replace(id=ide, msgcount=0, owner=self))
                    elif found.msgdef.format != MessageDefinitionFormat.NONE:
                        self._define(found)
            self._count_from_storages()
            if self._compressed_messages():
                self.metadata = self.metadata._replace(
                    compression_format="zstd", compression_mode="message"
                )
        except BaseException:
            self.stack.close()
            self.storages = []
            raise

    def _compressed_messages(self) -> bool:
        """Whether the messages are zstd frames (a bag recorded with message compression,
        which only its missing metadata.yaml says): a CDR message never begins so."""
        for storage in self.storages:
            if not storage.connections:
                continue
            stream = storage.messages(storage.connections)
            try:
                first = next(stream, None)
            finally:
                stream.close()
            if first is not None:
                return bytes(first[2][:4]) == _ZSTD_MAGIC
        return False

    def _define(self, found: Connection) -> None:
        """Give the connection like ``found`` its message definition if it has none."""
        for index, known in enumerate(self.connections):
            if _same(found, known) and known.msgdef.format == MessageDefinitionFormat.NONE:
                self.connections[index] = known._replace(msgdef=found.msgdef)

    def _count_from_storages(self) -> None:
        counts: dict[int, int] = defaultdict(int)
        for storage in self.storages:
            for found in storage.connections:
                for known in self.connections:
                    if _same(found, known):
                        counts[known.id] += found.msgcount
                        break
        self.connections = [c._replace(msgcount=counts[c.id]) for c in self.connections]
        ends = [s.metadata for s in self.storages if s.metadata.message_count]
        count = sum(m.message_count for m in ends)
        first = min((m.start_time for m in ends), default=0)
        last = max((m.end_time - 1 for m in ends), default=0)
        self.metadata = _metadata(count, first, last)._replace(
            compression_format=self.metadata.compression_format,
            compression_mode=self.metadata.compression_mode,
            ros_distro=self.metadata.ros_distro,
            custom=self.metadata.custom,
        )


def _same(found: Connection, known: Connection) -> bool:
    """Whether a storage's connection is a bag's (rosbags matches them so)."""
    return (
        found.topic == known.topic
        and found.msgtype == known.msgtype
        and found.ext == known.ext
        and (not found.digest or not known.digest or found.digest == known.digest)
    )


class RecoveringReader2(Ros2Reader):
    """rosbags' ROS 2 reader with the recovering readers of this module."""

    STORAGE_PLUGINS: Mapping[str, type[ReaderProtocol]] = {
        "dir": RecoveringDirectoryReader,
        ".mcap": RecoveringMcapReader,
        ".db3": RecoveringSqlite3Reader,
    }

    @property
    def recovery(self) -> BagRecovery | Recovery | None:
        """What was recovered (None: the bag was whole)."""
        found = getattr(self.storage, "recovery", None)
        return found if isinstance(found, BagRecovery | Recovery) else None
