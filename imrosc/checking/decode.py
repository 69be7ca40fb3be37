"""One topic's messages of a chunk as the engine's values: a float64 matrix and strings.

The engine reads a message as its topic's layout in the invariants file (``topics[topic]
.variables``): the numeric values as a float64 vector, the strings as a list. A chunk of
one topic's messages becomes one matrix (a row per message, the numeric variables in the
engine's order) and one object column per string variable. The raw bytes are decoded at
once by the translator's :class:`~imrosc.translate.rawdecode.RawDecoder` where the file's
layout is the one the bag's message definition gives and every value is exact (averages
and deviations of arrays are left to the engine's flattener: a summation in another order
may round otherwise); else each message is deserialized and flattened as the engine's
replay does it (:func:`~imrosc.runtime.flatten.make_flattener`), a message that cannot be
decoded skipped.
"""

from __future__ import annotations

import re
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, replace
from typing import Any, Literal

import numpy as np
import numpy.typing as npt

from imrosc.bags import MessageError
from imrosc.msgtypes import flatten
from imrosc.runtime.engine import NUMERIC_TYPES
from imrosc.runtime.flatten import make_flattener
from imrosc.translate.layout import topic_layout
from imrosc.translate.rawdecode import RawDecoder

FloatMatrix = npt.NDArray[np.float64]
_ELEMENT = re.compile(r"^(.*)\[(\d+)\]$")
INEXACT = ("avg", "std")
"""Derived statistics whose value depends on the order of summation."""


@dataclass
class Decoded:
    """A chunk of one topic: which messages were decoded, their values."""

    kept: npt.NDArray[np.bool_]
    """Per message of the chunk, whether it was decoded (a bad one is skipped)."""
    numeric: FloatMatrix
    """Rows of the kept messages: the numeric values in the engine's order."""
    strings: list[npt.NDArray[Any]]
    """Per string variable (the layout's order), the kept messages' values."""


def _short(variable: Mapping[str, Any]) -> str | None:
    """The topic's short name in a variable's name (``imu`` of ``imu.angular_velocity.x``)."""
    name, path = variable["name"], variable["path"]
    if variable.get("derived"):
        inner = name[name.find("(") + 1 : -1]
        return inner[: -len(path) - 1] if inner.endswith("." + path) else None
    return name[: -len(path) - 1] if name.endswith("." + path) else None


class TopicDecoder:
    """Decodes the chunks of one topic of an invariants file from one bag."""

    def __init__(self, topic: str, variables: Sequence[Mapping[str, Any]], reader: Any) -> None:
        self.topic = topic
        self.variables = list(variables)
        self.reader = reader
        self.numeric_at = [k for k, v in enumerate(variables) if v["type"] in NUMERIC_TYPES]
        self.string_at = [k for k, v in enumerate(variables) if v["type"] == "string"]
        self.numeric_names = [variables[k]["name"] for k in self.numeric_at]
        self.string_names = [variables[k]["name"] for k in self.string_at]
        self.flatten = make_flattener(variables)
        self.raw: dict[str, RawDecoder | None] = {}

    def _raw(self, msgtype: str) -> RawDecoder | None:
        """The raw decoder of ``msgtype`` when it gives exactly the file's variables."""
        if msgtype in self.raw:
            return self.raw[msgtype]
        self.raw[msgtype] = None
        shorts = {_short(v) for v in self.variables}
        short = shorts.pop() if len(shorts) == 1 else None
        if short is None:
            return None
        elements: dict[str, int] = {}
        for variable in self.variables:
            found = _ELEMENT.match(variable["path"])
            if found and not variable.get("derived"):
                path, index = found.group(1), int(found.group(2))
                elements[path] = max(elements.get(path, 0), index + 1)
        serialization: Literal["ros1", "cdr"] = (
            "cdr" if getattr(self.reader, "is2", False) else "ros1"
        )
        try:
            fields = tuple(
                replace(spec, length=elements[spec.path])
                if spec.array == "sequence" and spec.path in elements
                else spec
                for spec in flatten(self.reader.typestore, msgtype)
            )
            fixed = {spec.path for spec in fields if spec.array == "fixed"}
            layout = topic_layout(self.topic, msgtype, fields, short, trigger=True)
            known = {v.name: (v.path, v.derived) for v in layout.variables}
            for variable in self.variables:
                derived = variable.get("derived") or None
                if known.get(variable["name"]) != (variable["path"], derived):
                    return None
                if derived in INEXACT and variable["path"] not in fixed:
                    return None  # a summation whose order depends on the lengths
            decoder = RawDecoder(self.reader.typestore, msgtype, layout, serialization)
        except (KeyError, ValueError, TypeError):
            return None
        self.raw[msgtype] = decoder
        return decoder

    def decode(self, msgtypes: Sequence[str], raws: Sequence[Any]) -> Decoded:
        """The values of one chunk's messages (their types and serialized bytes)."""
        count = len(raws)
        if count and all(t == msgtypes[0] for t in msgtypes):
            decoder = self._raw(msgtypes[0])
            columns = decoder.decode(list(raws)) if decoder is not None else None
            if columns is not None:
                if self.numeric_names:
                    numeric = np.empty((count, len(self.numeric_names)))
                    for k, name in enumerate(self.numeric_names):
                        numeric[:, k] = columns[name]
                else:
                    numeric = np.empty((count, 0))
                strings = [columns[name] for name in self.string_names]
                return Decoded(np.ones(count, dtype=bool), numeric, strings)
        return self._deserialized(msgtypes, raws)

    def _deserialized(self, msgtypes: Sequence[str], raws: Sequence[Any]) -> Decoded:
        """Message by message, as the engine's replay reads them."""
        kept = np.ones(len(raws), dtype=bool)
        rows: list[list[Any]] = []
        for index, (msgtype, raw) in enumerate(zip(msgtypes, raws, strict=True)):
            try:
                message = self.reader.deserialize(raw, msgtype)
            except MessageError:
                kept[index] = False
                continue
            rows.append(self.flatten(message))
        numeric = np.empty((len(rows), len(self.numeric_at)))
        for row, values in enumerate(rows):
            numeric[row] = [values[k] for k in self.numeric_at]
        strings = []
        for k in self.string_at:
            column = np.empty(len(rows), dtype=object)
            column[:] = [values[k] for values in rows]
            strings.append(column)
        return Decoded(kept, numeric, strings)
