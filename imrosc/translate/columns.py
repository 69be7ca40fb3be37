"""Flattening a chunk of deserialized messages into typed columns.

Field access goes through ``operator.attrgetter`` over the dotted paths (C speed, no
generated code from bag-supplied field names). Numeric scalars become one float64 array per
variable, strings object arrays, and each numeric array field gives its statistics
(``len``, ``avg``, ``std``, ``min``, ``max``) computed for the whole chunk at once with
``reduceat`` over the concatenated elements.

>>> from types import SimpleNamespace as M
>>> from imrosc.msgtypes import FieldSpec
>>> from imrosc.translate.layout import topic_layout
>>> specs = (FieldSpec("x", "float"), FieldSpec("r", "float", "sequence"))
>>> layout = topic_layout("/t", "T", specs, "t", trigger=True)
>>> cols = flatten_chunk(layout, [M(x=1.0, r=[1.0, 3.0]), M(x=2.0, r=[])])
>>> cols["t.x"].tolist(), cols["avg(t.r)"].tolist()[0], cols["len(t.r)"].tolist()
([1.0, 2.0], 2.0, [2.0, 0.0])
"""

from __future__ import annotations

import math
import operator
from collections.abc import Callable, Sequence
from typing import Any

import numpy as np
import numpy.typing as npt

from imrosc.infer.core import Variable
from imrosc.translate.layout import TopicLayout

Columns = dict[str, npt.NDArray[Any]]


def _getter(paths: Sequence[str]) -> Callable[[Any], tuple[Any, ...]]:
    if not paths:
        return lambda message: ()
    get = operator.attrgetter(*paths)
    if len(paths) == 1:
        return lambda message: (get(message),)
    return get


def _lenient(paths: Sequence[str], missing: Any) -> Callable[[Any], tuple[Any, ...]]:
    """Like :func:`_getter`, with ``missing`` for a field the message lacks (schema drift:
    a later bag's type without a field of the first bag's)."""
    getters = [operator.attrgetter(path) for path in paths]

    def get(message: Any) -> tuple[Any, ...]:
        values = []
        for getter in getters:
            try:
                values.append(getter(message))
            except AttributeError:
                values.append(missing)
        return tuple(values)

    return get


def _number(value: Any) -> float:
    try:
        return float(value)
    except (TypeError, ValueError):
        return math.nan


def _numeric_column(values: list[Any]) -> npt.NDArray[np.float64]:
    try:
        return np.asarray(values, dtype=np.float64)
    except (TypeError, ValueError):
        return np.fromiter((_number(v) for v in values), dtype=np.float64, count=len(values))


def _stacked(arrays: list[Any], lengths: npt.NDArray[np.int64]) -> npt.NDArray[np.float64] | None:
    """All arrays as one (rows x length) matrix when they have one length, else None."""
    if not len(arrays) or lengths.min() != lengths.max():
        return None
    try:
        return np.asarray(arrays, dtype=np.float64).reshape(len(arrays), int(lengths[0]))
    except (TypeError, ValueError):
        return None


def _elements(arrays: list[Any], elements: list[Variable], out: Columns) -> None:
    lengths = np.fromiter((len(a) for a in arrays), dtype=np.int64, count=len(arrays))
    matrix = _stacked(arrays, lengths)
    if matrix is None or matrix.shape[1] < len(elements):
        matrix = np.full((len(arrays), len(elements)), np.nan)
        for row, values in enumerate(arrays):
            count = min(len(values), len(elements))
            if count:
                matrix[row, :count] = np.asarray(values[:count], dtype=np.float64)
    for index, variable in enumerate(elements):
        out[variable.name] = np.ascontiguousarray(matrix[:, index])


def _array_stats(arrays: list[Any], variables: tuple[Variable, ...], out: Columns) -> None:
    elements = [v for v in variables if v.derived is None]
    if elements:
        _elements(arrays, elements, out)
    variables = tuple(v for v in variables if v.derived is not None)
    lengths = np.fromiter((len(a) for a in arrays), dtype=np.int64, count=len(arrays))
    by_stat = {v.derived: v.name for v in variables}
    if "len" in by_stat:
        out[by_stat["len"]] = lengths.astype(np.float64)
    if set(by_stat) == {"len"}:
        return
    rows = len(arrays)
    nonempty = lengths > 0
    stats = {stat: np.full(rows, np.nan) for stat in ("avg", "std", "min", "max")}
    matrix = _stacked(arrays, lengths) if rows and lengths[0] > 0 else None
    if matrix is not None:
        with np.errstate(invalid="ignore"):
            stats = {
                "avg": matrix.mean(axis=1),
                "std": matrix.std(axis=1),
                "min": matrix.min(axis=1),
                "max": matrix.max(axis=1),
            }
    elif nonempty.any():
        kept = [np.asarray(a, dtype=np.float64).ravel() for a in arrays if len(a)]
        values = np.concatenate(kept)
        counts = lengths[nonempty]
        starts = np.concatenate(([0], np.cumsum(counts)[:-1]))
        mean = np.add.reduceat(values, starts) / counts
        deviation = values - np.repeat(mean, counts)
        stats["avg"][nonempty] = mean
        stats["std"][nonempty] = np.sqrt(np.add.reduceat(deviation * deviation, starts) / counts)
        stats["min"][nonempty] = np.minimum.reduceat(values, starts)
        stats["max"][nonempty] = np.maximum.reduceat(values, starts)
    for stat, name in by_stat.items():
        if stat != "len":
            out[name] = stats[stat]  # type: ignore[index]


class Flattener:
    """Columns of one topic's layout from a list of messages."""

    def __init__(self, layout: TopicLayout) -> None:
        self.layout = layout
        self.numeric = [v for spec, v in layout.scalars if v.numeric]
        self.strings = [v for spec, v in layout.scalars if not v.numeric]
        self._numbers = _getter([v.path for v in self.numeric])
        self._texts = _getter([v.path for v in self.strings])
        self._arrays = _getter([spec.path for spec, _ in layout.arrays])

    def _rows(self, messages: Sequence[Any], which: str, missing: Any) -> list[tuple[Any, ...]]:
        """Each message's values of one kind; a field a message lacks gives ``missing``."""
        get = getattr(self, which)
        try:
            return [get(m) for m in messages]
        except AttributeError:
            paths = {
                "_numbers": [v.path for v in self.numeric],
                "_texts": [v.path for v in self.strings],
                "_arrays": [spec.path for spec, _ in self.layout.arrays],
            }[which]
            lenient = _lenient(paths, missing)
            return [lenient(m) for m in messages]

    def __call__(self, messages: Sequence[Any]) -> Columns:
        out: Columns = {}
        rows = self._rows(messages, "_numbers", math.nan)
        try:
            block = np.array(rows, dtype=np.float64).reshape(len(rows), len(self.numeric)).T.copy()
        except (TypeError, ValueError):  # a value that is no number: convert column by column
            block = np.array(
                [_numeric_column([row[i] for row in rows]) for i in range(len(self.numeric))]
            )
        for index, variable in enumerate(self.numeric):
            out[variable.name] = block[index]
        texts = self._rows(messages, "_texts", "")
        for index, variable in enumerate(self.strings):
            column = np.empty(len(messages), dtype=object)
            column[:] = [str(row[index]) for row in texts]
            out[variable.name] = column
        arrays = self._rows(messages, "_arrays", ())
        for index, (_, variables) in enumerate(self.layout.arrays):
            _array_stats([row[index] for row in arrays], variables, out)
        return out


def flatten_chunk(layout: TopicLayout, messages: Sequence[Any]) -> Columns:
    """Columns of ``messages`` per ``layout`` (see :class:`Flattener` to reuse one)."""
    return Flattener(layout)(messages)
