"""Variable layout: which variables a topic's messages give, and what they are called.

A message flattens into the field paths of ``imrosc.msgtypes``. Each scalar field is one
variable named ``<topic short name>.<path>`` (``imu.linear_acceleration.x``); a numeric array
gives the derived variables ``len(..)``, ``avg(..)``, ``std(..)``, ``min(..)`` and ``max(..)``
(the last two are its element bounds); a byte array gives its ``len``; strings and bools are
kept as such. Bookkeeping fields are left out: ``header.seq`` counts messages and header
stamps are absolute times that no other run shares (the point's own time column carries
time).

Short numeric arrays (at most ``MAX_EXPANDED`` elements) give one variable per element.

The short name of a topic is its last name segment, lengthened until it is unique among the
topics of a plan (``/a/imu`` and ``/b/imu`` become ``a/imu`` and ``b/imu``).

>>> short_names(["/cf1/imu", "/cf1/log_pos", "/a/imu"])
{'/a/imu': 'a/imu', '/cf1/imu': 'cf1/imu', '/cf1/log_pos': 'log_pos'}
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass

from imrosc.infer.core import Variable, VariableType
from imrosc.msgtypes import FieldSpec

SKIPPED_PATHS = ("header.seq",)
DERIVED_STATS = ("len", "avg", "std", "min", "max")
MAX_EXPANDED = 8
"""A numeric array of at most this many elements (fixed, or as first recorded) gives one
variable per element (``log_pos.values[0]``) and its length instead of statistics."""


def short_names(topics: Iterable[str]) -> dict[str, str]:
    """A unique short name per topic: the fewest trailing segments that tell them apart."""
    names = sorted(set(topics))
    segments = {topic: topic.strip("/").split("/") for topic in names}
    shown: dict[str, str] = {}
    for topic in names:
        for depth in range(1, len(segments[topic]) + 1):
            suffix = segments[topic][-depth:]
            if not any(segments[o][-depth:] == suffix for o in names if o != topic):
                shown[topic] = "/".join(suffix)
                break
        else:  # the topic is a suffix of another one: only its full name tells it apart
            shown[topic] = topic
    return shown


@dataclass(frozen=True)
class TopicLayout:
    """The variables one topic gives, with the fields that feed them (same order)."""

    topic: str
    msgtype: str
    scalars: tuple[tuple[FieldSpec, Variable], ...]
    arrays: tuple[tuple[FieldSpec, tuple[Variable, ...]], ...]

    @property
    def variables(self) -> tuple[Variable, ...]:
        """Every variable of the topic: scalars first, then array statistics."""
        return tuple(v for _, v in self.scalars) + tuple(v for _, vs in self.arrays for v in vs)


def _kept(spec: FieldSpec) -> bool:
    return spec.path not in SKIPPED_PATHS and spec.type != "time" and "[]" not in spec.path


def topic_layout(
    topic: str, msgtype: str, fields: tuple[FieldSpec, ...], short: str, *, trigger: bool
) -> TopicLayout:
    """The layout of ``topic`` whose messages have the flattened ``fields``."""
    scalars: list[tuple[FieldSpec, Variable]] = []
    arrays: list[tuple[FieldSpec, tuple[Variable, ...]]] = []
    for spec in fields:
        if not _kept(spec):
            continue
        name = f"{short}.{spec.path}"
        kind: VariableType = "uint" if spec.type == "bytes" else spec.type
        if spec.array is None:
            scalars.append((spec, Variable(name, kind, topic, spec.path, trigger=trigger)))
            continue
        expand = spec.type in ("float", "int", "uint") and 0 < (spec.length or 0) <= MAX_EXPANDED
        stats = ("len",) if expand or spec.type in ("bytes", "string", "bool") else DERIVED_STATS
        elements = tuple(
            Variable(f"{name}[{i}]", kind, topic, f"{spec.path}[{i}]", trigger=trigger)
            for i in range(spec.length or 0)
            if expand
        )
        derived = elements + tuple(
            Variable(
                f"{stat}({name})",
                "uint" if stat == "len" else "float",
                topic,
                spec.path,
                derived=stat,  # type: ignore[arg-type]
                trigger=trigger,
            )
            for stat in stats
        )
        arrays.append((spec, derived))
    return TopicLayout(topic, msgtype, tuple(scalars), tuple(arrays))
