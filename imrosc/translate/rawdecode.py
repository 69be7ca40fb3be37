"""Columns straight from serialized messages: a chunk decoded with numpy, not message by message.

:class:`RawDecoder` gives exactly the columns :class:`~imrosc.translate.columns.Flattener`
gives for the deserialized messages (same names, dtypes and bits), but reads the values out
of the raw bytes of the whole chunk at once. ROS 1 serialization is little-endian without
padding; CDR (ROS 2) has a 4-byte encapsulation header and aligns each primitive to its size
relative to the data start.

The message definition is walked once per chunk. The offset of the current field is one
number while every message agrees on it (same byte length, same length prefixes so far): a
field is then a strided numpy view over the joined chunk. Once a length prefix differs (frame
ids of other lengths) offsets are kept per message, and the rest of every message is copied
once into rows of one width, after which fields are strided views again. Strings are decoded
once per distinct value (found by comparing byte rows).

Whatever it does not handle (big-endian CDR, ``wstring``, very long arrays of messages whose
layout varies, a message rosbags would reject) makes :meth:`RawDecoder.decode` return None:
the caller then deserializes, so correctness never depends on this module.

>>> from rosbags.typesys import Stores, get_typestore
>>> from imrosc.msgtypes import flatten
>>> from imrosc.translate.layout import topic_layout
>>> store = get_typestore(Stores.ROS1_NOETIC)
>>> kind = "std_msgs/msg/Float64"
>>> layout = topic_layout("/volt", kind, flatten(store, kind), "volt", trigger=True)
>>> raws = [store.serialize_ros1(store.types[kind](data=v), kind) for v in (1.5, -2.0)]
>>> RawDecoder(store, kind, layout, "ros1").decode(raws)["volt.data"].tolist()
[1.5, -2.0]
"""

from __future__ import annotations

import contextlib
from collections.abc import Sequence
from typing import Any, Literal

import numpy as np
import numpy.typing as npt
from rosbags.interfaces import Nodetype

from imrosc.infer.core import Variable
from imrosc.msgtypes import flatten
from imrosc.translate.layout import TopicLayout

Columns = dict[str, npt.NDArray[Any]]
IntArray = npt.NDArray[np.int64]
Rel = int | IntArray
"""An offset relative to the data start: one for all messages, or one per message."""

_PRIMITIVES: dict[str, str] = {  # the numpy dtypes rosbags unpacks each primitive as
    "bool": "u1",
    "byte": "i1",
    "char": "u1",
    "int8": "i1",
    "uint8": "u1",
    "int16": "<i2",
    "uint16": "<u2",
    "int32": "<i4",
    "uint32": "<u4",
    "int64": "<i8",
    "uint64": "<u8",
    "float32": "<f4",
    "float64": "<f8",
}
_U1 = np.dtype("u1")
_U4 = np.dtype("<u4")
_STATS = ("avg", "std", "min", "max")
MAX_STEPS = 2_000
"""Field visits a chunk may spend walking arrays of messages whose layout is not static."""
MAX_DISTINCT_COUNTS = 256
MAX_DISTINCT_TEXTS = 8
MAX_DEPTH = 64
MAX_CHUNK_BYTES = 1 << 29
"""Larger chunks are left to the deserializing path (joining them would copy it all)."""
_EMPTY_MEMBER = "structure_needs_at_least_one_member"  # not serialized in ROS 1 (rosbags)


class _UnsupportedError(Exception):
    """The message type (or the layout over it) is not decoded here."""


class _FallbackError(Exception):
    """This chunk must be deserialized message by message."""


class _NotStaticError(Exception):
    """The size of a field depends on the data."""


def _view(
    buf: npt.NDArray[np.uint8],
    shape: tuple[int, ...],
    dtype: np.dtype[Any],
    offset: int,
    strides: tuple[int, ...],
) -> npt.NDArray[Any]:
    """A strided view of ``buf`` (no copy)."""
    view: npt.NDArray[Any] = np.ndarray(shape, dtype, buffer=buf, offset=offset, strides=strides)
    return view


def _rows(buf: npt.NDArray[np.uint8], index: IntArray, width: int) -> npt.NDArray[np.uint8]:
    """``width`` bytes of ``buf`` from each of ``index``, one row each (a copy)."""
    if width == 0:
        return np.zeros((len(index), 0), dtype=np.uint8)
    items = _view(buf, (len(buf) - width + 1,), np.dtype(f"V{width}"), 0, (1,))
    rows: npt.NDArray[np.uint8] = items[index].view(np.uint8).reshape(len(index), width)
    return rows


class _Chunk:
    """The raw bytes of a chunk's messages (or of some of them), from some offset on.

    ``buf`` has room after the last message for a window as wide as the widest one.
    """

    def __init__(
        self,
        buf: npt.NDArray[np.uint8],
        limits: IntArray,
        starts: IntArray | None,
        stride: int | None,
        base: int,
    ) -> None:
        self.buf = buf
        self.limits = limits  # bytes of each message from its start
        self.n = len(limits)
        self.least = int(limits.min()) if self.n else 0
        self._starts = starts  # where each message starts in buf
        self.stride = stride  # when message i starts at base + i * stride (strided views)
        self.base = base

    def starts(self) -> IntArray:
        if self._starts is None:
            assert self.stride is not None
            self._starts = np.arange(self.n, dtype=np.int64) * self.stride + self.base
        return self._starts

    def need(self, end: Rel) -> None:
        """Fall back unless every message has ``end`` bytes."""
        fits = end <= self.least if isinstance(end, int) else bool(np.all(end <= self.limits))
        if not fits:
            raise _FallbackError

    def subset(self, mask: npt.NDArray[np.bool_]) -> _Chunk:
        return _Chunk(self.buf, self.limits[mask], self.starts()[mask], None, self.base)

    def realigned(self, rel: IntArray, cdr: bool) -> tuple[_Chunk, int] | None:
        """The rest of every message from ``rel`` on as rows of one width (then views again).

        CDR alignment is relative to the data start, so rows start at ``rel`` rounded down to
        8 when every ``rel`` has the same residue; None when they have not, or when the rests
        differ so much in length that copying them is no gain.
        """
        residue = int(rel[0]) % 8 if cdr else 0
        if cdr and bool(np.any((rel - residue) & 7)):
            return None
        rest = self.limits - rel
        if int(rest.min()) < 0:
            raise _FallbackError
        width = int(rest.max()) + residue
        if width == 0 or self.n * width > 2 * int(rest.sum()) + 64 * self.n:
            return None
        index = np.append(self.starts() + rel - residue, 0)  # the last row pads the next copy
        rows = _rows(self.buf, index, width)
        return _Chunk(rows.reshape(-1), rest + residue, None, width, 0), residue

    def _strided(self, rel: Rel) -> bool:
        return self.stride is not None and isinstance(rel, int)

    def block(self, rel: Rel, width: int) -> npt.NDArray[np.uint8]:
        """``width`` bytes at ``rel`` of every message, one row per message."""
        if self._strided(rel):
            assert self.stride is not None and isinstance(rel, int)
            return _view(self.buf, (self.n, width), _U1, self.base + rel, (self.stride, 1))
        return _rows(self.buf, self.starts() + rel, width)

    def column(self, rel: Rel, dtype: np.dtype[Any]) -> npt.NDArray[Any]:
        """One value of ``dtype`` at ``rel`` per message."""
        if self._strided(rel):
            assert self.stride is not None and isinstance(rel, int)
            return _view(self.buf, (self.n,), dtype, self.base + rel, (self.stride,))
        return self.block(rel, dtype.itemsize).view(dtype).reshape(self.n)

    def matrix(self, rel: Rel, dtype: np.dtype[Any], count: int) -> npt.NDArray[Any]:
        """``count`` values of ``dtype`` from ``rel`` per message (rows x count)."""
        if self._strided(rel):
            assert self.stride is not None and isinstance(rel, int)
            strides = (self.stride, dtype.itemsize)
            return _view(self.buf, (self.n, count), dtype, self.base + rel, strides)
        return self.block(rel, count * dtype.itemsize).view(dtype)

    def ragged(self, rel: Rel, dtype: np.dtype[Any], counts: IntArray) -> npt.NDArray[Any]:
        """``counts[i]`` values from ``rel`` of message ``i``, concatenated in message order."""
        widths = counts * dtype.itemsize
        total = int(widths.sum())
        first = self.starts() + rel
        index = np.repeat(first - (np.cumsum(widths) - widths), widths) + np.arange(total)
        return self.buf[index].view(dtype)


def _uniform(values: npt.NDArray[Any]) -> Rel:
    """One number when every message has the same value, else the values (int64)."""
    wide = values.astype(np.int64)
    if bool((wide == wide[0]).all()):
        return int(wide[0])
    return wide


class _Walk:
    """The state of decoding one chunk: serialization, budget, results of the ops that emit."""

    def __init__(self, cdr: bool, max_sequence: int) -> None:
        self.cdr = cdr
        self.max_sequence = max_sequence
        self.steps = MAX_STEPS
        self.results: dict[int, Any] = {}

    def align(self, rel: Rel, size: int) -> Rel:
        if not self.cdr or size == 1:
            return rel
        return (rel + size - 1) & -size

    def prefix(self, chunk: _Chunk, rel: Rel) -> tuple[Rel, Rel]:
        """The uint32 count or length at ``rel`` (aligned) and the offset after it."""
        rel = self.align(rel, 4)
        chunk.need(rel + 4)
        count = _uniform(chunk.column(rel, _U4))
        return count, rel + 4

    def spend(self, steps: int) -> None:
        self.steps -= steps
        if self.steps < 0:
            raise _FallbackError


class _Op:
    """One serialized field; ``slot`` is set when a layout variable needs its value."""

    slot: int | None = None

    def reads(self) -> bool:
        """Whether walking over it reads bytes (else it is offset arithmetic)."""
        return True

    def run(self, walk: _Walk, chunk: _Chunk, rel: Rel) -> Rel:
        raise NotImplementedError

    def skip(self, rel: int, cdr: bool) -> int:
        """The offset after this field from ``rel``, when that needs no data (else raise)."""
        raise _NotStaticError


def _align_int(rel: int, size: int, cdr: bool) -> int:
    return (rel + size - 1) & -size if cdr else rel


class _Scalar(_Op):
    def __init__(self, base: str) -> None:
        self.dtype = np.dtype(_PRIMITIVES[base])
        self.size = self.dtype.itemsize
        self.bool = base == "bool"

    def run(self, walk: _Walk, chunk: _Chunk, rel: Rel) -> Rel:
        rel = walk.align(rel, self.size)
        end = rel + self.size
        if self.slot is not None:
            chunk.need(end)
            view = chunk.column(rel, self.dtype)
            walk.results[self.slot] = (view != 0 if self.bool else view).astype(np.float64)
        return end

    def reads(self) -> bool:
        return self.slot is not None

    def skip(self, rel: int, cdr: bool) -> int:
        return _align_int(rel, self.size, cdr) + self.size


class _String(_Op):
    def run(self, walk: _Walk, chunk: _Chunk, rel: Rel) -> Rel:
        length, rel = walk.prefix(chunk, rel)
        end = rel + length
        chunk.need(end)
        width = length
        if walk.cdr:  # the length counts a NUL terminator, which must be there
            if bool(np.any(np.asarray(length) < 1)):
                raise _FallbackError
            width = length - 1
            if bool(chunk.column(end - 1, _U1).any()):
                raise _FallbackError
        if self.slot is not None:
            walk.results[self.slot] = _texts(chunk, rel, width)
        return end


def _texts(chunk: _Chunk, rel: Rel, width: Rel) -> npt.NDArray[np.object_]:
    """The strings of ``width`` bytes at ``rel``, decoded as rosbags does (strict UTF-8).

    A few distinct strings (frame ids) are found by comparing rows with numpy; past
    ``MAX_DISTINCT_TEXTS`` of them the rest are decoded one by one.
    """
    column = np.empty(chunk.n, dtype=object)
    widest = int(np.max(width))
    if widest == 0:
        column.fill("")
        return column
    rows = chunk.block(rel, widest)  # bytes past a shorter string are not its own: zero them
    if isinstance(width, int) and bool((rows == rows[0]).all()):  # one frame id
        column.fill(rows[0].tobytes().decode())
        return column
    widths = np.broadcast_to(np.asarray(width, dtype=np.int64), (chunk.n,))
    if not isinstance(width, int):
        rows = np.where(np.arange(widest) < widths[:, None], rows, np.uint8(0))
    left = np.arange(chunk.n)
    for _ in range(MAX_DISTINCT_TEXTS):
        first = int(left[0])
        same = (widths[left] == widths[first]) & (rows[left] == rows[first]).all(axis=1)
        column[left[same]] = rows[first, : widths[first]].tobytes().decode()
        left = left[~same]
        if not len(left):
            return column
    data = np.ascontiguousarray(rows[left]).tobytes()
    cache: dict[bytes, str] = {}
    texts = []
    for at, size in enumerate(widths[left].tolist()):
        piece = data[at * widest : at * widest + size]
        text = cache.get(piece)
        if text is None:
            text = cache[piece] = piece.decode()
        texts.append(text)
    column[left] = texts
    return column


class _PrimitiveArray(_Op):
    def __init__(self, base: str, fixed: int | None) -> None:
        self.dtype = np.dtype(_PRIMITIVES[base])
        self.size = self.dtype.itemsize
        self.fixed = fixed
        self.bool = base == "bool"
        self.values = False  # whether a layout variable needs the elements (not only len)

    def run(self, walk: _Walk, chunk: _Chunk, rel: Rel) -> Rel:
        count: Rel
        if self.fixed is not None:
            count = self.fixed
            rel = walk.align(rel, self.size)
        else:
            count, rel = walk.prefix(chunk, rel)
            if bool(np.any(np.asarray(count) > walk.max_sequence)):
                raise _FallbackError
            if walk.cdr and self.size > 1:  # rosbags aligns the elements of non-empty ones
                if isinstance(count, int):
                    rel = walk.align(rel, self.size) if count else rel
                else:
                    rel = np.where(count > 0, walk.align(rel, self.size), rel)
        end = rel + count * self.size
        if self.slot is not None:
            data: npt.NDArray[Any] | None = None
            if self.values:
                chunk.need(end)
                if isinstance(count, int):
                    data = chunk.matrix(rel, self.dtype, count)
                else:
                    data = chunk.ragged(rel, self.dtype, count)
            walk.results[self.slot] = (count, data)
        return end

    def reads(self) -> bool:
        return self.fixed is None or self.values

    def skip(self, rel: int, cdr: bool) -> int:
        if self.fixed is None:
            raise _NotStaticError
        return _align_int(rel, self.size, cdr) + self.fixed * self.size


class _Repeat(_Op):
    """An array of strings or of messages: each element is walked (or skipped when static)."""

    def __init__(self, element: list[_Op], fixed: int | None, cdr: bool) -> None:
        self.element = element
        self.fixed = fixed
        self.cdr = cdr
        self.advances: list[int] | None = None  # per start offset mod 8, when static
        self._totals: dict[tuple[int, int], int] = {}
        with contextlib.suppress(_NotStaticError):
            self.advances = [_skip_all(element, r, cdr) - r for r in range(8)]
        if self.advances is not None and cdr and min(self.advances) == 0:
            raise _UnsupportedError("empty elements")

    def _total(self, count: int, residue: int) -> int:
        """Bytes that ``count`` static elements take from an offset with ``residue`` mod 8."""
        key = (count, residue)
        if key in self._totals:
            return self._totals[key]
        assert self.advances is not None
        seen: dict[int, tuple[int, int]] = {}
        done = total = 0
        r = residue
        while done < count:
            if r in seen:  # the residues cycle: jump over whole cycles
                first_done, first_total = seen[r]
                period, gain = done - first_done, total - first_total
                cycles = (count - done) // period
                done += cycles * period
                total += cycles * gain
                seen = {}
                if done >= count:
                    break
            seen[r] = (done, total)
            step = self.advances[r]
            total += step
            r = (r + step) % 8
            done += 1
        if len(self._totals) > 4096:
            self._totals.clear()
        self._totals[key] = total
        return total

    def _advance(self, count: Rel, rel: Rel) -> Rel:
        assert self.advances is not None
        if not self.cdr:
            return rel + count * self.advances[0]
        if isinstance(count, int):
            table = [self._total(count, r) for r in range(8)]
            if isinstance(rel, int):
                return rel + table[rel % 8]
            moved: IntArray = rel + np.asarray(table, dtype=np.int64)[rel & 7]
            return moved
        counts, inverse = np.unique(count, return_inverse=True)
        if len(counts) > MAX_DISTINCT_COUNTS:
            raise _FallbackError
        tables = np.array(
            [[self._total(int(c), r) for r in range(8)] for c in counts], dtype=np.int64
        )
        offsets = np.broadcast_to(np.asarray(rel, dtype=np.int64), count.shape)
        after: IntArray = offsets + tables[inverse.ravel(), offsets & 7]
        return after

    def run(self, walk: _Walk, chunk: _Chunk, rel: Rel) -> Rel:
        count: Rel
        if self.fixed is not None:
            count = self.fixed
        else:
            count, rel = walk.prefix(chunk, rel)
            if bool(np.any(np.asarray(count) > walk.max_sequence)):
                raise _FallbackError
        if self.slot is not None:
            walk.results[self.slot] = (count, None)
        if self.advances is not None:
            return self._advance(count, rel)
        if isinstance(count, int):
            walk.spend(count * len(self.element))
            for _ in range(count):
                for op in self.element:
                    rel = op.run(walk, chunk, rel)
            return rel
        walk.spend(int(count.max()) * len(self.element))
        offsets = np.array(np.broadcast_to(np.asarray(rel, dtype=np.int64), count.shape))
        for index in range(int(count.max())):
            active = count > index
            part = chunk.subset(active)
            at: Rel = offsets[active]
            for op in self.element:
                at = op.run(walk, part, at)
            offsets[active] = at
        return offsets

    def reads(self) -> bool:
        return self.fixed is None or self.advances is None

    def skip(self, rel: int, cdr: bool) -> int:
        if self.advances is None or self.fixed is None:
            raise _NotStaticError
        if not cdr:
            return rel + self.fixed * self.advances[0]
        return rel + self._total(self.fixed, rel % 8)


def _skip_all(ops: list[_Op], rel: int, cdr: bool) -> int:
    for op in ops:
        rel = op.skip(rel, cdr)
    return rel


def _compile(
    store: Any, msgtype: str, prefix: str | None, cdr: bool, paths: dict[str, _Op], depth: int
) -> list[_Op]:
    """The ops of ``msgtype``'s fields; ``paths`` gets the ops a layout may ask for."""
    if depth > MAX_DEPTH:
        raise _UnsupportedError("too deep")
    try:
        _, fields = store.fielddefs[msgtype]
    except KeyError:
        raise _UnsupportedError(f"unknown type {msgtype}") from None
    ops: list[_Op] = []
    for name, (kind, detail) in fields:
        if not cdr and name == _EMPTY_MEMBER:
            continue
        path = f"{prefix}.{name}" if prefix else (name if prefix is not None else None)
        op: _Op
        if kind == Nodetype.BASE:
            if detail[0] == "string":
                op = _String()
            elif detail[0] in _PRIMITIVES:
                op = _Scalar(detail[0])
            else:
                raise _UnsupportedError(f"primitive {detail[0]}")
        elif kind == Nodetype.NAME:
            ops += _compile(store, detail, path, cdr, paths, depth + 1)
            continue
        elif kind in (Nodetype.ARRAY, Nodetype.SEQUENCE):
            (element_kind, element_detail), length = detail
            fixed = int(length) if kind == Nodetype.ARRAY else None
            if element_kind == Nodetype.BASE and element_detail[0] == "string":
                op = _Repeat([_String()], fixed, cdr)
            elif element_kind == Nodetype.BASE and element_detail[0] in _PRIMITIVES:
                op = _PrimitiveArray(element_detail[0], fixed)
            elif element_kind == Nodetype.NAME:
                element = _compile(store, element_detail, None, cdr, paths, depth + 1)
                op = _Repeat(element, fixed, cdr)
            else:
                raise _UnsupportedError(f"array of {element_detail}")
        else:
            raise _UnsupportedError(f"field kind {kind}")
        if path is not None:
            paths[path] = op
        ops.append(op)
    return ops


def _array_columns(
    variables: tuple[Variable, ...],
    count: Rel,
    data: npt.NDArray[Any] | None,
    rows: int,
    out: Columns,
) -> None:
    """The element and statistic columns of one array field, as the Flattener computes them."""
    lengths = np.full(rows, count, dtype=np.int64) if isinstance(count, int) else count
    elements = [v for v in variables if v.derived is None]
    for variable in elements:
        index = int(variable.path[variable.path.rindex("[") + 1 : -1])
        assert data is not None
        if isinstance(count, int):
            if index < count:
                out[variable.name] = np.ascontiguousarray(data[:, index], dtype=np.float64)
            else:
                out[variable.name] = np.full(rows, np.nan)
        else:
            column = np.full(rows, np.nan)
            present = lengths > index
            column[present] = data[(np.cumsum(lengths) - lengths)[present] + index]
            out[variable.name] = column
    by_stat = {v.derived: v.name for v in variables if v.derived is not None}
    if "len" in by_stat:
        out[by_stat["len"]] = lengths.astype(np.float64)
    if not set(by_stat) - {"len"}:
        return
    nonempty = lengths > 0
    stats = {stat: np.full(rows, np.nan) for stat in _STATS}
    with np.errstate(all="ignore"):
        if isinstance(count, int) and rows and count > 0:
            assert data is not None
            matrix = np.ascontiguousarray(data, dtype=np.float64)
            stats = {
                "avg": matrix.mean(axis=1),
                "std": matrix.std(axis=1),
                "min": matrix.min(axis=1),
                "max": matrix.max(axis=1),
            }
        elif bool(nonempty.any()):
            assert data is not None
            values = np.asarray(data, dtype=np.float64).ravel()
            counts = lengths[nonempty]
            starts = np.concatenate(([0], np.cumsum(counts)[:-1]))
            mean = np.add.reduceat(values, starts) / counts
            deviation = values - np.repeat(mean, counts)
            stats["avg"][nonempty] = mean
            stats["std"][nonempty] = np.sqrt(
                np.add.reduceat(deviation * deviation, starts) / counts
            )
            stats["min"][nonempty] = np.minimum.reduceat(values, starts)
            stats["max"][nonempty] = np.maximum.reduceat(values, starts)
    for stat, name in by_stat.items():
        if stat != "len":
            out[name] = stats[stat]


class RawDecoder:
    """Columns of one topic's layout straight from a chunk of its serialized messages.

    ``decode`` gives what ``Flattener(layout)`` gives for the deserialized messages, or None
    when it cannot (then deserialize). ``reason`` says why a type is never decoded here.
    """

    def __init__(
        self,
        typestore: Any,
        msgtype: str,
        layout: TopicLayout,
        serialization: Literal["ros1", "cdr"],
    ) -> None:
        self.layout = layout
        self.cdr = serialization == "cdr"
        self.max_sequence = int(getattr(typestore, "max_sequence_length", 2**32 - 1))
        self.reason: str | None = None
        self._ops: list[_Op] = []
        self._numeric: list[tuple[str, int]] = []
        self._strings: list[tuple[str, int]] = []
        self._arrays: list[tuple[tuple[Variable, ...], int]] = []
        self._reads_after: list[int] = []
        try:
            if serialization not in ("ros1", "cdr"):
                raise _UnsupportedError(f"serialization {serialization}")
            paths: dict[str, _Op] = {}
            self._ops = _compile(typestore, msgtype, "", self.cdr, paths, 0)
            self._plan(typestore, msgtype, paths)
        except _UnsupportedError as error:
            self.reason = str(error) or "unsupported"
            self._ops = []

    @property
    def supported(self) -> bool:
        """Whether chunks of this type can be decoded here (a chunk may still fall back)."""
        return self.reason is None

    def _plan(self, typestore: Any, msgtype: str, paths: dict[str, _Op]) -> None:
        try:
            specs = {spec.path: spec for spec in flatten(typestore, msgtype)}
        except KeyError as error:
            raise _UnsupportedError(f"unknown type {error}") from None
        slots = 0

        def slot(
            spec_path: str, spec_type: str, spec_array: str | None, kinds: tuple[type, ...]
        ) -> _Op:
            nonlocal slots
            actual = specs.get(spec_path)
            op = paths.get(spec_path)
            if actual is None or op is None or not isinstance(op, kinds):
                raise _UnsupportedError(f"field {spec_path}")
            if (actual.type, actual.array) != (spec_type, spec_array) or op.slot is not None:
                raise _UnsupportedError(f"field {spec_path} differs from the layout")
            op.slot = slots
            slots += 1
            return op

        for spec, variable in self.layout.scalars:
            if variable.numeric:
                op = slot(spec.path, spec.type, spec.array, (_Scalar,))
                assert op.slot is not None
                self._numeric.append((variable.name, op.slot))
        for spec, variable in self.layout.scalars:
            if not variable.numeric:
                op = slot(spec.path, spec.type, spec.array, (_String,))
                assert op.slot is not None
                self._strings.append((variable.name, op.slot))
        for spec, variables in self.layout.arrays:
            op = slot(spec.path, spec.type, spec.array, (_PrimitiveArray, _Repeat))
            needs_values = any(v.derived != "len" for v in variables)
            if needs_values:
                if not isinstance(op, _PrimitiveArray) or op.bool:
                    raise _UnsupportedError(f"statistics of {spec.path}")
                op.values = True
            assert op.slot is not None
            self._arrays.append((variables, op.slot))
        reading = [op.reads() for op in self._ops]
        self._reads_after = [sum(reading[index + 1 :]) for index in range(len(reading))]

    def _empty(self) -> Columns:
        out: Columns = {}
        for name, _ in self._numeric:
            out[name] = np.empty(0, dtype=np.float64)
        for name, _ in self._strings:
            out[name] = np.empty(0, dtype=object)
        for variables, _ in self._arrays:
            for variable in variables:
                out[variable.name] = np.empty(0, dtype=np.float64)
        return out

    def decode(self, raws: Sequence[bytes | memoryview]) -> Columns | None:
        """The layout's columns of ``raws`` (serialized messages), or None: deserialize them."""
        if self.reason is not None:
            return None
        if not len(raws):
            return self._empty()
        try:
            return self._decode(raws)
        except (_FallbackError, ValueError, IndexError, TypeError, OverflowError):
            return None

    def _decode(self, raws: Sequence[bytes | memoryview]) -> Columns:
        rows = len(raws)
        sizes = np.fromiter(map(len, raws), dtype=np.int64, count=rows)
        if int(sizes.sum()) > MAX_CHUNK_BYTES:
            raise _FallbackError
        pad = bytes(int(sizes.max()))  # room for windows past the last message
        buf = np.frombuffer(b"".join([*raws, pad]), dtype=np.uint8)
        base = 4 if self.cdr else 0
        first = int(sizes[0])
        if bool((sizes == first).all()):
            chunk = _Chunk(buf, sizes - base, None, first, base)
        else:
            chunk = _Chunk(buf, sizes - base, np.cumsum(sizes) - sizes + base, None, base)
        if self.cdr:  # little-endian CDR only (bytes 0 and 1 of the encapsulation header)
            chunk.need(0)
            if bool(chunk.column(-4, _U1).any()) or not bool((chunk.column(-3, _U1) == 1).all()):
                raise _FallbackError
        walk = _Walk(self.cdr, self.max_sequence)
        rel: Rel = 0
        for index, op in enumerate(self._ops):
            rel = op.run(walk, chunk, rel)
            if not isinstance(rel, int) and self._reads_after[index] > 1:  # copy, then views
                moved = chunk.realigned(rel, self.cdr)
                if moved is not None:
                    chunk, rel = moved
        chunk.need(rel)
        spare = chunk.limits - rel
        if bool(np.any(spare > (3 if self.cdr else 0))):  # rosbags rejects these sizes
            raise _FallbackError
        results = walk.results
        out: Columns = {}
        for name, index in self._numeric:
            out[name] = results[index]
        for name, index in self._strings:
            out[name] = results[index]
        for variables, index in self._arrays:
            count, data = results[index]
            _array_columns(variables, count, data, rows, out)
        return out
