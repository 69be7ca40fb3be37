"""Finding and opening bags: every stage that reads bags goes through here.

A bag is a ROS 1 ``.bag`` file or a ROS 2 bag directory (one holding ``metadata.yaml``, with
sqlite3 ``.db3`` or ``.mcap`` storage files). :func:`discover_bags` turns a path the user gave
into the bags it names, and reports what it cannot use; :func:`open_bag` opens one with
rosbags' ``AnyReader`` and turns every way a bag can be broken (missing, truncated, corrupt,
an unsupported serialization, an unknown message type) into a :class:`BagError` with a
one-line message, never a traceback.
"""

from __future__ import annotations

import functools
import os
import stat
from collections.abc import Collection, Generator, Iterator
from contextlib import ExitStack, contextmanager, suppress
from pathlib import Path

from rosbags.highlevel import AnyReader, AnyReaderError
from rosbags.interfaces import Connection
from rosbags.rosbag1 import ReaderError as Ros1ReaderError
from rosbags.rosbag2 import ReaderError as Ros2ReaderError
from rosbags.serde import SerdeError
from rosbags.typesys import Stores, TypesysError, get_typestore
from rosbags.typesys.store import Typestore

from imrosc import progress
from imrosc.bagrecover import RecoveringReader
from imrosc.bagrecover_ros2 import RecoveringReader2, storage_files
from imrosc.diagnostics import Diagnostic, make
from imrosc.remote import BagUrl, RemoteError, discover_url, fetched, local_glob

__all__ = [
    "ROS1_SUFFIX",
    "ROS2_METADATA",
    "ROS2_STORAGE_SUFFIXES",
    "BagError",
    "MessageError",
    "discover_bags",
    "is_unfinished",
    "open_bag",
    "recovered",
    "recovered_diagnostic",
    "time_text",
]

ROS1_SUFFIX = ".bag"
ACTIVE_SUFFIX = ".active"
ROS2_METADATA = "metadata.yaml"
ROS2_STORAGE_SUFFIXES = (".db3", ".mcap")

_SQLITE_COMPANIONS = ("-wal", "-shm", "-journal")
"""What sqlite writes beside a database (a recording's open transaction)."""
_MAX_MESSAGE = 200
_ROSBAGS_ERRORS = (AnyReaderError, Ros1ReaderError, Ros2ReaderError, SerdeError, TypesysError)


class BagError(Exception):
    """A bag that cannot be found, opened or read; ``message`` is one line."""

    def __init__(self, path: Path, message: str) -> None:
        super().__init__(f"{path}: {message}")
        self.path = path
        self.message = message

    def diagnostic(self) -> Diagnostic:
        """The ``bag-error`` diagnostic for this problem (a bag has no lines: 1:1)."""
        return make(str(self.path), 1, 1, "bag-error", self.message)


class MessageError(BagError):
    """One message of a readable bag cannot be decoded; the rest of the bag may be fine."""


def _one_line(error: BaseException) -> str:
    """A one-line description of an exception raised by rosbags or the OS."""
    if isinstance(error, OSError) and error.strerror:
        text = error.strerror
    elif isinstance(error, UnicodeError):  # its args hold the raw bytes: quote none
        text = f"text that is not UTF-8 ({getattr(error, 'reason', error)})"
    else:  # bytes among the arguments are the damaged data itself: quote none
        text = " ".join(str(part) for part in error.args if not isinstance(part, bytes | bytearray))
    text = " ".join(text.split()).rstrip(".")
    if not text:
        return type(error).__name__
    if len(text) > _MAX_MESSAGE:
        text = text[: _MAX_MESSAGE - 3] + "..."
    return text[:1].lower() + text[1:]


def time_text(nanoseconds: int) -> str:
    """A bag time in seconds with all nine decimals, as rosbag prints it.

    >>> time_text(1379178116917492974)
    '1379178116.917492974'
    """
    seconds, rest = divmod(nanoseconds, 1_000_000_000)
    return f"{seconds}.{rest:09d}"


@functools.lru_cache(maxsize=1)
def _fallback_typestore() -> Typestore:
    """Types for ROS 2 bags that store no message definitions (older rosbag2 versions)."""
    return get_typestore(Stores.LATEST)


def is_unfinished(path: Path) -> bool:
    """Whether ``path`` names an unfinished ROS 1 bag: ``rosbag record`` writes
    ``NAME.bag.active`` and renames it ``NAME.bag`` when it closes it; interrupted, it
    leaves the ``.active`` file, unindexed (read up to its last whole record)."""
    return path.name.endswith(ROS1_SUFFIX + ACTIVE_SUFFIX)


class _AsRos1(type(Path())):  # type: ignore[misc]
    """A path AnyReader takes for a ROS 1 bag whatever its name ends with (it tells the two
    formats apart by the suffix ``.bag`` alone)."""

    @property
    def suffix(self) -> str:
        return ROS1_SUFFIX


class _SafeReader(AnyReader):
    """An AnyReader whose reading methods raise only :class:`BagError` on a broken bag."""

    def __init__(self, path: Path, name: Path) -> None:
        self.bag_path = name
        if path.suffix == ROS1_SUFFIX or is_unfinished(path):
            super().__init__([_AsRos1(path)], default_typestore=_fallback_typestore())
            self.readers = [RecoveringReader(path)]  # scanned when cut short or never indexed
            return
        # AnyReader's own ROS 2 reader refuses a folder without metadata.yaml: set up as
        # AnyReader.__init__ does, with a reader that reads such a folder and cut storage
        if not path.exists():
            raise FileNotFoundError(path)
        self.paths = [path]
        self.is2 = True
        self.stack = None
        self.connections = []
        self.default_typestore = _fallback_typestore()
        self.typestore = get_typestore(Stores.EMPTY)
        self.readers = [RecoveringReader2(path)]

    @property
    def recovered(self) -> str | None:
        """What was recovered from a bag cut short, never indexed or without its
        ``metadata.yaml``, in one line (None: the bag was read whole)."""
        recovery = getattr(self.readers[0], "recovery", None) if self.readers else None
        return None if recovery is None else recovery.text()

    def messages(
        self,
        connections: Collection[Connection] = (),
        start: int | None = None,
        stop: int | None = None,
    ) -> Generator[tuple[Connection, int, bytes], None, None]:
        """The messages of :meth:`AnyReader.messages`; a broken chunk raises BagError. The
        progress bar hears of them every :data:`imrosc.progress.EVERY` messages."""
        stream = super().messages(connections, start, stop)
        selected = connections or self.connections
        total = sum(int(getattr(c, "msgcount", 0) or 0) for c in selected)
        every = progress.EVERY
        read = 0
        while True:
            try:
                item = next(stream)
            except StopIteration:
                return
            except Exception as error:  # corrupt data raises anything from rosbags
                message = f"cannot read messages (bag damaged or truncated?): {_one_line(error)}"
                raise BagError(self.bag_path, message) from error
            read += 1
            if read == every:
                progress.reading(read, total)
                read = 0
            yield item

    def deserialize(self, rawdata: bytes, typ: str) -> object:
        """Decode one message; an unknown type or a corrupt message raises MessageError."""
        if typ not in self.typestore.fielddefs:
            raise MessageError(self.bag_path, f"unknown message type {typ}")
        try:
            return super().deserialize(rawdata, typ)
        except Exception as error:  # corrupt data raises anything from rosbags
            message = f"cannot decode a {typ} message: {_one_line(error)}"
            raise MessageError(self.bag_path, message) from error


def recovered(reader: AnyReader) -> str | None:
    """What was recovered from a ROS 1 bag cut short or never indexed, in one line (None:
    the bag was read through its index); :mod:`imrosc.bagrecover` says how."""
    found = getattr(reader, "recovered", None)
    return found if isinstance(found, str) else None


def recovered_diagnostic(path: Path, reader: AnyReader) -> Diagnostic | None:
    """The ``bag-recovered`` warning for a bag :func:`recovered` says was recovered."""
    found = recovered(reader)
    return None if found is None else make(str(path), 1, 1, "bag-recovered", found)


@contextmanager
def open_bag(path: Path) -> Iterator[AnyReader]:
    """Open one bag (a ``.bag`` file or a ROS 2 bag directory, or either by URL: a
    :class:`~imrosc.remote.BagUrl`, downloaded for the time it is open) for reading.

    Anything that goes wrong while opening, iterating ``messages()`` or calling
    ``deserialize()`` raises :class:`BagError` (:class:`MessageError` for one bad message);
    rosbags' own errors raised in the ``with`` body become BagError too.
    """
    with ExitStack() as stack:
        local = path
        if isinstance(path, BagUrl):
            try:
                local = stack.enter_context(fetched(path))
            except RemoteError as error:
                raise BagError(path, str(error)) from None

        def said(error: BaseException) -> str:  # of a URL's bag, its URL, not its copy
            text = _one_line(error)
            return text if local is path else text.replace(str(local), str(path))

        try:
            reader = _SafeReader(local, path)
            reader.open()
        except Exception as error:  # a broken bag raises anything from rosbags
            if not os.path.lexists(local):
                raise BagError(path, "no such file or directory") from None
            raise BagError(path, f"cannot open bag: {said(error)}") from error
        try:
            yield reader
        except _ROSBAGS_ERRORS as error:
            raise BagError(path, f"cannot read bag: {said(error)}") from error
        finally:
            with suppress(Exception):  # closing a broken bag must not hide the first error
                reader.close()


def _is_ros2_bag(directory: Path) -> bool:
    """Whether a folder is a ROS 2 bag: it holds ``metadata.yaml``, or it holds storage
    files and nothing else (a recorder killed before it wrote ``metadata.yaml``)."""
    if (directory / ROS2_METADATA).is_file():
        return True
    storage = storage_files(directory)
    if not storage:
        return False
    names = {p.name for p in storage}
    try:
        entries = [e for e in os.listdir(directory) if not e.startswith(".")]
    except OSError:
        return False
    return all(e in names or e.endswith(_SQLITE_COMPANIONS) for e in entries)


def _not_a_bag(path: Path) -> Diagnostic:
    if path.suffix in ROS2_STORAGE_SUFFIXES:
        reason = f"a ROS 2 storage file without {ROS2_METADATA} beside it (try ros2 bag reindex)"
    else:
        reason = f"not a bag: expected a {ROS1_SUFFIX} file or a directory holding {ROS2_METADATA}"
    return make(str(path), 1, 1, "bag-error", reason)


def _search(directory: Path, bags: list[Path], found: list[Diagnostic], seen: set[Path]) -> None:
    """Collect the bags under a directory that is not itself a bag."""
    real = directory.resolve()
    if real in seen:
        return
    seen.add(real)
    try:
        entries = sorted(os.scandir(directory), key=lambda entry: entry.name)
    except OSError as error:
        message = f"cannot read directory: {error.strerror or _one_line(error)}"
        found.append(make(str(directory), 1, 1, "bag-error", message))
        return
    for entry in entries:
        if entry.name.startswith("."):
            continue
        child = directory / entry.name
        if child.is_dir():
            if _is_ros2_bag(child):
                bags.append(child)
            else:
                _search(child, bags, found, seen)
        elif (child.suffix == ROS1_SUFFIX or is_unfinished(child)) and child.is_file():
            bags.append(child)
        else:
            found.append(_not_a_bag(child))


def discover_bags(path: Path) -> tuple[list[Path], list[Diagnostic]]:
    """The bags a path names, sorted, and a ``bag-error`` for everything else.

    * a ``.bag`` file is a ROS 1 bag, and so is a ``.bag.active`` file (an unfinished one,
      :func:`is_unfinished`);
    * a directory holding ``metadata.yaml`` is a ROS 2 bag, and so is one holding storage
      files (``.db3``, ``.mcap``) and nothing else (a recorder killed before it wrote
      ``metadata.yaml``: read from the storage files); its ``metadata.yaml`` or one of its
      storage files stands for it too;
    * any other directory is searched recursively: each ``.bag`` file and ROS 2 bag directory
      in it is a bag, each other file is reported as not a bag (hidden files and directories,
      whose names start with ``.``, are skipped), and a directory with no bag is reported.

    A missing path or a file that is not a bag is reported. A glob pattern (``*``, ``?``,
    ``[``) that names no file as it is names the bags of every path it matches; a URL
    (:class:`~imrosc.remote.BagUrl`) is looked up where it points
    (:func:`~imrosc.remote.discover_url`).
    """
    if isinstance(path, BagUrl):
        return discover_url(path)
    matches = local_glob(path)
    if matches is not None:
        if not matches:
            return [], [make(str(path), 1, 1, "bag-error", "no bag matches the pattern")]
        every: list[Path] = []
        problems: list[Diagnostic] = []
        for match in matches:
            more, bad = discover_bags(match)
            every += more
            problems += bad
        return sorted(set(every)), problems
    try:
        mode = path.stat().st_mode
    except OSError as error:
        reason = "no such file or directory" if isinstance(error, FileNotFoundError) else None
        message = reason or f"cannot read: {error.strerror or _one_line(error)}"
        return [], [make(str(path), 1, 1, "bag-error", message)]
    if stat.S_ISDIR(mode):
        if _is_ros2_bag(path):
            return [path], []
        bags: list[Path] = []
        found: list[Diagnostic] = []
        _search(path, bags, found, set())
        if not bags and not found:
            found.append(make(str(path), 1, 1, "bag-error", "directory holds no bag"))
        return sorted(set(bags)), found
    if path.suffix == ROS1_SUFFIX or is_unfinished(path):
        return [path], []
    is_ros2_part = path.name == ROS2_METADATA or path.suffix in ROS2_STORAGE_SUFFIXES
    if is_ros2_part and _is_ros2_bag(path.parent):
        return [path.parent], []
    return [], [_not_a_bag(path)]


def publisher_of(connection: Connection) -> str | None:
    """The node that published on a connection of a bag: ROS 1's ``callerid`` (``None``
    where the bag does not say, as in ROS 2 bags)."""
    return getattr(connection.ext, "callerid", None) or None
