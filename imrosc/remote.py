"""Bags named by URL: ``s3://``, ``gs://``, ``http(s)://`` or any other fsspec protocol.

A bag URL travels through the stages as a :class:`BagUrl`, a path whose text is the URL, so
that every stage that names, sorts, reports and sends bags (to worker processes and Dask
workers) carries it unchanged. Two places know it is remote: :func:`discover_url` (what bags
a URL or a glob of URLs names) and :func:`fetched` (a local copy for rosbags, which reads
files: the process that reads the bag downloads it into its scratch folder, keeps it while
it may read it again, and deletes it after). fsspec does the transfers; the protocols other
than local files need a package of their own (:data:`PACKAGES`), named in the error when
it is missing.
"""

from __future__ import annotations

import atexit
import glob
import multiprocessing
import os
import re
import shutil
import sys
import tempfile
import threading
from collections import OrderedDict
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from imrosc.diagnostics import Diagnostic, make

_URL = re.compile(r"^[A-Za-z][A-Za-z0-9+.-]*://")
_MAGIC = re.compile(r"[*?[]")
ROS1_SUFFIX = ".bag"
ROS2_METADATA = "metadata.yaml"

PACKAGES = {
    "s3": ("s3fs", "s3"),
    "s3a": ("s3fs", "s3"),
    "gs": ("gcsfs", "gs"),
    "gcs": ("gcsfs", "gs"),
    "http": ("aiohttp", "http"),
    "https": ("aiohttp", "http"),
}
"""Per protocol, the package fsspec needs for it and imrosc's extra that installs it."""
GCS_EMULATOR = "STORAGE_EMULATOR_HOST"
"""The variable naming a Google Cloud Storage endpoint other than Google's (gcsfs's)."""
GCSFS_CONTROL_PLANE = "GCSFS_EXPERIMENTAL_ZB_HNS_SUPPORT"
"""gcsfs's switch of its bucket-type lookup (Google's gRPC control plane): off by default
when :data:`GCS_EMULATOR` names another endpoint, which does not serve it."""

SCRATCH_MB = 2048
"""Downloaded bags a process keeps (MiB, ``IMROSC_SCRATCH_MB``) for its next reads of them."""


def is_url(text: str) -> bool:
    """Whether a bag argument is a URL (``scheme://...``).

    >>> is_url("s3://fleet/run1.bag"), is_url("runs/run1.bag"), is_url("C:/x")
    (True, False, False)
    """
    return bool(_URL.match(text))


def has_magic(text: str) -> bool:
    """Whether a bag argument is a glob pattern (``*``, ``?`` or ``[``)."""
    return bool(_MAGIC.search(text))


def _segments(url: str) -> tuple[str, ...]:
    scheme, rest = url.split("://", 1)
    path = rest.split("?", 1)[0].split("#", 1)[0]
    return ("/", f"{scheme}:", *[part for part in path.split("/") if part])


_Base: Any = type(Path())


class BagUrl(_Base):  # type: ignore[misc]
    """A bag named by URL, as a path: ``str()`` is the URL, ``name`` and ``suffix`` are its
    last segment's, it is absolute and resolves to itself, and it pickles as its URL."""

    url: str

    def __new__(cls, url: str) -> BagUrl:
        self: BagUrl = super().__new__(cls, *_segments(url))
        self.url = url
        return self

    def __init__(self, url: str) -> None:
        if sys.version_info >= (3, 12):  # pragma: no cover - Path's own __init__ from 3.12
            super().__init__(*_segments(url))

    def with_segments(self, *segments: Any) -> Path:  # pragma: no cover - Python >= 3.12
        return Path(*segments)

    def __str__(self) -> str:
        return getattr(self, "url", None) or str(super().__str__())

    def __fspath__(self) -> str:
        return str(self)

    def __repr__(self) -> str:
        return f"BagUrl({str(self)!r})"

    def __reduce__(self) -> tuple[Any, ...]:
        return (BagUrl, (str(self),))

    def __eq__(self, other: object) -> bool:
        return isinstance(other, BagUrl) and str(other) == str(self)

    def __hash__(self) -> int:
        return hash(("BagUrl", str(self)))

    def absolute(self) -> BagUrl:
        return self

    def resolve(self, strict: bool = False) -> BagUrl:
        return self

    def is_absolute(self) -> bool:
        return True

    @property
    def parent(self) -> BagUrl:
        """The URL of the folder that holds this one."""
        head, _, _ = str(self).rstrip("/").rpartition("/")
        return BagUrl(head) if "://" in head else self

    def __truediv__(self, name: Any) -> BagUrl:
        return BagUrl(f"{str(self).rstrip('/')}/{name}")

    def with_name(self, name: str) -> BagUrl:
        return self.parent / name

    @property
    def protocol(self) -> str:
        return str(self).split("://", 1)[0].lower()


def bag_arguments(ctx: Any, param: Any, values: tuple[str, ...]) -> tuple[Path, ...]:
    """A click callback: bags on the command line, paths, globs or URLs (:func:`bag_path`)."""
    return tuple(bag_path(value) for value in values)


def bag_path(entry: str | Path, base: Path | None = None) -> Path:
    """A bag as the user names it: a URL (:class:`BagUrl`; ``file://`` gives a local path),
    else a path, relative to ``base`` when given.

    >>> bag_path("https://host/r.bag"), bag_path("r.bag", Path("/data"))
    (BagUrl('https://host/r.bag'), PosixPath('/data/r.bag'))
    """
    if isinstance(entry, BagUrl):
        return entry
    text = str(entry)
    if is_url(text):
        if text.lower().startswith("file://"):
            return Path(text[len("file://") :])
        return BagUrl(text)
    return base / text if base is not None else Path(text)


class RemoteError(Exception):
    """A bag URL that cannot be used; the message is one line, the URL apart."""


def _one_line(error: BaseException) -> str:
    text = " ".join(str(error).split())
    return text[:200] or type(error).__name__


def _filesystem(url: BagUrl) -> Any:
    """The fsspec file system of the URL's protocol, or :class:`RemoteError` saying what to
    install."""
    try:
        import fsspec
    except ImportError:  # pragma: no cover - a dependency of imrosc
        raise RemoteError("reading bags by URL needs fsspec: pip install fsspec") from None
    protocol = url.protocol
    if PACKAGES.get(protocol, ("",))[0] == "gcsfs" and os.environ.get(GCS_EMULATOR):
        # gcsfs asks Google's gRPC control plane what kind of bucket it reads: an emulator
        # or a compatible store does not serve it, and each bucket then waits a minute
        os.environ.setdefault(GCSFS_CONTROL_PLANE, "false")
    try:
        return fsspec.filesystem(protocol)
    except ImportError:
        package, extra = PACKAGES.get(protocol, (None, None))
        if package is None:
            raise RemoteError(
                f"fsspec cannot read {protocol}:// URLs here: install the package it needs"
            ) from None
        raise RemoteError(
            f"reading {protocol}:// URLs needs {package}: pip install {package} "
            f"(or pip install 'imrosc[{extra}]')"
        ) from None
    except ValueError:
        raise RemoteError(f"fsspec knows no protocol {protocol}://") from None


def _problem(error: BaseException) -> str:
    """A transfer's error in one line."""
    if isinstance(error, RemoteError):
        return str(error)
    status = getattr(error, "status", None)  # a web server's answer
    if isinstance(status, int) and status >= 400:
        if status == 404:
            return "not found (HTTP 404)"
        if status in (401, 403):
            return f"access denied (HTTP {status})"
        return f"the server answered HTTP {status}: {getattr(error, 'message', '') or ''}".strip()
    cause = error.__cause__
    if isinstance(error, FileNotFoundError) and cause is not None and cause is not error:
        return _problem(cause)  # fsspec's http: an answer or a host out of reach
    if isinstance(error, FileNotFoundError):
        return "not found"
    if isinstance(error, PermissionError):
        return "access denied"
    name = type(error).__name__
    if isinstance(error, OSError) or "Connect" in name or "Timeout" in name:
        return f"cannot reach it: {_one_line(error)}"
    return f"cannot download it: {name}: {_one_line(error)}"


def _error(url: str, message: str) -> Diagnostic:
    return make(url, 1, 1, "bag-error", message)


def _not_a_bag(url: str) -> Diagnostic:
    return _error(
        url, f"not a bag: expected a {ROS1_SUFFIX} file or a folder holding {ROS2_METADATA}"
    )


def _url_of(fs: Any, url: BagUrl, found: str) -> BagUrl:
    """A path an fsspec listing gives, as a URL of the same protocol."""
    text = str(found)
    return BagUrl(text if "://" in text else f"{url.protocol}://{text.lstrip('/')}")


def discover_url(url: BagUrl) -> tuple[list[Path], list[Diagnostic]]:
    """The bags a URL names, sorted, and a ``bag-error`` for everything else: a ``.bag``
    file, a ROS 2 bag folder (or its ``metadata.yaml``), a glob of them, or a folder that
    a listing shows (object stores; web servers that list their folders)."""
    text = str(url)
    # a web URL's query is no pattern (a presigned URL's signature: ?X-Amz-Signature=...)
    path = text.split("?", 1)[0] if url.protocol in ("http", "https") else text
    try:
        fs = _filesystem(url)
        if has_magic(path):
            matches = sorted(fs.glob(text))
            if not matches:
                return [], [_error(text, "no bag matches the pattern")]
            bags: list[Path] = []
            problems: list[Diagnostic] = []
            for match in matches:
                more, bad = _named(fs, _url_of(fs, url, match))
                bags += more
                problems += bad
            return sorted(set(bags)), problems
        return _named(fs, url)
    except Exception as error:  # a transfer fails with anything from fsspec's back ends
        return [], [_error(text, _problem(error))]


def _is_ros1(url: BagUrl) -> bool:
    """Whether a URL names a ROS 1 bag: ``NAME.bag``, or the ``NAME.bag.active`` of a
    recording never closed (read up to its last whole record once downloaded)."""
    return url.suffix == ROS1_SUFFIX or str(url.name).endswith(ROS1_SUFFIX + ".active")


def _named(fs: Any, url: BagUrl) -> tuple[list[Path], list[Diagnostic]]:
    text = str(url)
    if url.name == ROS2_METADATA:
        return _named(fs, url.parent)
    if _is_ros1(url):
        fs.info(text)  # not found: FileNotFoundError
        return [url], []
    if fs.exists(str(url / ROS2_METADATA)):
        return [url], []
    if not fs.isdir(text):
        if not fs.exists(text):
            raise FileNotFoundError(text)
        return [], [_not_a_bag(text)]
    bags: set[Path] = set()
    for found in fs.find(text):
        child = _url_of(fs, url, found)
        if _is_ros1(child):
            bags.add(child)
        elif child.name == ROS2_METADATA:
            bags.add(child.parent)
    if not bags:
        return [], [_error(text, "folder holds no bag")]
    return sorted(bags), []


def local_glob(path: Path) -> list[Path] | None:
    """The paths a local glob pattern matches, sorted (``None``: ``path`` is no pattern, or
    names a file as it is)."""
    text = str(path)
    if not has_magic(text) or os.path.lexists(path):
        return None
    return [Path(found) for found in sorted(glob.glob(text, recursive=True))]


# -- local copies ----------------------------------------------------------------------------


@dataclass
class _Copy:
    path: Path
    size: int
    users: int = 0


class Scratch:
    """This process's downloaded bags, by URL, each in a folder of its own under the
    temporary folder (``TMPDIR``): a bag in use is kept, the others deleted, least recently
    used first, past ``limit`` bytes (0: each as soon as it is read); all deleted when the
    process exits."""

    def __init__(self, limit: int) -> None:
        self.limit = limit
        self.pid = os.getpid()
        self.copies: OrderedDict[str, _Copy] = OrderedDict()
        self.lock = threading.Lock()
        if limit:
            atexit.register(self.clear)

    @contextmanager
    def local(self, url: BagUrl) -> Iterator[Path]:
        """A local copy of the bag at ``url`` while the context lasts (:class:`RemoteError`
        when it cannot be downloaded)."""
        with self.lock:
            copy = self.copies.get(str(url))
            if copy is None:
                copy = self.copies[str(url)] = _download(url)
            self.copies.move_to_end(str(url))
            copy.users += 1
        try:
            yield copy.path
        finally:
            with self.lock:
                copy.users -= 1
                self._trim()

    def _trim(self) -> None:
        total = sum(copy.size for copy in self.copies.values())
        for key, copy in list(self.copies.items()):
            if total <= self.limit:
                break
            if copy.users == 0:
                shutil.rmtree(copy.path.parent, ignore_errors=True)
                del self.copies[key]
                total -= copy.size

    def clear(self) -> None:
        """Delete every copy (at exit)."""
        for copy in self.copies.values():
            shutil.rmtree(copy.path.parent, ignore_errors=True)
        self.copies.clear()


def _download(url: BagUrl) -> _Copy:
    fs = _filesystem(url)
    target = Path(tempfile.mkdtemp(prefix="imrosc-bag-")) / (url.name or "bag")
    try:
        if _is_ros1(url):
            fs.get_file(str(url), str(target))
        else:
            _get_ros2(fs, url, target)
    except Exception as error:  # a transfer fails with anything from fsspec's back ends
        shutil.rmtree(target.parent, ignore_errors=True)
        raise RemoteError(_problem(error)) from None
    size = sum(p.stat().st_size for p in [target, *target.rglob("*")] if p.is_file())
    return _Copy(target, size)


def _get_ros2(fs: Any, url: BagUrl, target: Path) -> None:
    """A ROS 2 bag folder: its ``metadata.yaml``, then the storage files it lists."""
    from ruamel.yaml import YAML

    target.mkdir()
    fs.get_file(str(url / ROS2_METADATA), str(target / ROS2_METADATA))
    data = YAML(typ="safe").load((target / ROS2_METADATA).read_text(encoding="utf-8"))
    info = data.get("rosbag2_bagfile_information", {}) if isinstance(data, dict) else {}
    for name in info.get("relative_file_paths", ()) or ():
        if not isinstance(name, str) or name.startswith("/") or ".." in name.split("/"):
            raise RemoteError(f"{ROS2_METADATA} lists a storage file outside the bag: {name}")
        (target / name).parent.mkdir(parents=True, exist_ok=True)
        fs.get_file(str(url / name), str(target / name))


_scratch: Scratch | None = None


def scratch() -> Scratch:
    """This process's :class:`Scratch`: in the main process it keeps ``IMROSC_SCRATCH_MB``
    (:data:`SCRATCH_MB`) of copies for the stages that read the bags again; worker processes
    (local ones, which are ended without their exit handlers, and Dask's) keep none."""
    global _scratch  # noqa: PLW0603 - one per process
    if _scratch is None or _scratch.pid != os.getpid():  # a forked child: copies of its own
        limit = 0
        if multiprocessing.parent_process() is None:
            try:
                limit = int(os.environ.get("IMROSC_SCRATCH_MB", SCRATCH_MB))
            except ValueError:
                limit = SCRATCH_MB
        _scratch = Scratch(max(limit, 0) * 1024 * 1024)
    return _scratch


@contextmanager
def fetched(url: BagUrl) -> Iterator[Path]:
    """A local copy of a bag URL for as long as the context lasts."""
    with scratch().local(url) as path:
        yield path
