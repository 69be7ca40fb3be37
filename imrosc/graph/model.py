"""The node graph: which node publishes, subscribes to and serves what.

Relative-topic grouping (thesis section 3.3) and launch rewriting read the graph. It comes
from three sources (``docs/graph.md``): architecture records in bags, the ``callerid`` of ROS 1
bag connections, and a graph file. :meth:`Graph.merge` unions them; ``knows_subscriptions``
says whether any source could see subscriptions at all (callerids cannot).

>>> from imrosc.records import TopicEnds
>>> graph = Graph.from_snapshot(
...     ArchSnapshot({"/t": TopicEnds(frozenset({"/a"}), frozenset({"/b"}))}, {}), "records")
>>> graph.publishers("/t"), graph.subscribers("/t")
(('/a',), ('/b',))
>>> print(graph.render_text(), end="")
# sources: records
/a
  publishes /t
/b
  subscribes /t
"""

from __future__ import annotations

import json
import re
from collections.abc import Iterable, Mapping
from dataclasses import dataclass, field

from imrosc.records import ArchSnapshot

__all__ = [
    "EDGE_KEYS",
    "FORMAT_VERSION",
    "SOURCE_CALLERID",
    "SOURCE_FILE",
    "SOURCE_RECORDS",
    "Graph",
    "Node",
]

FORMAT_VERSION = 1
SOURCE_RECORDS = "records"
SOURCE_CALLERID = "callerid"
SOURCE_FILE = "file"

EDGE_KEYS = ("publishes", "subscribes", "serves")
"""The keys of a node in a graph file, in the order they are written."""
_PLAIN = re.compile(r"/[A-Za-z0-9_/]*")


@dataclass(frozen=True)
class Node:
    """One node and its edges: the topics it publishes and subscribes, the services it serves."""

    name: str
    publishes: frozenset[str] = frozenset()
    subscribes: frozenset[str] = frozenset()
    serves: frozenset[str] = frozenset()

    def union(self, other: Node) -> Node:
        """This node with the edges of another (of the same name) added."""
        return Node(
            self.name,
            self.publishes | other.publishes,
            self.subscribes | other.subscribes,
            self.serves | other.serves,
        )

    def edges(self) -> dict[str, list[str]]:
        """The non-empty edge lists, sorted, by graph-file key."""
        lists = {
            "publishes": sorted(self.publishes),
            "subscribes": sorted(self.subscribes),
            "serves": sorted(self.serves),
        }
        return {key: names for key, names in lists.items() if names}


@dataclass(frozen=True)
class Graph:
    """Nodes by name, the sources the graph came from, and whether subscriptions are known."""

    nodes: Mapping[str, Node] = field(default_factory=dict)
    sources: tuple[str, ...] = ()
    knows_subscriptions: bool = False

    @staticmethod
    def build(nodes: Iterable[Node], sources: Iterable[str], knows_subscriptions: bool) -> Graph:
        """A graph of the given nodes (nodes of one name united), sorted by name."""
        united: dict[str, Node] = {}
        for node in nodes:
            known = united.get(node.name)
            united[node.name] = node if known is None else known.union(node)
        ordered = {name: united[name] for name in sorted(united)}
        return Graph(ordered, tuple(dict.fromkeys(sources)), knows_subscriptions)

    @staticmethod
    def merge(*graphs: Graph) -> Graph:
        """The union of the graphs' edges; sources in order, each once."""
        return Graph.build(
            (node for graph in graphs for node in graph.nodes.values()),
            (source for graph in graphs for source in graph.sources),
            any(graph.knows_subscriptions for graph in graphs),
        )

    @staticmethod
    def from_snapshot(snapshot: ArchSnapshot, source: str = SOURCE_RECORDS) -> Graph:
        """The graph of one architecture record; it knows subscriptions."""
        nodes: list[Node] = []
        for topic, ends in snapshot.topics.items():
            nodes += [Node(name, publishes=frozenset({topic})) for name in ends.pubs]
            nodes += [Node(name, subscribes=frozenset({topic})) for name in ends.subs]
        for service, servers in snapshot.services.items():
            nodes += [Node(name, serves=frozenset({service})) for name in servers]
        return Graph.build(nodes, (source,), knows_subscriptions=True)

    def publishers(self, topic: str) -> tuple[str, ...]:
        """The nodes that publish a topic, sorted."""
        return tuple(sorted(n.name for n in self.nodes.values() if topic in n.publishes))

    def subscribers(self, topic: str) -> tuple[str, ...]:
        """The nodes that subscribe to a topic, sorted."""
        return tuple(sorted(n.name for n in self.nodes.values() if topic in n.subscribes))

    def servers(self, service: str) -> tuple[str, ...]:
        """The nodes that serve a service, sorted."""
        return tuple(sorted(n.name for n in self.nodes.values() if service in n.serves))

    def topics(self) -> tuple[str, ...]:
        """Every topic some node publishes or subscribes to, sorted."""
        names: set[str] = set()
        for node in self.nodes.values():
            names |= node.publishes | node.subscribes
        return tuple(sorted(names))

    def services(self) -> tuple[str, ...]:
        """Every service some node serves, sorted."""
        names: set[str] = set()
        for node in self.nodes.values():
            names |= node.serves
        return tuple(sorted(names))

    def to_document(self) -> dict[str, object]:
        """The graph-file document: version and nodes, sorted, empty lists left out."""
        nodes = {name: self.nodes[name].edges() for name in sorted(self.nodes)}
        return {"version": FORMAT_VERSION, "nodes": nodes}

    def _header(self) -> str:
        sources = ", ".join(self.sources) if self.sources else "none"
        unknown = "" if self.knows_subscriptions or not self.nodes else "; subscriptions unknown"
        return f"# sources: {sources}{unknown}"

    def render_text(self) -> str:
        """A readable listing: each node, then one line per edge, all sorted."""
        lines = [self._header()]
        for name in sorted(self.nodes):
            lines.append(name)
            for key, names in self.nodes[name].edges().items():
                lines += [f"  {key} {item}" for item in names]
        return "\n".join(lines) + "\n"

    def render_yaml(self) -> str:
        """The graph as a graph file (``docs/graph.md``) that loads back to the same nodes."""
        lines = [self._header(), f"version: {FORMAT_VERSION}"]
        if not self.nodes:
            lines.append("nodes: {}")
        else:
            lines.append("nodes:")
        for name in sorted(self.nodes):
            edges = self.nodes[name].edges()
            lines.append(f"  {_scalar(name)}:" + ("" if edges else " {}"))
            for key, names in edges.items():
                lines.append(f"    {key}:")
                lines += [f"      - {_scalar(item)}" for item in names]
        return "\n".join(lines) + "\n"


def _scalar(name: str) -> str:
    """A name as a YAML scalar: plain when it is a plain global ROS name, else JSON-quoted."""
    return name if _PLAIN.fullmatch(name) else json.dumps(name)
