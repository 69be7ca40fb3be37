"""``imrosc info``: what bags hold, before a configuration is written (as ``rosbag info`` and
``ros2 bag info`` tell it), and which topics a ``<publish>`` could watch.

Per bag: its format, start, end, duration and messages; per topic: message type, count,
mean rate over the bag, the publishers its ROS 1 connections name (``callerid``), and the
variables imrosc would make of a message (numeric, string, arrays) with the first few
names. A topic whose type the bag does not define, or whose messages hold no variable, is
marked as not usable. The record topics ``imrosc record`` writes are listed apart.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from imrosc import records
from imrosc.bags import BagError, discover_bags, open_bag, recovered_diagnostic, time_text
from imrosc.diagnostics import Diagnostic
from imrosc.msgtypes import FieldSpec, flatten
from imrosc.progress import ProgressFactory

SECOND = 1_000_000_000
SHOWN_VARIABLES = 6
"""How many variable names a topic's line shows."""


@dataclass(frozen=True)
class TopicInfo:
    """One topic of a bag."""

    topic: str
    msgtype: str
    messages: int
    rate: float | None
    """Messages per second over the bag's duration (None: the bag lasts no time)."""
    publishers: tuple[str, ...] = ()
    numeric: int = 0
    strings: int = 0
    arrays: int = 0
    variables: tuple[str, ...] = ()
    problem: str | None = None
    """Why a configuration cannot use the topic (None: it can)."""

    @property
    def usable(self) -> bool:
        return self.problem is None

    def as_json(self) -> dict[str, Any]:
        return {
            "topic": self.topic,
            "type": self.msgtype,
            "messages": self.messages,
            "rate": None if self.rate is None else round(self.rate, 3),
            "publishers": list(self.publishers),
            "numeric": self.numeric,
            "strings": self.strings,
            "arrays": self.arrays,
            "variables": list(self.variables),
            "usable": self.usable,
            "problem": self.problem,
        }


@dataclass
class BagInfo:
    """One bag: format, time span, messages, topics and record topics."""

    path: Path
    storage: str
    start: int
    end: int
    messages: int
    topics: list[TopicInfo] = field(default_factory=list)
    records: list[TopicInfo] = field(default_factory=list)

    @property
    def duration(self) -> float:
        return max(self.end - self.start, 0) / SECOND

    def as_json(self) -> dict[str, Any]:
        return {
            "bag": str(self.path),
            "storage": self.storage,
            "start": self.start / SECOND,
            "end": self.end / SECOND,
            "duration": round(self.duration, 6),
            "messages": self.messages,
            "topics": [t.as_json() for t in self.topics],
            "records": [t.as_json() for t in self.records],
        }


def _storage(path: Path) -> str:
    if path.is_file():
        return "ros1"
    if any(path.glob("*.mcap")):
        return "ros2 (mcap)"
    return "ros2 (sqlite3)"


def _variables(fields: Sequence[FieldSpec]) -> tuple[int, int, int, tuple[str, ...]]:
    numeric = sum(1 for f in fields if f.array is None and f.type not in ("string", "bytes"))
    strings = sum(1 for f in fields if f.array is None and f.type == "string")
    arrays = sum(1 for f in fields if f.array is not None)
    names = tuple(f.path for f in fields)
    return numeric, strings, arrays, names


def bag_info(path: Path, warnings: list[Diagnostic] | None = None) -> BagInfo:
    """What one bag holds (raises :class:`~imrosc.bags.BagError` when it cannot be read);
    a bag recovered from its records gives a warning in ``warnings``."""
    with open_bag(path) as reader:
        warning = recovered_diagnostic(path, reader)
        if warning is not None and warnings is not None:
            warnings.append(warning)
        start, end = reader.start_time, reader.end_time
        if not reader.message_count:
            start = end = 0
        info = BagInfo(path, _storage(Path(str(reader.paths[0]))), start, end, reader.message_count)
        duration = max(end - start, 0) / SECOND
        by_topic: dict[str, list[Any]] = {}
        for connection in reader.connections:
            by_topic.setdefault(connection.topic, []).append(connection)
        for topic, connections in sorted(by_topic.items()):
            msgtype = connections[0].msgtype
            count = sum(c.msgcount for c in connections)
            callers = sorted(
                {str(c.ext.callerid) for c in connections if getattr(c.ext, "callerid", None)}
            )
            problem = None
            numeric = strings = arrays = 0
            names: tuple[str, ...] = ()
            types = sorted({c.msgtype for c in connections})
            try:
                numeric, strings, arrays, names = _variables(flatten(reader.typestore, msgtype))
            except KeyError as missing:
                problem = f"the bag stores no definition of {missing.args[0]}"
            if problem is None and len(types) > 1:
                problem = f"connections of several types: {', '.join(types)}"
            if problem is None and not names:
                problem = "its messages hold no variable"
            found = TopicInfo(
                topic,
                msgtype,
                count,
                count / duration if duration > 0 else None,
                tuple(callers),
                numeric,
                strings,
                arrays,
                names,
                problem,
            )
            (info.records if topic in records.RECORD_TOPICS else info.topics).append(found)
    return info


def collect(
    paths: Sequence[Path], progress_factory: ProgressFactory | None = None
) -> tuple[list[BagInfo], list[Diagnostic]]:
    """Every bag under ``paths`` (folders are searched as ``imrosc infer`` searches them);
    bags that cannot be read become diagnostics."""
    infos: list[BagInfo] = []
    problems: list[Diagnostic] = []
    bags: list[Path] = []
    for path in paths:
        found, reported = discover_bags(path)
        bags += found
        problems += reported
    progress = progress_factory(len(bags)) if progress_factory is not None else None
    for bag in bags:
        try:
            infos.append(bag_info(bag, problems))
        except BagError as error:
            problems.append(error.diagnostic())
        if progress is not None:
            progress(bag, infos[-1].messages if infos and infos[-1].path == bag else 0)
    return infos, problems


def _rate(value: float | None) -> str:
    return "-" if value is None else f"{value:.3g} Hz"


def render(infos: Sequence[BagInfo]) -> str:
    """The text of ``imrosc info``."""
    lines: list[str] = []
    for info in infos:
        lines.append(f"bag:       {info.path}")
        lines.append(f"format:    {info.storage}")
        if info.messages:
            lines.append(f"start:     {time_text(info.start)}")
            lines.append(f"end:       {time_text(info.end)}")
        lines.append(f"duration:  {info.duration:.3f} s")
        lines.append(f"messages:  {info.messages}")
        lines.append("topics:")
        width = max((len(t.topic) for t in info.topics + info.records), default=0)
        for t in info.topics:
            lines.append(
                f"  {t.topic:<{width}}  {t.messages:>7} msgs  {_rate(t.rate):>10}  {t.msgtype}"
            )
            if t.publishers:
                lines.append(f"  {'':<{width}}  published by {', '.join(t.publishers)}")
            if t.usable:
                shown = ", ".join(t.variables[:SHOWN_VARIABLES])
                more = len(t.variables) - SHOWN_VARIABLES
                shown += f", ... ({more} more)" if more > 0 else ""
                lines.append(
                    f"  {'':<{width}}  {t.numeric} numeric, {t.strings} string, "
                    f"{t.arrays} array variables: {shown}"
                )
            else:
                lines.append(f"  {'':<{width}}  not usable: {t.problem}")
        if info.records:
            lines.append("imrosc records:")
            for t in info.records:
                lines.append(f"  {t.topic:<{width}}  {t.messages:>7} msgs")
        lines.append("")
    return "\n".join(lines)
