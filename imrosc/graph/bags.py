"""The node graph recorded in bags: architecture records, and ROS 1 connection callerids.

Two of the three graph sources live in bags (``docs/graph.md``):

* every message on :data:`imrosc.records.ARCH_TOPIC` is a snapshot of the whole graph,
  subscribers and servers included; the snapshots of all bags are united;
* every ROS 1 connection header names the node that published on it (``callerid``); that
  gives publishers only, so a graph made of callerids alone does not know subscriptions.

A bag that cannot be read is a ``bag-error`` and is skipped; so is each bad record.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path

from rosbags.highlevel import AnyReader
from rosbags.interfaces import Connection, ConnectionExtRosbag1

from imrosc.bags import (
    BagError,
    MessageError,
    discover_bags,
    open_bag,
    recovered_diagnostic,
    time_text,
)
from imrosc.diagnostics import Diagnostic, make
from imrosc.graph.model import SOURCE_CALLERID, SOURCE_RECORDS, Graph, Node
from imrosc.progress import ProgressFactory
from imrosc.records import ARCH_TOPIC, RECORD_PREFIX, RECORD_TYPE, RecordError, decode_arch

__all__ = [
    "BagGraphs",
    "PublisherStart",
    "graph_from_bag",
    "graph_of_reader",
    "merge_graphs",
    "publisher_starts",
    "read_bag_graphs",
]


@dataclass
class _BagGraph:
    """What one bag says about the graph."""

    records: list[Graph] = field(default_factory=list)
    callers: list[Node] = field(default_factory=list)
    problems: list[Diagnostic] = field(default_factory=list)


def _published(reader: AnyReader) -> list[tuple[Connection, str]]:
    """Each ROS 1 connection with its publisher (``callerid``), the recording node's own
    topics left out."""
    found = []
    for connection in reader.connections:
        ext = connection.ext
        if not isinstance(ext, ConnectionExtRosbag1) or not ext.callerid:
            continue
        if not connection.topic.startswith(RECORD_PREFIX):
            found.append((connection, ext.callerid))
    return found


def _callers(reader: AnyReader) -> list[Node]:
    """One publisher node per ROS 1 connection, the recording node's own topics left out."""
    return [
        Node(callerid, publishes=frozenset({connection.topic}))
        for connection, callerid in _published(reader)
    ]


@dataclass(frozen=True)
class PublisherStart:
    """A ROS 1 connection's publisher and when it first published (bag time, ns)."""

    time: int
    topic: str
    node: str


def _first_message(reader: AnyReader, connection: Connection) -> int | None:
    """Time (ns) of the connection's first message, from the bag's index; ``None`` for a
    connection with no message."""
    indexes = getattr(connection.owner, "indexes", None)
    if not isinstance(indexes, dict):  # not a ROS 1 reader: the bag's start stands for it
        return int(reader.start_time) if connection.msgcount else None
    found = indexes.get(connection.id)
    return int(found[0].time) if found else None


def publisher_starts(reader: AnyReader) -> list[PublisherStart]:
    """Each ROS 1 connection's publisher (``callerid``) from its first message on, earliest
    first; the recording node's own topics and connections without messages left out."""
    starts: dict[tuple[str, str], int] = {}
    for connection, callerid in _published(reader):
        first = _first_message(reader, connection)
        if first is None:
            continue
        key = (connection.topic, callerid)
        starts[key] = min(first, starts.get(key, first))
    found = [PublisherStart(time, topic, node) for (topic, node), time in starts.items()]
    return sorted(found, key=lambda s: (s.time, s.topic, s.node))


def _record_problem(path: Path, time_ns: int, message: str) -> Diagnostic:
    where = f"{ARCH_TOPIC} message at {time_text(time_ns)} s"
    return make(str(path), 1, 1, "bag-error", f"{where}: {message}")


def _records(reader: AnyReader, path: Path, found: _BagGraph) -> None:
    """Decode every architecture record of the bag into ``found``."""
    connections = []
    for connection in reader.connections:
        if connection.topic != ARCH_TOPIC:
            continue
        if connection.msgtype != RECORD_TYPE:
            message = (
                f"{ARCH_TOPIC} has type {connection.msgtype}, not {RECORD_TYPE}; "
                f"its {connection.msgcount} messages are skipped"
            )
            found.problems.append(make(str(path), 1, 1, "bag-error", message))
            continue
        connections.append(connection)
    if not connections:  # AnyReader.messages() reads every topic when given no connection
        return
    for connection, time_ns, raw in reader.messages(connections):
        try:
            text = getattr(reader.deserialize(raw, connection.msgtype), "data", None)
            if not isinstance(text, str):
                raise RecordError("the message has no string 'data'")
            found.records.append(Graph.from_snapshot(decode_arch(text), SOURCE_RECORDS))
        except MessageError as error:
            found.problems.append(_record_problem(path, time_ns, error.message))
        except RecordError as error:
            found.problems.append(_record_problem(path, time_ns, error.message))


def graph_from_bag(path: Path) -> tuple[Graph, list[Diagnostic]]:
    """The graph one bag records: raises :class:`imrosc.bags.BagError` if it is unreadable."""
    with open_bag(path) as reader:
        return graph_of_reader(reader, path)


def graph_of_reader(reader: AnyReader, path: Path) -> tuple[Graph, list[Diagnostic]]:
    """The graph the open bag ``path`` records (:func:`graph_from_bag`)."""
    found = _BagGraph()
    warning = recovered_diagnostic(path, reader)
    if warning is not None:
        found.problems.append(warning)
    found.callers = _callers(reader)
    _records(reader, path, found)
    callers = Graph.build(found.callers, [SOURCE_CALLERID] if found.callers else [], False)
    return Graph.merge(*found.records, callers), found.problems


def merge_graphs(graphs: Sequence[Graph]) -> Graph:
    """The graphs of bags (in bag order) merged: records first in the sources, callerids
    second."""
    merged = Graph.merge(*graphs)
    sources = tuple(s for s in (SOURCE_RECORDS, SOURCE_CALLERID) if s in merged.sources)
    return replace(merged, sources=sources)


@dataclass(frozen=True)
class BagGraphs:
    """The graph of many bags, the problems found, and the bags that could be read."""

    graph: Graph
    diagnostics: tuple[Diagnostic, ...]
    read: tuple[Path, ...]


def read_bag_graphs(
    paths: Sequence[Path], progress_factory: ProgressFactory | None = None
) -> BagGraphs:
    """Discover the bags under the paths and merge the graphs of those that can be read.

    Records come first in the merged graph's sources, callerids second.
    """
    problems: list[Diagnostic] = []
    bags: list[Path] = []
    for path in paths:
        found, reported = discover_bags(path)
        bags += found
        problems += reported
    graphs: list[Graph] = []
    read: list[Path] = []
    ordered = sorted(set(bags))
    progress = progress_factory(len(ordered)) if progress_factory is not None else None
    for bag in ordered:
        try:
            graph, reported = graph_from_bag(bag)
        except BagError as error:
            problems.append(error.diagnostic())
            continue
        finally:
            if progress is not None:
                progress(bag, 0)
        graphs.append(graph)
        read.append(bag)
        problems += reported
    return BagGraphs(merge_graphs(graphs), tuple(problems), tuple(read))
