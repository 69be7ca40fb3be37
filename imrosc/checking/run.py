"""One bag replayed as one run, chunk after chunk, with the engine's results and order.

The bag's messages are read in bag order and numbered (a publisher's first message in a bag
without architecture records is a clock event of its own, numbered before the message);
every ``CHUNK_MESSAGES`` messages:

1. each topic's messages are decoded at once (:mod:`.decode`);
2. the engine gets, message by message, what it still checks itself: the records
   (parameters, service calls, graph snapshots), the messages of topics its own points
   read (points with parameters or learnt detectors; calls, parameters, architecture),
   the events of temporal points, and its clock (``advance``) when it has timers;
3. each vectorised publish point checks its chunk of samples (:mod:`.points`).

Every violation and alarm is placed by the clock event it belongs to, then by stage (the
timers, the architecture's periodic check, the samples, the events) and by the point's
rank, which is the order the per-message engine produces them in; the run's lists are
those places sorted.
"""

from __future__ import annotations

import gc
import json
from collections.abc import Iterator, Mapping, Sequence
from contextlib import contextmanager
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from imrosc import records
from imrosc.bags import BagError, MessageError, open_bag, publisher_of, recovered
from imrosc.graph.bags import PublisherStart, publisher_starts
from imrosc.runtime import Engine, Violation
from imrosc.runtime.alarms import Alarm, Fed

from .decode import TopicDecoder
from .points import SAMPLE, TIMER, ChunkPoint, Found, Key, TopicRows, vectorisable
from .recorded import RECORDS, record_call

if TYPE_CHECKING:
    from imrosc.replay import RunResult

CHUNK_MESSAGES = 8192
_ARCH_STAGE, _EVENT_STAGE = 1, 3

Item = tuple[int, Any, int, bytes]
"""A buffered message: its clock position, connection, time (ns) and bytes."""


@contextmanager
def gc_paused() -> Iterator[None]:
    """Python's cyclic garbage collector off for the block (back on after, if it was on).

    A replay keeps tens of thousands of objects alive (violations, plotted samples) and
    makes more: each of the collector's passes walks them, which cost a quarter of the
    checking time of a bag with many violations. What a replay makes is freed by reference
    counting (it builds no cycles); any cycle is collected once the collector is back on."""
    enabled = gc.isenabled()
    gc.disable()
    try:
        yield
    finally:
        if enabled:
            gc.enable()


class ChunkedChecker:
    """Checks bags against one engine (its points vectorised where :func:`vectorisable`)."""

    def __init__(self, document: Mapping[str, Any], engine: Engine) -> None:
        self.document = document
        self.engine = engine
        self.rank = {key: rank for rank, key in enumerate(engine.points)}
        self.points = [
            ChunkPoint(engine, point, self.rank[key])
            for key, point in engine.points.items()
            if vectorisable(engine, point)
        ]
        engine.hand_over([p.point.key for p in self.points])
        handed = {p.point.key for p in self.points}
        self.engine_topics: set[str] = set()
        for key, point in engine.points.items():
            if key in handed:
                continue
            if point.kind == "publish":
                self.engine_topics |= {point.trigger, *point.inputs}
            self.engine_topics |= {f.topic for f in point.filters if f.topic}
        self.event_topics = {
            name for (kind, name) in engine._events if kind == "publish"
        } - self.engine_topics
        self.clocked = bool(engine._timed or engine._arch_points)
        self.kinds = {key: point.kind for key, point in engine.points.items()}

    # -- placing the engine's outputs -----------------------------------------------------

    def _place(self, position: int, found: Sequence[Violation], advanced: bool) -> list[Key]:
        keys = []
        for v in found:
            kind = self.kinds.get(v.point, "")
            if advanced:
                stage = _ARCH_STAGE if kind == "arch" else TIMER
            else:
                stage = _EVENT_STAGE if kind == "temporal" else SAMPLE
            keys.append((position, stage, self.rank.get(v.point, -1)))
        return keys

    def _engine_call(self, position: int, found: list[Violation], advanced: bool) -> None:
        if found:
            self.violations += zip(self._place(position, found, advanced), found, strict=True)
        alarms = self.engine.take_alarms()
        if alarms:
            keys = self._place(position, [a.violation for a in alarms], advanced)
            self.alarms += zip(keys, alarms, strict=True)
        fed = self.engine.alarms.fed
        if fed:  # a recording tracker: its samples in the engine's order at the end
            self.fed += [((position, SAMPLE, self.rank.get(f[1], -1)), f) for f in fed]
            fed.clear()

    # -- a run ----------------------------------------------------------------------------

    def run(self, bag: Path, result: RunResult) -> None:
        """Replay ``bag`` into ``result``; a broken bag gives its error (``result.error``)."""
        from imrosc.replay import _drifted, _topic_warnings, _unchecked, no_samples

        engine = self.engine
        engine.reset()
        for point in self.points:
            point.reset()
        self.violations: list[tuple[Key, Violation]] = []
        self.alarms: list[tuple[Key, Alarm]] = []
        self.fed: list[tuple[Key, Fed]] = []
        self.carry: dict[str, TopicRows] = {}
        self.position = 0
        self.due = engine.next_due()
        topics = self.document["topics"]
        try:
            with open_bag(bag) as reader, np.errstate(all="ignore"), gc_paused():
                result.start, result.end = reader.start_time / 1e9, reader.end_time / 1e9
                result.recovered = recovered(reader)
                result.warnings += filter(None, [result.recovered])
                drifted = _drifted(topics, reader.connections)
                result.warnings += drifted.values()
                wanted = [
                    c
                    for c in reader.connections
                    if (c.topic in topics or c.topic in RECORDS)
                    and c.msgcount
                    and c.topic not in drifted
                ]
                present = {c.topic for c in wanted}
                result.warnings += _topic_warnings(set(topics) - set(drifted), present)
                self.reader = reader
                self.result = result
                self.starts: list[PublisherStart] = (
                    [] if records.ARCH_TOPIC in present else publisher_starts(reader)
                )
                self.seen: dict[str, set[str]] = {}
                self.decoders = {t: TopicDecoder(t, topics[t]["variables"], reader) for t in topics}
                buffer: list[Item | tuple[int, None, int, bytes]] = []
                try:
                    starts = self.starts
                    first_start = starts[0].time if starts else None
                    size = CHUNK_MESSAGES
                    for connection, stamp, raw in reader.messages(wanted) if wanted else ():
                        if first_start is not None and first_start <= stamp:
                            while starts and starts[0].time <= stamp:
                                buffer.append(self._start_group())
                            first_start = starts[0].time if starts else None
                        self.position += 1
                        buffer.append((self.position, connection, stamp, raw))
                        if len(buffer) >= size:
                            self._chunk(buffer)
                            buffer = []
                except BagError:
                    self._chunk(buffer)
                    self._finish(result, withdraw=False)
                    raise
                while self.starts and self.starts[0].time <= reader.end_time:
                    buffer.append(self._start_group())
                self._chunk(buffer)
                result.checked = engine.checked()
                result.unchecked = no_samples(self.document, result.checked)
                result.warnings += _unchecked(self.document, result.checked, present)
                self._finish(result, withdraw=True)
        except BagError as error:
            result.error = str(error)

    def _finish(self, result: RunResult, *, withdraw: bool) -> None:
        withdrawn: set[int] = set()
        if withdraw:
            withdrawn = {id(v) for v in self.engine.end_run()}
        self.engine.take_alarms()
        self.engine.alarms.fed[:] = [f for _, f in sorted(self.fed, key=lambda kf: kf[0])]
        ordered = sorted(self.violations, key=lambda kv: kv[0])
        result.violations[:] = [v for _, v in ordered if id(v) not in withdrawn]
        if withdraw:
            alarms = sorted(self.alarms, key=lambda ka: ka[0])
            result.alarms = [a for _, a in alarms if id(a.violation) not in withdrawn]

    def _next(self) -> int:
        self.position += 1
        return self.position

    def _start_group(self) -> tuple[int, None, int, bytes]:
        """The publishers that first published at one time (a graph snapshot)."""
        at = self.starts[0].time
        group = []
        while self.starts and self.starts[0].time == at:
            group.append(self.starts.pop(0))
        return (self._next(), None, at, json.dumps([(s.topic, s.node) for s in group]).encode())

    # -- a chunk --------------------------------------------------------------------------

    def _chunk(self, buffer: Sequence[tuple[int, Any, int, bytes]]) -> None:
        if not buffer:
            return
        by_topic: dict[str, list[tuple[int, int, str, bytes]]] = {}
        for position, connection, stamp, raw in buffer:
            if connection is not None and connection.topic in self.decoders:
                entry = (position, stamp, connection.msgtype, raw)
                by_topic.setdefault(connection.topic, []).append(entry)
        rows: dict[str, TopicRows] = {}
        skipped: set[int] = set()
        values_of: dict[int, tuple[str, int]] = {}
        for topic, entries in by_topic.items():
            decoder = self.decoders[topic]
            decoded = decoder.decode([e[2] for e in entries], [e[3] for e in entries])
            pos = np.fromiter((e[0] for e in entries), np.int64, len(entries))
            time = np.fromiter((e[1] for e in entries), np.int64, len(entries)) / 1e9
            if not decoded.kept.all():
                skipped.update(pos[~decoded.kept].tolist())
                pos, time = pos[decoded.kept], time[decoded.kept]
            fresh = TopicRows(
                pos,
                time,
                decoded.numeric,
                decoded.strings,
                [v["name"] for v in decoder.variables],
                decoder.numeric_at,
                decoder.string_at,
            )
            if topic in self.engine_topics:
                for row, position in enumerate(pos.tolist()):
                    values_of[position] = (topic, row)
            carried = self.carry.get(topic)
            rows[topic] = _joined(carried, fresh) if carried is not None else fresh
        for topic, carried in self.carry.items():
            rows.setdefault(topic, carried)
        dropped: set[int] = set()
        clock = self._engine_pass(buffer, rows, skipped, values_of, dropped)
        if dropped:  # unknown publishers' messages: no point's sample, no input's value
            gone = np.fromiter(dropped, np.int64, len(dropped))
            for topic, topic_rows in rows.items():
                kept = ~np.isin(topic_rows.pos, gone)
                if not kept.all():
                    rows[topic] = topic_rows.kept(kept)
        found = Found()
        for point in self.points:
            point.check(rows, clock, found)
        self.engine.take_alarms()  # placed already (found.alarms)
        self.violations += found.violations
        self.alarms += found.alarms
        self.fed += found.fed
        for topic, topic_rows in rows.items():
            if len(topic_rows.pos):
                self.carry[topic] = topic_rows.tail()

    def _engine_pass(
        self,
        buffer: Sequence[tuple[int, Any, int, bytes]],
        rows: Mapping[str, TopicRows],
        skipped: set[int],
        values_of: Mapping[int, tuple[str, int]],
        dropped: set[int],
    ) -> tuple[Any, Any]:
        """Feed the engine what it checks itself, message by message; the chunk's clock
        events (positions and times) for the vectorised points' timers. The positions of
        messages from publishers the architecture does not know (``Engine.intruder``) go
        into ``dropped``: the engine reported them, and no point checks their values."""
        guarded = self.engine.guarded
        engine = self.engine
        result = self.result
        events: list[int] = []
        times: list[float] = []
        for position, connection, stamp, raw in buffer:
            if connection is None:  # publishers' first messages
                for topic, node in json.loads(raw):
                    self.seen.setdefault(topic, set()).add(node)
                snapshot = {"pub": {t: frozenset(p) for t, p in self.seen.items()}}
                now = stamp / 1e9
                events.append(position)
                times.append(now)
                self._engine_call(position, engine.advance(now), True)
                self._engine_call(position, engine.graph(now, snapshot, ("pub",)), False)
                self.due = engine.next_due()
                continue
            result.messages += 1
            topic = connection.topic
            now = stamp / 1e9
            if topic in RECORDS:
                call = self._record(connection, raw)
                if call is None:
                    continue
                events.append(position)
                times.append(now)
                self._engine_call(position, engine.advance(now), True)
                self._engine_call(position, call(now), False)
                self.due = engine.next_due()
                continue
            if position in skipped:
                result.skipped += 1
                continue
            events.append(position)
            times.append(now)
            if topic in guarded:
                publisher = publisher_of(connection)
                if publisher is not None:
                    self._engine_call(position, engine.advance(now), True)
                    refused = engine.intruder(topic, now, publisher)
                    if refused:
                        self._engine_call(position, refused, False)
                        dropped.add(position)
                        self.due = engine.next_due()
                        continue
            if topic in self.engine_topics:
                name, row = values_of[position]
                topic_rows = rows[name]
                at = row + topic_rows.carried
                if topic_rows.strings:
                    values: Any = self._layout_values(topic_rows, at)
                else:
                    values = topic_rows.numeric[at]
                self._engine_call(position, engine.advance(now), True)
                self._engine_call(position, engine.message(topic, now, values), False)
            elif topic in self.event_topics:
                self._engine_call(position, engine.advance(now), True)
                self._engine_call(position, engine.published(topic, now), False)
            elif self.clocked and now >= self.due:
                self._engine_call(position, engine.advance(now), True)
            else:
                continue
            self.due = engine.next_due()
        return np.asarray(events, dtype=np.int64), np.asarray(times, dtype=np.float64)

    @staticmethod
    def _layout_values(rows: TopicRows, at: int) -> list[Any]:
        values: list[Any] = [None] * len(rows.names)
        for k, place in enumerate(rows.numeric_at):
            values[place] = float(rows.numeric[at, k])
        for k, place in enumerate(rows.string_at):
            values[place] = rows.strings[k][at]
        return values

    def _record(self, connection: Any, raw: bytes) -> Any:
        """The engine call of one record (``None``: it could not be decoded)."""
        try:
            message = self.reader.deserialize(raw, connection.msgtype)
        except MessageError:
            self.result.skipped += 1
            return None
        return record_call(self.engine, connection.topic, message)


def _joined(first: TopicRows, second: TopicRows) -> TopicRows:
    """The carried row of a topic followed by its chunk."""
    return TopicRows(
        np.concatenate([first.pos, second.pos]),
        np.concatenate([first.time, second.time]),
        np.concatenate([first.numeric, second.numeric]),
        [np.concatenate([a, b]) for a, b in zip(first.strings, second.strings, strict=True)],
        second.names,
        second.numeric_at,
        second.string_at,
        len(first.pos),
    )
