"""The user's graph file: a YAML description of which node publishes, subscribes, serves what.

.. code-block:: yaml

    version: 1
    nodes:
      /a/car_ctrl:
        publishes: [/a/cmd_subject_ctrl_state]
        subscribes: [/a/car_pose, /a/subject_pose]
      /a/car:
        serves: [/a/execute_task]

Loading is safe and precise. The file is read under a size cap and composed by
:func:`imrosc.graph.yamltree.compose_plain`, which refuses anchors, aliases, tags, several
documents and deep nesting (``graph-invalid``) without expanding anything, and keeps the
1-based line and column of every value. Structure errors are ``graph-invalid``, syntax errors
``graph-syntax``, bad ROS names the codes of :func:`imrosc.schema.names.check_graph_name`.
A bad node or name is reported and skipped; the rest of the file is still used.
"""

from __future__ import annotations

import os
import stat
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path

from imrosc.diagnostics import Diagnostic, make
from imrosc.graph.model import EDGE_KEYS, FORMAT_VERSION, SOURCE_FILE, Graph, Node
from imrosc.graph.yamltree import YList, YMap, YScalar, YValue, compose_plain
from imrosc.schema.names import BAD_NAME, check_graph_name, resolve_name

__all__ = ["MAX_DEPTH", "MAX_GRAPH_BYTES", "load_graph_file", "parse_graph_text"]

MAX_GRAPH_BYTES = 1 << 20
"""A graph file over 1 MiB is refused unread (the pure-Python YAML reader needs ~8 s per MiB)."""
MAX_DEPTH = 32
"""Collections nested deeper than this are refused (a graph file needs 4)."""

_KINDS = {
    "null": "null",
    "int": "an integer",
    "float": "a number",
    "bool": "a boolean",
    "timestamp": "a timestamp",
    "merge": "a merge key (<<)",
    "value": "a value key (=)",
}
_EDGE_KINDS = {"publishes": "topic", "subscribes": "topic", "serves": "service"}


@dataclass
class _Loader:
    """The state of loading one graph file: its label and what was found so far."""

    label: str
    found: list[Diagnostic] = field(default_factory=list)

    def report(self, value: YValue, code: str, message: str, offset: int = 0) -> None:
        self.found.append(make(self.label, value.line, value.column + offset, code, message))

    def invalid(self, value: YValue, message: str) -> None:
        self.report(value, "graph-invalid", message)


def _kind(value: YValue) -> str:
    """What a YAML value is, for messages."""
    if isinstance(value, YMap):
        return "a mapping"
    if isinstance(value, YList):
        return "a list"
    return _KINDS.get(value.tag, "a string")


def _is_null(value: YValue) -> bool:
    return isinstance(value, YScalar) and value.tag == "null"


def _at(value: YValue, key: YValue) -> YValue:
    """Where to report a bad value: the value, or its key when the value is empty (null)."""
    empty = isinstance(value, YScalar) and value.tag == "null" and not value.value
    return key if empty else value


def _read(path: Path, label: str, max_bytes: int) -> tuple[str | None, list[Diagnostic]]:
    """The file's text, or the diagnostic saying why there is none."""
    try:
        info = os.stat(path)
        if not stat.S_ISREG(info.st_mode):
            kind = "a directory" if stat.S_ISDIR(info.st_mode) else "not a regular file"
            return None, [make(label, 1, 1, "io-error", f"cannot read graph file: it is {kind}")]
        with open(path, "rb") as stream:
            data = stream.read(max_bytes + 1)
    except OSError as error:
        message = f"cannot read graph file: {error.strerror or error}"
        return None, [make(label, 1, 1, "io-error", message)]
    if len(data) > max_bytes:
        message = f"graph file is larger than the {max_bytes}-byte cap"
        return None, [make(label, 1, 1, "graph-invalid", message)]
    body = data.removeprefix(b"\xef\xbb\xbf")
    try:
        return body.decode("utf-8"), []
    except UnicodeDecodeError as error:
        line = body.count(b"\n", 0, error.start) + 1
        column = len(body[body.rfind(b"\n", 0, error.start) + 1 : error.start]) + 1
        message = f"graph file is not valid UTF-8: byte 0x{body[error.start]:02x}"
        return None, [make(label, line, column, "encoding-error", message)]


def _pairs(loader: _Loader, mapping: YMap, what: str) -> Iterator[tuple[YScalar, str, YValue]]:
    """The string-keyed entries of a mapping; other keys and repeated keys are reported."""
    seen: dict[str, int] = {}
    for key, value in mapping.pairs:
        if not isinstance(key, YScalar) or key.tag != "str":
            loader.invalid(key, f"a key of {what} must be a string, not {_kind(key)}")
            continue
        if key.value in seen:
            first = seen[key.value]
            loader.invalid(key, f"{what} has the key {key.value!r} twice (first on line {first})")
            continue
        seen[key.value] = key.line
        yield key, key.value, value


def _name(loader: _Loader, value: YValue, kind: str, what: str) -> str | None:
    """A checked, resolved global name, or None (reported) when it cannot be used."""
    if not isinstance(value, YScalar) or value.tag != "str":
        loader.invalid(value, f"{what} must be a {kind} name, not {_kind(value)}")
        return None
    usable = True
    for problem in check_graph_name(value.value, kind):
        loader.report(value, problem.code, problem.message, int(value.quoted) + problem.offset)
        usable = usable and problem.code != BAD_NAME
    return resolve_name(value.value) if usable else None


def _edges(loader: _Loader, name: str, value: YValue) -> Node | None:
    """The edges of one node entry."""
    if _is_null(value):
        return Node(name)
    if not isinstance(value, YMap):
        message = f"node {name} must map to its edges (publishes, subscribes, serves), "
        loader.invalid(value, message + f"not {_kind(value)}")
        return None
    lists: dict[str, frozenset[str]] = {}
    for key, edge, items in _pairs(loader, value, f"node {name}"):
        if edge not in EDGE_KEYS:
            expected = ", ".join(EDGE_KEYS)
            loader.invalid(key, f"unknown key {edge!r} of node {name}; expected one of {expected}")
            continue
        kind = _EDGE_KINDS[edge]
        if not isinstance(items, YList):
            message = f"'{edge}' of node {name} must be a list of {kind} names"
            loader.invalid(_at(items, key), f"{message}, not {_kind(items)}")
            continue
        where = f"an item of '{edge}' of node {name}"
        names = (_name(loader, item, kind, where) for item in items.items)
        lists[edge] = frozenset(n for n in names if n is not None)
    empty: frozenset[str] = frozenset()
    return Node(
        name,
        lists.get("publishes", empty),
        lists.get("subscribes", empty),
        lists.get("serves", empty),
    )


def _version(loader: _Loader, key: YValue, value: YValue) -> bool:
    if isinstance(value, YScalar) and value.tag == "int":
        try:
            number = int(value.value, 0)
        except ValueError:
            number = -1
        if number == FORMAT_VERSION:
            return True
        loader.invalid(value, f"unsupported graph file version {value.value}; imrosc reads 1")
        return False
    message = f"'version' must be the integer {FORMAT_VERSION}, not {_kind(value)}"
    loader.invalid(_at(value, key), message)
    return False


def _nodes(loader: _Loader, mapping: YMap) -> list[Node]:
    nodes: list[Node] = []
    seen: dict[str, int] = {}
    for key, _, value in _pairs(loader, mapping, "'nodes'"):
        name = _name(loader, key, "node", "a node name")
        if name is None:
            continue
        if name in seen:
            loader.invalid(key, f"node {name} is listed twice (first on line {seen[name]})")
            continue
        seen[name] = key.line
        node = _edges(loader, name, value)
        if node is not None:
            nodes.append(node)
    return nodes


def _document(loader: _Loader, root: YValue | None) -> Graph | None:
    """The graph of a composed document, or None when its top level is unusable."""
    if root is None or (isinstance(root, YScalar) and _is_null(root) and not root.value):
        loader.found.append(make(loader.label, 1, 1, "graph-invalid", "graph file is empty"))
        return None
    if not isinstance(root, YMap):
        loader.invalid(root, f"a graph file must be a mapping, not {_kind(root)}")
        return None
    entries = {name: (key, value) for key, name, value in _pairs(loader, root, "the graph file")}
    for name, (key, _) in entries.items():
        if name not in {"version", "nodes"}:
            loader.invalid(key, f"unknown key {name!r}; a graph file has 'version' and 'nodes'")
    usable = True
    for required in ("version", "nodes"):
        if required not in entries:
            loader.invalid(root, f"the graph file has no {required!r}")
            usable = False
    if not usable or not _version(loader, *entries["version"]):
        return None
    key, nodes = entries["nodes"]
    if not isinstance(nodes, YMap):
        message = f"'nodes' must be a mapping of node names to their edges, not {_kind(nodes)}"
        loader.invalid(_at(nodes, key), message)
        return None
    return Graph.build(_nodes(loader, nodes), (SOURCE_FILE,), knows_subscriptions=True)


def parse_graph_text(text: str, label: str) -> tuple[Graph | None, list[Diagnostic]]:
    """Parse graph-file text (``label`` names it in diagnostics)."""
    root, refused = compose_plain(text, max_depth=MAX_DEPTH)
    if refused:
        found = [
            make(
                label, p.line, p.column, "graph-syntax" if p.syntax else "graph-invalid", p.message
            )
            for p in refused
        ]
        return None, sorted(found)
    loader = _Loader(label)
    graph = _document(loader, root)
    return graph, sorted(loader.found)


def load_graph_file(
    path: Path, *, label: str | None = None, max_bytes: int = MAX_GRAPH_BYTES
) -> tuple[Graph | None, list[Diagnostic]]:
    """Read and parse a graph file; None and the diagnostics when it cannot be used at all.

    A file that parses but has bad entries gives the graph of its good entries and the
    diagnostics of the bad ones. A graph file is taken as complete: it knows subscriptions.
    """
    name = label if label is not None else str(path)
    text, problems = _read(path, name, max_bytes)
    if text is None:
        return None, problems
    return parse_graph_text(text, name)
