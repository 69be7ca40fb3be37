"""The launch file of a recording: the servers of the recorded services remapped to ``/rec/``.

The recording node relays each service of the scope (thesis 3.2, Figure 3.4): the real
server must offer it as ``/rec/<srv>``, so that the recorder can offer ``<srv>`` itself. In
roslaunch that is one line in the server's ``<node>``::

    <node pkg="robot" type="car" name="car" ns="a">
      <remap from="/a/execute_task" to="/rec/a/execute_task"/>
    </node>

Only the server's node gets it: a client remapped the same way would call the server
directly, unrecorded. :func:`rewrite_for_recording` writes that line into a copy of the
launch file for every server it finds (or points an existing remap that leads to the
service at ``/rec/<srv>``); the original is never modified. The file is read as the monitor
backend reads launch files (:func:`imrosc.backends.launch.read_launch`: size cap, no DTD,
no entities). A server whose ``<node>`` is not in the file (an ``<include>``, a name with a
substitution) is reported; remap it by hand.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping
from dataclasses import dataclass, field
from pathlib import Path

from lxml import etree

from imrosc.backends.launch import (
    LaunchWalker,
    append_child,
    join_namespace,
    read_launch,
    resolve,
)
from imrosc.backends.quoting import xml_comment
from imrosc.diagnostics import Diagnostic

__all__ = ["RecordLaunch", "record_launch_name", "rewrite_for_recording"]

_SUBSTITUTION = "$("


@dataclass
class RecordLaunch:
    """The rewritten launch file (None if the original could not be read), the remaps added
    as ``(node, service)``, the servers not found, and what was reported."""

    content: bytes | None
    remapped: list[tuple[str, str]] = field(default_factory=list)
    missing: list[tuple[str, str]] = field(default_factory=list)
    diagnostics: list[Diagnostic] = field(default_factory=list)


def record_launch_name(path: Path) -> Path:
    """Where the copy goes by default: beside the original (so ``$(dirname)`` still works).

    >>> record_launch_name(Path("launch/robot.launch"))
    PosixPath('launch/robot.record.launch')
    """
    return path.with_name(f"{path.stem}.record{path.suffix or '.launch'}")


class _Walker(LaunchWalker):
    def __init__(self, label: str, servers: Mapping[str, Iterable[str]], prefix: str) -> None:
        self.out = RecordLaunch(None)
        super().__init__(label, self.out.diagnostics)
        self.prefix = prefix.rstrip("/")
        self.wanted = {(node, service) for service, nodes in servers.items() for node in nodes}
        self.unresolved: list[etree._Element] = []
        self.includes: list[etree._Element] = []

    def include(self, element: etree._Element) -> None:
        self.includes.append(element)

    def node(self, element: etree._Element, namespace: str | None) -> None:
        name = element.get("name", "")
        ns = element.get("ns")
        if namespace is None or _SUBSTITUTION in name or (ns and _SUBSTITUTION in ns):
            self.unresolved.append(element)
            return
        node_ns = join_namespace(namespace, ns) if ns else namespace
        full = resolve(name, node_ns)
        for node, service in sorted(self.wanted):
            if node == full:
                self.remap(element, node_ns, full, service)

    def remap(self, element: etree._Element, namespace: str, full: str, service: str) -> None:
        target = f"{self.prefix}{service}"
        self.wanted.discard((full, service))
        self.out.remapped.append((full, service))
        for existing in element.iterchildren("remap"):
            if resolve(existing.get("to", ""), namespace) in (service, target):
                existing.set("to", target)
                return
        added = etree.Element("remap")
        added.set("from", service)
        added.set("to", target)
        append_child(element, added)

    def finish(self) -> None:
        """Report the servers no ``<node>`` of the file matched."""
        self.out.missing = sorted((service, node) for node, service in self.wanted)
        if not self.out.missing:
            return
        for element in self.unresolved:
            self.report(
                element,
                "launch-unknown-node",
                f"node {element.get('name', '')!r} has a name imrosc cannot resolve (a "
                f"substitution); if it serves a recorded service, remap it by hand",
            )
        for element in self.includes:
            self.report(
                element,
                "launch-unrewritten",
                f"<include file={element.get('file', '')!r}>: the nodes of an included file "
                f"are not remapped; if one serves a recorded service, remap it by hand",
            )


def rewrite_for_recording(
    path: Path,
    servers: Mapping[str, Iterable[str]],
    *,
    prefix: str = "/rec",
    label: str | None = None,
    banner: str = "",
) -> RecordLaunch:
    """The copy of the roslaunch file at ``path`` in which each server in ``servers``
    (service name to the nodes that serve it) serves its service as ``<prefix><service>``."""
    shown = label if label is not None else str(path)
    tree, problems = read_launch(path, shown)
    if tree is None:
        return RecordLaunch(None, diagnostics=problems)
    walker = _Walker(shown, servers, prefix)
    root = tree.getroot()
    walker.scope(root, "/")
    walker.finish()
    if banner:
        first = root
        for sibling in root.itersiblings(preceding=True):
            first = sibling
        first.addprevious(etree.Comment(xml_comment(banner)))
    content = etree.tostring(tree, xml_declaration=True, encoding="UTF-8")
    walker.out.content = content if content.endswith(b"\n") else content + b"\n"
    return walker.out
