"""Translating one bag, in bounded chunks, into the samples of every program point.

Messages are read in bag order and numbered; every ``chunk`` messages the buffered ones are
flattened into columns and each point's samples are built. A publish point pairs each of its
messages with the latest earlier message of each input topic, of its condition's topic and
of the parameter records (Algorithm 1, vectorised with ``searchsorted`` on the message
numbers); the last row of every topic is carried into the next chunk, so pairing is the same
whatever the chunk size and memory stays bounded by it. A sample whose inputs have not all
been seen yet is not produced (it is counted as unpaired).
"""

from __future__ import annotations

import json
from abc import ABC, abstractmethod
from collections.abc import Iterator, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Generic, Literal, NamedTuple, TypeVar

import numpy as np
import numpy.typing as npt

from imrosc import records
from imrosc.bags import MessageError, open_bag
from imrosc.graph.bags import PublisherStart, publisher_starts
from imrosc.infer.core import Samples, Variable, kept_restarts
from imrosc.runtime.arch import node_names
from imrosc.translate.catalog import flatten_json
from imrosc.translate.columns import Columns, Flattener
from imrosc.translate.condition import ConditionError, evaluate_mask
from imrosc.translate.layout import TopicLayout
from imrosc.translate.points import ARCH_VARIABLE, PointSpec
from imrosc.translate.rawdecode import RawDecoder

State = TypeVar("State")

CHUNK_MESSAGES = 16384
ARCH_PERIOD = 1.0
"""Architecture and parameter points are sampled once a second (and at every change), as a
recorder polling the master every second would see them; a bag without records gives its
connections' publishers (ROS 1 ``callerid``), each from its connection's first message on
(a topic none of them has published yet is unknown, not empty). (A parameter record is
written only when a value changes: sampled at its changes alone, a parameter that keeps its
value would give a point one sample, too few to justify any invariant.)"""
PARAMS = records.PARAMS_TOPIC
PARAM_TICKS = PARAMS + "#ticks"
"""The parameters in force at every tick and change: the rows of parameter points."""
SRVS = records.SRVS_TOPIC
ARCH = records.ARCH_TOPIC


@dataclass
class Rows:
    """Rows of one source (a topic or a record stream): message numbers, times, columns."""

    seq: npt.NDArray[np.int64]
    time: npt.NDArray[np.float64]
    columns: Columns
    extra: list[Any] = field(default_factory=list)

    def __len__(self) -> int:
        return len(self.seq)

    def tail(self) -> Rows:
        """The last row (what the next chunk pairs with)."""
        return Rows(self.seq[-1:], self.time[-1:], {k: v[-1:] for k, v in self.columns.items()})


def _concat(first: Rows | None, second: Rows | None) -> Rows | None:
    if first is None or second is None:
        return first or second
    names = set(first.columns) | set(second.columns)
    columns = {
        name: np.concatenate([_column(first, name), _column(second, name)]) for name in names
    }
    return Rows(
        np.concatenate([first.seq, second.seq]), np.concatenate([first.time, second.time]), columns
    )


def _column(rows: Rows, name: str) -> npt.NDArray[Any]:
    if name in rows.columns:
        return rows.columns[name]
    return np.full(len(rows), np.nan)


def _missing(variable: Variable, rows: int) -> npt.NDArray[Any]:
    if variable.numeric:
        return np.full(rows, np.nan)
    column = np.empty(rows, dtype=object)
    column[:] = [frozenset() if variable.type == "set" else "" for _ in range(rows)]
    return column


def _json_rows(entries: list[tuple[int, float, dict[str, Any]]]) -> Rows:
    names = sorted({name for _, _, values in entries for name in values})
    columns: Columns = {}
    for name in names:
        values = [v.get(name) for _, _, v in entries]
        if any(isinstance(v, str) for v in values):
            column = np.empty(len(values), dtype=object)
            column[:] = ["" if v is None else str(v) for v in values]
        else:
            column = np.array([np.nan if v is None else float(v) for v in values])
        columns[name] = column
    seq = np.array([s for s, _, _ in entries], dtype=np.int64)
    time = np.array([t for _, t, _ in entries], dtype=np.float64)
    return Rows(seq, time, columns, [values for _, _, values in entries])


class BagTranslator:
    """Turns one bag into samples for a fixed set of point specs."""

    def __init__(
        self,
        specs: Sequence[PointSpec],
        layouts: Mapping[str, TopicLayout],
        callerids: Mapping[str, set[str]] | None = None,
        chunk: int = CHUNK_MESSAGES,
    ) -> None:
        self.specs = list(specs)
        self.flatteners = {topic: Flattener(layout) for topic, layout in layouts.items()}
        self.chunk = chunk
        self.topics: set[str] = set()
        for spec in self.specs:
            if spec.kind == "publish":
                self.topics |= {spec.trigger, *spec.inputs}
            if spec.condition is not None:
                self.topics.add(spec.condition.topic)
            self.topics |= {name for _, kind, name in spec.events if kind == "publish"}
        self.topics &= set(self.flatteners)
        self.records = {PARAMS, SRVS, ARCH}
        self.callerids = callerids or {}
        self.messages = 0
        self.span = (0.0, 0.0)
        """The first and last message times of the bag being translated (seconds)."""
        self.decoders: dict[tuple[str, str], RawDecoder | None] = {}
        self.skipped: dict[str, int] = {}
        self.problems: list[str] = []
        self._gaps: dict[str, bool] = {}

    def translate(self, bag: Path, run: int) -> Iterator[Samples]:
        """Samples of every point from ``bag`` (run number ``run``), chunk after chunk."""
        carry: dict[str, Rows] = {}
        self._gaps = {}
        """Per conditional point: its condition did not hold at its last sample so far."""
        with open_bag(bag) as reader:
            self._reader = reader
            self.span = (reader.start_time / 1e9, reader.end_time / 1e9)
            self._arch = _ArchClock(reader.start_time / 1e9, reader.end_time / 1e9)
            self._param_clock = _ParamClock(reader.start_time / 1e9, reader.end_time / 1e9)
            if not any(c.topic == ARCH for c in reader.connections):
                self._arch.starts = publisher_starts(reader)
            wanted = [c for c in reader.connections if c.topic in self.topics | self.records]
            buffer: dict[str, list[tuple[int, float, Any, str]]] = {}
            count = 0
            for connection, stamp, raw in reader.messages(connections=wanted) if wanted else ():
                count += 1
                entry = (count, stamp / 1e9, raw, connection.msgtype)
                buffer.setdefault(connection.topic, []).append(entry)
                if count % self.chunk == 0:
                    yield from self._flush(buffer, carry, run)
                    buffer = {}
            yield from self._flush(buffer, carry, run, final=True)
            self.messages += count

    # -- one chunk --------------------------------------------------------------------------

    def _deserialized(
        self, topic: str, entries: list[tuple[int, float, Any, str]]
    ) -> tuple[list[Any], npt.NDArray[np.bool_]]:
        """Deserialize buffered raw messages; a bad one is counted and left out."""
        messages: list[Any] = []
        kept = np.ones(len(entries), dtype=bool)
        for index, (_, _, raw, msgtype) in enumerate(entries):
            try:
                messages.append(self._reader.deserialize(raw, msgtype))
            except MessageError:
                kept[index] = False
                self.skipped[topic] = self.skipped.get(topic, 0) + 1
        return messages, kept

    def _raw_columns(
        self, topic: str, entries: list[tuple[int, float, Any, str]]
    ) -> Columns | None:
        """Columns decoded straight from the raw bytes, when the chunk allows it."""
        msgtype = entries[0][3]
        if any(entry[3] != msgtype for entry in entries):
            return None
        key = (topic, msgtype)
        if key not in self.decoders:
            serialization: Literal["ros1", "cdr"] = (
                "cdr" if getattr(self._reader, "is2", False) else "ros1"
            )
            try:
                self.decoders[key] = RawDecoder(
                    self._reader.typestore, msgtype, self.flatteners[topic].layout, serialization
                )
            except (KeyError, ValueError, TypeError):
                self.decoders[key] = None
        decoder = self.decoders[key]
        return None if decoder is None else decoder.decode([entry[2] for entry in entries])

    def _rows(self, buffer: Mapping[str, list[tuple[int, float, Any, str]]]) -> dict[str, Rows]:
        data: dict[str, Rows] = {}
        for topic, entries in buffer.items():
            seq = np.fromiter((e[0] for e in entries), dtype=np.int64, count=len(entries))
            time = np.fromiter((e[1] for e in entries), dtype=np.float64, count=len(entries))
            if topic in self.flatteners:
                columns = self._raw_columns(topic, entries)
                if columns is None:
                    messages, kept = self._deserialized(topic, entries)
                    columns, seq, time = self.flatteners[topic](messages), seq[kept], time[kept]
                data[topic] = Rows(seq, time, columns)
                continue
            messages, kept = self._deserialized(topic, entries)
            if topic == PARAMS:
                data[PARAMS] = self._param_rows(
                    list(zip(seq[kept], time[kept], messages, strict=True))
                )
            elif topic in (SRVS, ARCH):
                data[topic] = Rows(seq[kept], time[kept], {}, [m.data for m in messages])
        return data

    def _param_rows(self, entries: list[tuple[int, float, Any]]) -> Rows:
        parsed = []
        for seq, time, message in entries:
            try:
                params = records.decode_params(message.data).params
            except (records.RecordError, json.JSONDecodeError):
                continue
            values: dict[str, Any] = {}
            for name, value in params.items():
                values.update(flatten_json(value, name))
            parsed.append((int(seq), float(time), values))
        return _json_rows(parsed)

    def _flush(
        self,
        buffer: Mapping[str, list[tuple[int, float, Any, str]]],
        carry: dict[str, Rows],
        run: int,
        *,
        final: bool = False,
    ) -> Iterator[Samples]:
        data = self._rows(buffer)
        if any(spec.kind == "arch" for spec in self.specs):
            data[ARCH] = self._arch.rows(data.get(ARCH), buffer, final=final)
        if any(spec.kind == "param" for spec in self.specs):
            data[PARAM_TICKS] = self._param_clock.rows(data.get(PARAMS), buffer, final=final)
        calls = self._calls(data.get(SRVS))
        for spec in self.specs:
            samples = self._point(spec, data, calls, carry, run)
            if samples is not None and len(samples):
                yield samples
        for name, rows in data.items():
            if len(rows) and name not in (SRVS, ARCH, PARAM_TICKS):
                carry[name] = rows.tail()

    def _calls(self, rows: Rows | None) -> dict[str, list[tuple[int, float, dict[str, Any]]]]:
        calls: dict[str, list[tuple[int, float, dict[str, Any]]]] = {}
        if rows is None:
            return calls
        for seq, time, text in zip(rows.seq, rows.time, rows.extra, strict=True):
            try:
                call = records.decode_call(text)
            except (records.RecordError, json.JSONDecodeError):
                continue
            values = flatten_json({"request": call.request, "response": call.response})
            values["delay"] = call.delay
            calls.setdefault(call.service, []).append((int(seq), float(time), values))
        return calls

    def _pair(
        self, trigger: Rows, source: str, data: Mapping[str, Rows], carry: Mapping[str, Rows]
    ) -> tuple[npt.NDArray[np.int64], Rows | None]:
        rows = _concat(carry.get(source), data.get(source))
        if rows is None:
            return np.full(len(trigger), -1, dtype=np.int64), None
        return np.searchsorted(rows.seq, trigger.seq) - 1, rows

    def _point(
        self,
        spec: PointSpec,
        data: Mapping[str, Rows],
        calls: Mapping[str, list[tuple[int, float, dict[str, Any]]]],
        carry: Mapping[str, Rows],
        run: int,
    ) -> Samples | None:
        if spec.kind == "publish":
            trigger = data.get(spec.trigger)
            sources = (*spec.inputs, *((PARAMS,) if spec.params else ()))
        elif spec.kind == "call":
            entries = calls.get(spec.trigger)
            trigger = _json_rows(entries) if entries else None
            if trigger is not None:  # record fields are named by path; variables by short name
                named = {v.path: v.name for v in spec.variables if v.topic == spec.trigger}
                trigger.columns = {named.get(k, k): c for k, c in trigger.columns.items()}
            sources = (PARAMS,) if spec.params else ()
        elif spec.kind == "param":
            rows = data.get(PARAM_TICKS)
            trigger = rows if rows is not None and spec.trigger in rows.columns else None
            sources = ()
        elif spec.kind == "arch":
            trigger = self._arch_rows(spec, data.get(ARCH))
            sources = ()
        else:
            trigger = self._event_rows(spec, data, calls)
            sources = ()
        if trigger is None or not len(trigger):
            return None
        return self._assemble(spec, trigger, sources, data, carry, run)

    def _assemble(
        self,
        spec: PointSpec,
        trigger: Rows,
        sources: Sequence[str],
        data: Mapping[str, Rows],
        carry: Mapping[str, Rows],
        run: int,
    ) -> Samples:
        valid = np.ones(len(trigger), dtype=bool)
        columns: Columns = dict(trigger.columns)
        for source in sources:
            index, rows = self._pair(trigger, source, data, carry)
            valid &= index >= 0
            if rows is not None:
                safe = np.maximum(index, 0)
                for name, column in rows.columns.items():
                    columns.setdefault(name, column[safe])
        restarts = None
        if spec.condition is not None:
            index, rows = self._pair(trigger, spec.condition.topic, data, carry)
            present = valid.copy()  # the samples a monitor checks the condition of
            valid &= index >= 0
            if rows is not None:
                safe = np.maximum(index, 0)
                paired = {
                    name: rows.columns[name][safe]
                    for name in spec.condition.fields.values()
                    if name in rows.columns
                }
                try:
                    valid &= evaluate_mask(
                        spec.condition.expression, spec.condition.fields, paired, len(trigger)
                    )
                except (ConditionError, KeyError):
                    valid &= False
            restarts, self._gaps[spec.key] = kept_restarts(
                present, valid, self._gaps.get(spec.key, False)
            )
        rows_kept = int(valid.sum())
        variables = spec.variables
        if spec.kind == "arch":  # only the kinds this bag can tell
            variables = tuple(v for v in variables if v.name in columns)
        out = {
            v.name: columns[v.name][valid] if v.name in columns else _missing(v, rows_kept)
            for v in variables
        }
        return Samples(spec.key, run, trigger.time[valid], out, variables, restarts)

    def _arch_rows(self, spec: PointSpec, rows: Rows | None) -> Rows | None:
        """One row per architecture sample: the snapshot in force, per kind and resource."""
        if rows is None or spec.arch is None or not len(rows):
            return None
        columns: Columns = {}
        for kind, resources in spec.arch.items():
            if kind != "pub" and any(s.callerid_only for s in rows.extra):
                continue  # callerids say nothing of subscribers and servers
            for resource in resources:
                column = np.empty(len(rows), dtype=object)
                column[:] = [s.ends(kind, resource) for s in rows.extra]
                columns[f"{ARCH_VARIABLE[kind]}({resource})"] = column
        return Rows(rows.seq, rows.time, columns)

    def _event_rows(
        self,
        spec: PointSpec,
        data: Mapping[str, Rows],
        calls: Mapping[str, list[tuple[int, float, dict[str, Any]]]],
    ) -> Rows | None:
        seqs: list[npt.NDArray[np.int64]] = []
        times: list[npt.NDArray[np.float64]] = []
        labels: list[npt.NDArray[Any]] = []
        for ident, kind, name in spec.events:
            if kind == "publish" and name in data:
                rows = data[name]
                seqs.append(rows.seq)
                times.append(rows.time)
            elif kind == "call" and name in calls:
                seqs.append(np.array([c[0] for c in calls[name]], dtype=np.int64))
                times.append(np.array([c[1] for c in calls[name]], dtype=np.float64))
            else:
                continue
            column = np.empty(len(seqs[-1]), dtype=object)
            column[:] = ident
            labels.append(column)
        if not seqs:
            return None
        seq = np.concatenate(seqs)
        order = np.argsort(seq, kind="stable")
        event = np.concatenate(labels)[order]
        return Rows(seq[order], np.concatenate(times)[order], {"event": event})


@dataclass
class _Snapshot:
    """The graph in force; ``callerid_only``: the publishers seen so far in a bag without
    records (a topic it does not list is unknown)."""

    snapshot: records.ArchSnapshot
    callerid_only: bool = False

    def ends(self, kind: str, resource: str) -> frozenset[str] | None:
        """Who publishes, subscribes to or serves ``resource`` (anonymous names in their
        stable form, ``imrosc.runtime.arch.node_name``); ``None`` when unknown."""
        snapshot = self.snapshot
        if kind == "srv":
            return node_names(snapshot.services.get(resource, ()))
        ends = snapshot.topics.get(resource)
        if ends is None:
            return None if self.callerid_only else frozenset()
        return node_names(ends.pubs if kind == "pub" else ends.subs)


def _callerid_snapshot(publishers: Mapping[str, set[str]]) -> _Snapshot:
    """The snapshot of the publishers seen so far (topic to callerids)."""
    topics = {t: records.TopicEnds(frozenset(p), frozenset()) for t, p in publishers.items()}
    return _Snapshot(records.ArchSnapshot(topics, {}), callerid_only=True)


class _Timeline(NamedTuple):
    """A chunk's messages in time order and how far its clock samples go."""

    seqs: npt.NDArray[np.int64]
    times: npt.NDArray[np.float64]
    horizon: float


@dataclass
class _Clock(ABC, Generic[State]):
    """Samples a state in force every ``ARCH_PERIOD`` seconds and at each change.

    Ticks fall at ``start + k * ARCH_PERIOD`` (none before the first state, none at the time
    of a change: the change is that sample); a tick gets the message number just after the
    last message at or before it, so conditions pair with it as with any sample.
    """

    start: float
    end: float
    current: State | None = None
    tick: int = 0
    last_seq: int = 0

    def _seq(self, seqs: npt.NDArray[np.int64], times: npt.NDArray[np.float64], at: float) -> int:
        before = int(np.searchsorted(times, at, side="right"))
        if before:
            return int(seqs[before - 1]) + 1
        return int(seqs[0]) if len(seqs) else self.last_seq + 1

    def rows(
        self,
        records_rows: Rows | None,
        buffer: Mapping[str, list[tuple[int, float, Any, str]]],
        *,
        final: bool,
    ) -> Rows:
        """The chunk's samples of the state, from its records (``None``: none this chunk)."""
        timeline = self.timeline(buffer, final=final)
        changes = self.changes(records_rows) if records_rows is not None else []
        changes += self.more_changes(timeline)
        return self.frame(self.ticks(changes, timeline))

    def timeline(
        self, buffer: Mapping[str, list[tuple[int, float, Any, str]]], *, final: bool
    ) -> _Timeline:
        """The chunk's messages (numbers and times, in time order) and how far its samples
        go: up to its last message (the bag's end for the ``final`` chunk)."""
        entries = sorted((e[1], e[0]) for es in buffer.values() for e in es)
        times = np.array([t for t, _ in entries], dtype=np.float64)
        seqs = np.array([s for _, s in entries], dtype=np.int64)
        horizon = self.end if final else (float(times[-1]) if len(times) else self.start)
        return _Timeline(seqs, times, horizon)

    @abstractmethod
    def changes(self, records_rows: Rows) -> list[tuple[float, int, State]]:
        """``(time, seq, state)`` of each change the records carry, in time order."""

    def more_changes(self, timeline: _Timeline) -> list[tuple[float, int, State]]:
        """Changes the records do not carry, up to the timeline's horizon (none)."""
        return []

    @abstractmethod
    def frame(self, out: list[tuple[int, float, State]]) -> Rows:
        """The samples as the rows a point reads."""

    def ticks(
        self, changes: Sequence[tuple[float, int, State]], timeline: _Timeline
    ) -> list[tuple[int, float, State]]:
        """``(seq, time, state)`` of the chunk: its ``changes`` (time order) and the ticks
        up to the timeline's horizon."""
        seqs, times, horizon = timeline
        out: list[tuple[int, float, State]] = []
        pending = 0
        while True:
            at = self.start + self.tick * ARCH_PERIOD
            change = changes[pending] if pending < len(changes) else None
            if change is not None and change[0] <= at:
                self.current = change[2]
                out.append((change[1], change[0], change[2]))
                pending += 1
            elif at <= horizon:
                if self.current is not None and not (out and out[-1][1] == at):
                    out.append((self._seq(seqs, times, at), at, self.current))
                self.tick += 1
            elif change is not None:
                self.current = change[2]
                out.append((change[1], change[0], change[2]))
                pending += 1
            else:
                break
        if len(seqs):
            self.last_seq = int(seqs[-1])
        return out


@dataclass
class _ArchClock(_Clock[_Snapshot]):
    """The architecture in force, from the records' snapshots or, in a bag without records,
    from ``starts``: each connection's publisher from its first message on."""

    starts: list[PublisherStart] = field(default_factory=list)
    publishers: dict[str, set[str]] = field(default_factory=dict)

    def more_changes(self, timeline: _Timeline) -> list[tuple[float, int, _Snapshot]]:
        """A change at each time a publisher first published, up to the timeline's horizon;
        its message number follows the last message at or before it."""
        seqs, times, horizon = timeline
        found: list[tuple[float, int, _Snapshot]] = []
        while self.starts and self.starts[0].time / 1e9 <= horizon:
            at = self.starts[0].time
            while self.starts and self.starts[0].time == at:
                start = self.starts.pop(0)
                self.publishers.setdefault(start.topic, set()).add(start.node)
            snapshot = _callerid_snapshot(self.publishers)
            found.append((at / 1e9, self._seq(seqs, times, at / 1e9), snapshot))
        return found

    def changes(self, records_rows: Rows) -> list[tuple[float, int, _Snapshot]]:
        found: list[tuple[float, int, _Snapshot]] = []
        rows = zip(records_rows.seq, records_rows.time, records_rows.extra, strict=True)
        for seq, time, text in rows:
            try:
                found.append((float(time), int(seq), _Snapshot(records.decode_arch(text))))
            except (records.RecordError, json.JSONDecodeError):
                continue
        return found

    def frame(self, out: list[tuple[int, float, _Snapshot]]) -> Rows:
        return Rows(
            np.array([r[0] for r in out], dtype=np.int64),
            np.array([r[1] for r in out], dtype=np.float64),
            {},
            [r[2] for r in out],
        )


class _ParamClock(_Clock[dict[str, Any]]):
    """The parameters in force, from the records (their values kept in ``Rows.extra``)."""

    def changes(self, records_rows: Rows) -> list[tuple[float, int, dict[str, Any]]]:
        rows = zip(records_rows.time, records_rows.seq, records_rows.extra, strict=True)
        return [(float(time), int(seq), values) for time, seq, values in rows]

    def frame(self, out: list[tuple[int, float, dict[str, Any]]]) -> Rows:
        return _json_rows(out)
