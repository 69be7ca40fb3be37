"""Launch rewriting: a copy of the system's launch file that routes blocked names through the
monitor and starts it (thesis 4.3.2, Figure 4.4).

The ``<monitor launch="...">`` file is read safely (a size cap, UTF-8 only, no DOCTYPE, and an
lxml parser without network, DTD or entity resolution, as configurations are read) and never
modified: the rewritten copy is new bytes the backend writes into the monitor package
(``launch/system_monitored.launch``). In the copy

* every ``<node>`` that the graph says subscribes to a blocked topic gets
  ``<remap from="/t" to="/m/t"/>`` (or, when one of its own remaps already leads to ``/t``,
  that remap is pointed at ``/m/t``): it now hears the monitor's relay;
* every ``<node>`` the graph knows that does not serve a relayed service gets
  ``<remap from="/s" to="/m/s"/>``: its calls go through the monitor (the graph does not know
  service clients, and remapping a name a node does not use changes nothing);
* the monitor's own launch file is included, with its ``fail_open`` argument passed on from
  a new ``imrosc_fail_open`` argument.

What cannot be rewritten safely is reported and left as it is: a node the graph does not know
or whose name needs a substitution (``launch-unknown-node``), an ``<include>`` (its nodes are
in another file), a ``<remap>`` outside a node that touches an intercepted name, a node that
both publishes and subscribes to a blocked topic (a remap would move its output past the
monitor) and ``$(dirname)``, which would name the copy's folder (``launch-unrewritten``).

:data:`ROSLAUNCH` (roslaunch XML, :func:`rewrite_ros1`) and :data:`ROS2_LAUNCH` (ROS 2
launch XML, :func:`rewrite_ros2`) are the two dialects (:class:`LaunchDialect`); each
monitor backend names the one it rewrites (its ``launch_dialect``). ROS 2 launch XML names a
node with ``name`` and ``namespace`` attributes and scopes namespaces with
``<push-ros-namespace>`` inside ``<group>``; its arguments are read with ``$(var ...)`` and
packages found with ``$(find-pkg-share ...)``. What ROS 2 adds that cannot be rewritten
safely is reported too: a node without a ``name`` (its name is set in its code), composable
nodes, a ``<set_remap>`` that touches an intercepted name, and remaps in a node's
command-line arguments (they come first and win).
"""

from __future__ import annotations

import re
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path

from lxml import etree

from imrosc.backends.quoting import xml_comment
from imrosc.diagnostics import Diagnostic, make
from imrosc.graph.model import Graph, Node
from imrosc.schema.loader import MAX_CONFIG_BYTES

FAIL_OPEN_ARG = "imrosc_fail_open"
_DOCTYPE = re.compile(rb"<!DOCTYPE", re.IGNORECASE)
_SUBSTITUTION = "$("


@dataclass(frozen=True)
class Interception:
    """What the monitor intercepts: blocked topic to relay, relayed service to relay."""

    topics: Mapping[str, str] = field(default_factory=dict)
    services: Mapping[str, str] = field(default_factory=dict)

    def __bool__(self) -> bool:
        return bool(self.topics or self.services)


@dataclass(frozen=True)
class MonitorLaunch:
    """The monitor's own launch file, to include: its package and file name."""

    package: str
    launch_file: str


@dataclass
class Rewritten:
    """The rewritten launch file (``None`` when the original could not be read), the remaps
    added per node, and what was reported."""

    content: bytes | None
    remaps: dict[str, list[tuple[str, str]]] = field(default_factory=dict)
    diagnostics: list[Diagnostic] = field(default_factory=list)


def _parser() -> etree.XMLParser:
    return etree.XMLParser(
        resolve_entities=False,
        no_network=True,
        load_dtd=False,
        dtd_validation=False,
        huge_tree=False,
        remove_blank_text=False,
    )


def read_launch(path: Path, label: str) -> tuple[etree._ElementTree | None, list[Diagnostic]]:
    """Parse a launch file safely; a ``launch-error`` diagnostic says why it could not be
    (``io-error`` when it cannot be read at all: missing, a directory, no permission: an
    input error, as a configuration that cannot be read)."""

    def error(
        message: str, line: int = 1, code: str = "launch-error"
    ) -> tuple[None, list[Diagnostic]]:
        return None, [make(label, line, 1, code, message)]

    try:
        with open(path, "rb") as stream:
            data = stream.read(MAX_CONFIG_BYTES + 1)
    except OSError as problem:
        return error(f"cannot read the launch file: {problem.strerror}", code="io-error")
    if len(data) > MAX_CONFIG_BYTES:
        return error(f"the launch file is larger than {MAX_CONFIG_BYTES} bytes")
    try:
        data.decode("utf-8")
    except UnicodeDecodeError:
        return error("the launch file is not UTF-8")
    if _DOCTYPE.search(data):
        return error("the launch file has a DOCTYPE; DTDs and entities are refused")
    try:
        tree = etree.ElementTree(etree.fromstring(data, _parser()))
    except etree.XMLSyntaxError as problem:
        line = problem.lineno if isinstance(problem.lineno, int) else 1
        return error(f"the launch file is not well-formed XML: {problem.msg}", line)
    if tree.getroot().tag != "launch":
        return error(f"the root element is <{tree.getroot().tag}>, not <launch>")
    return tree, []


def join_namespace(parent: str, ns: str) -> str:
    """A roslaunch namespace: ``ns`` relative to ``parent`` (or global), normalised.

    >>> join_namespace("/a", "b/"), join_namespace("/a", "/c"), join_namespace("/", "")
    ('/a/b', '/c', '/')
    """
    ns = ns.strip()
    full = ns if ns.startswith("/") else f"{parent.rstrip('/')}/{ns}"
    parts = [part for part in full.split("/") if part]
    return "/" + "/".join(parts)


def resolve(name: str, namespace: str) -> str:
    """A graph name as roslaunch resolves it in ``namespace`` (private names excluded).

    >>> resolve("pose", "/a"), resolve("/t", "/a")
    ('/a/pose', '/t')
    """
    return join_namespace(namespace, name)


def indent_of(element: etree._Element) -> str:
    """The indentation of ``element``'s line (the whitespace after the last line break
    before it)."""
    previous = element.getprevious()
    parent = element.getparent()
    space = previous.tail if previous is not None else parent.text if parent is not None else ""
    space = space or ""
    return space[space.rfind("\n") + 1 :] if "\n" in space else ""


def append_child(parent: etree._Element, child: etree._Element, step: str = "  ") -> None:
    """Append ``child`` as the last element of ``parent``, indented like its siblings."""
    outer = indent_of(parent)
    inner = outer + step
    if len(parent):
        last = parent[-1]
        child.tail = last.tail if last.tail is not None else "\n" + outer
        last.tail = "\n" + inner
    else:
        parent.text = (parent.text or "") if (parent.text or "").strip() else "\n" + inner
        child.tail = "\n" + outer
    parent.append(child)


class LaunchWalker:
    """Walks the scopes of a roslaunch XML file: a ``<group ns=...>`` nests its namespace
    (``None`` where a substitution makes it unknown), and each ``<node>``, ``<include>`` and
    other element is handed to :meth:`node`, :meth:`include` and :meth:`other` with the
    namespace in force. The monitor's rewriter and ``imrosc record``'s copy build on it."""

    def __init__(self, label: str, diagnostics: list[Diagnostic]) -> None:
        self.label = label
        self.diagnostics = diagnostics

    def report(self, element: etree._Element, code: str, message: str) -> None:
        """A diagnostic at ``element``'s line."""
        line = element.sourceline if isinstance(element.sourceline, int) else 1
        self.diagnostics.append(make(self.label, line, 1, code, message))

    def scope(self, element: etree._Element, namespace: str | None) -> None:
        """Walk the children of ``element`` in ``namespace``."""
        for child in element:
            if not isinstance(child.tag, str):
                continue
            if child.tag == "group":
                ns = child.get("ns")
                inner = namespace
                if ns is not None and namespace is not None:
                    inner = None if _SUBSTITUTION in ns else join_namespace(namespace, ns)
                self.scope(child, inner)
            elif child.tag == "node":
                self.node(child, namespace)
            elif child.tag == "include":
                self.include(child)
            else:
                self.other(child, namespace)

    def node(self, element: etree._Element, namespace: str | None) -> None:
        """A ``<node>`` in ``namespace`` (each walker says what it does with one)."""
        raise NotImplementedError

    def include(self, element: etree._Element) -> None:
        """An ``<include>``."""

    def other(self, element: etree._Element, namespace: str | None) -> None:
        """Any other element of a scope."""


class _Rewriter(LaunchWalker):
    def __init__(
        self,
        label: str,
        interception: Interception,
        graph: Graph | None,
    ) -> None:
        self.out = Rewritten(None)
        super().__init__(label, self.out.diagnostics)
        self.interception = interception
        self.graph = graph

    def intercepted(self, name: str) -> bool:
        return name in self.interception.topics or name in self.interception.services

    def include(self, element: etree._Element) -> None:
        self.report(
            element,
            "launch-unrewritten",
            f"<include file={element.get('file', '')!r}>: the nodes of an included file "
            "are not remapped; rewrite that file or move its nodes here",
        )

    def other(self, element: etree._Element, namespace: str | None) -> None:
        if element.tag == "remap" and namespace is not None:
            self.loose_remap(element, namespace, "a <remap> outside a node")

    def loose_remap(self, element: etree._Element, namespace: str, what: str) -> None:
        """Report a remap that no node's rewriting sees (``what``: how the message names
        it) when it touches an intercepted name: it is left as is."""
        target = resolve(element.get("to", ""), namespace)
        source = resolve(element.get("from", ""), namespace)
        if self.intercepted(target) or self.intercepted(source):
            self.report(
                element,
                "launch-unrewritten",
                f"{what} touches the intercepted name "
                f"{target if self.intercepted(target) else source}; it is left as is",
            )

    namespace_attribute = "ns"
    """The attribute that puts a node into a namespace (ROS 2: ``namespace``)."""

    def resolve_in(self, name: str, namespace: str, full: str) -> str:
        """A name of a node's remap as the node resolves it (ROS 1: private names aside)."""
        del full
        return resolve(name, namespace)

    def node(self, element: etree._Element, namespace: str | None) -> None:
        name = element.get("name", "")
        ns = element.get(self.namespace_attribute)
        if namespace is None or _SUBSTITUTION in name or (ns and _SUBSTITUTION in ns):
            self.report(
                element,
                "launch-unknown-node",
                f"node {name!r} has a name imrosc cannot resolve (a substitution); "
                "it is not remapped",
            )
            return
        node_ns = join_namespace(namespace, ns) if ns else namespace
        full = resolve(name, node_ns)
        known = self.graph.nodes.get(full) if self.graph is not None else None
        if known is None:
            self.report(
                element,
                "launch-unknown-node",
                f"node {full} is not in the graph; imrosc cannot tell what it subscribes to, "
                "so it is not remapped",
            )
            return
        for topic, relay in sorted(self.interception.topics.items()):
            if topic not in known.subscribes:
                continue
            if topic in known.publishes:
                self.report(
                    element,
                    "launch-unrewritten",
                    f"node {full} both publishes and subscribes to the blocked topic {topic}; "
                    "remapping it would route its output past the monitor, so it is not "
                    "remapped",
                )
                continue
            self.remap(element, node_ns, full, topic, relay)
        for service, relay in sorted(self.interception.services.items()):
            if not self.serves(known, service):
                self.remap(element, node_ns, full, service, relay)

    @staticmethod
    def serves(node: Node, service: str) -> bool:
        return service in node.serves

    def remap(
        self, element: etree._Element, namespace: str, full: str, name: str, relay: str
    ) -> None:
        for existing in element.iterchildren("remap"):
            if self.resolve_in(existing.get("to", ""), namespace, full) == name:
                existing.set("to", relay)
                self.out.remaps.setdefault(full, []).append((existing.get("from", ""), relay))
                return
        added = etree.Element("remap")
        added.set("from", name)
        added.set("to", relay)
        append_child(element, added)
        self.out.remaps.setdefault(full, []).append((name, relay))


@dataclass(frozen=True)
class LaunchDialect:
    """A launch format the monitor backends rewrite (:data:`ROSLAUNCH`, :data:`ROS2_LAUNCH`):
    what differs between roslaunch XML and ROS 2 launch XML when a file is rewritten."""

    rewriter: type[_Rewriter]
    find: str
    """The substitution that names a package's share folder."""
    doc: str
    """The attribute that documents an argument."""
    value: str
    """The substitution that reads an argument."""

    def rewrite(
        self,
        path: Path,
        *,
        interception: Interception,
        graph: Graph | None,
        monitor: MonitorLaunch,
        banner: str,
        label: str | None = None,
    ) -> Rewritten:
        """The rewritten copy of the launch file at ``path`` (see the module docstring):
        remaps added to the ``<node>`` elements, the monitor's launch file ``monitor``
        included through the package share substitution (``$(find ...)``,
        ``$(find-pkg-share ...)``)."""
        shown = label if label is not None else str(path)
        tree, problems = read_launch(path, shown)
        if tree is None:
            return Rewritten(None, diagnostics=problems)
        rewriter = self.rewriter(shown, interception, graph)
        root = tree.getroot()
        if b"$(dirname)" in etree.tostring(root):
            rewriter.report(
                root,
                "launch-unrewritten",
                "the launch file uses $(dirname), which in the rewritten copy names the monitor "
                f"package's launch folder; make those paths $({self.find} pkg)/... instead",
            )
        rewriter.scope(root, "/")
        rewriter.out.content = _finish(
            root,
            banner,
            argument={self.doc: "true: relay the blocked names unchecked when the monitor dies"},
            include_file=f"$({self.find} {monitor.package})/launch/{monitor.launch_file}",
            passed=f"$({self.value} {FAIL_OPEN_ARG})",
        )
        return rewriter.out


ROSLAUNCH = LaunchDialect(_Rewriter, "find", "doc", "arg")
"""roslaunch XML (ROS 1)."""
rewrite_ros1 = ROSLAUNCH.rewrite
"""The rewritten copy of a roslaunch file (:meth:`LaunchDialect.rewrite`)."""


def _finish(
    root: etree._Element,
    banner: str,
    *,
    argument: Mapping[str, str],
    include_file: str,
    passed: str,
) -> bytes:
    """The rewritten file: the ``imrosc_fail_open`` argument (its description attributes in
    ``argument``) first, the monitor's launch file (``include_file``) included last with
    ``fail_open`` set to ``passed``, the banner on top."""
    has_arg = any(a.get("name") == FAIL_OPEN_ARG for a in root.iterchildren("arg"))
    if not has_arg:
        arg = etree.Element("arg")
        arg.set("name", FAIL_OPEN_ARG)
        arg.set("default", "false")
        for key, value in argument.items():
            arg.set(key, value)
        first_text = root.text
        root.insert(0, arg)
        arg.tail = first_text if first_text and first_text.strip() == "" else "\n  "
        root.text = first_text if first_text and first_text.strip() == "" else "\n  "
    include = etree.Element("include")
    include.set("file", include_file)
    given = etree.SubElement(include, "arg")
    given.set("name", "fail_open")
    given.set("value", passed)
    append_child(root, etree.Comment(" the imrosc monitor "))
    append_child(root, include)
    indent = indent_of(include)
    include.text = "\n" + indent + "  "
    given.tail = "\n" + indent
    before = list(root.itersiblings(preceding=True))[::-1]
    after = list(root.itersiblings())
    nodes = [etree.Comment(xml_comment(banner)), *before, root, *after]
    parts = [b'<?xml version="1.0" encoding="UTF-8"?>']
    parts += [etree.tostring(node, encoding="UTF-8", with_tail=False) for node in nodes]
    return b"\n".join(parts) + b"\n"


_PUSH_NAMESPACE = frozenset({"push-ros-namespace", "push_ros_namespace"})
_SET_REMAP = frozenset({"set-remap", "set_remap"})
_CONTAINERS = frozenset(
    {"node_container", "node-container", "load_composable_node", "load-composable-node"}
)
_COMPOSABLE = frozenset({"composable_node", "composable-node"})
_FALSE = frozenset({"false", "False", "FALSE", "0"})
_ARGUMENT_REMAP = re.compile(r"(?:^|\s)(?:-r|--remap)(?:\s|$)")


def resolve_ros2(name: str, namespace: str, node: str) -> str:
    """A name as a ROS 2 node ``node`` in ``namespace`` resolves it: ``~`` is the node's
    private namespace, a relative name is in the namespace.

    >>> resolve_ros2("~/state", "/a", "/a/car"), resolve_ros2("cmd", "/a", "/a/car")
    ('/a/car/state', '/a/cmd')
    """
    name = name.strip()
    if name == "~" or name.startswith("~/"):
        return join_namespace(node, name[2:])
    return resolve(name, namespace)


class _Ros2Rewriter(_Rewriter):
    """ROS 2 launch XML: ``namespace`` attributes, ``<push-ros-namespace>`` in the order of
    the file, ``<group>`` scoping it unless ``scoped="false"``."""

    namespace_attribute = "namespace"

    def resolve_in(self, name: str, namespace: str, full: str) -> str:
        return resolve_ros2(name, namespace, full)

    def scope(self, element: etree._Element, namespace: str | None) -> None:
        self.walk(element, namespace)

    def walk(self, element: etree._Element, namespace: str | None) -> str | None:
        """Rewrite the children of ``element`` in order; the namespace in force after them
        (what a non-scoping group leaves to the elements that follow it)."""
        current = namespace
        for child in element:
            if not isinstance(child.tag, str):
                continue
            tag = child.tag
            if tag in _PUSH_NAMESPACE:
                pushed = child.get("namespace")
                if current is not None:
                    unknown = pushed is None or _SUBSTITUTION in pushed
                    current = None if unknown else join_namespace(current, str(pushed))
            elif tag == "group":
                named = child.get("ns") is not None or child.get("namespace") is not None
                inner = self.walk(child, None if named else current)
                if child.get("scoped", "true").strip() in _FALSE:
                    current = inner
            elif tag == "node":
                self.node(child, current)
            elif tag == "include":
                self.include(child)
            elif tag in _CONTAINERS:
                for composable in child.iter(*_COMPOSABLE):
                    self.report(
                        composable,
                        "launch-unrewritten",
                        f"composable node {composable.get('name', '')!r}: composable nodes are "
                        "not remapped; add the <remap> elements to it yourself",
                    )
            elif tag in _SET_REMAP and current is not None:
                self.loose_remap(child, current, f"a <{tag}>")
        return current

    def node(self, element: etree._Element, namespace: str | None) -> None:
        if element.get("name") is None:
            self.report(
                element,
                "launch-unknown-node",
                f"node {element.get('exec', '')!r} of {element.get('pkg', '')!r} has no name "
                "attribute: its name is set in its code, so imrosc cannot tell which node of "
                "the graph it is; it is not remapped",
            )
            return
        before = sum(len(v) for v in self.out.remaps.values())
        super().node(element, namespace)
        remapped = sum(len(v) for v in self.out.remaps.values()) > before
        arguments = " ".join(element.get(key, "") for key in ("ros_args", "args"))
        if remapped and _ARGUMENT_REMAP.search(arguments):
            self.report(
                element,
                "launch-unrewritten",
                f"node {element.get('name')!r} also remaps names in its command-line "
                "arguments, which come before its <remap> elements and win: check that none "
                "of them leads to an intercepted name",
            )


ROS2_LAUNCH = LaunchDialect(_Ros2Rewriter, "find-pkg-share", "description", "var")
"""ROS 2 launch XML."""
rewrite_ros2 = ROS2_LAUNCH.rewrite
"""The rewritten copy of a ROS 2 launch XML file (:meth:`LaunchDialect.rewrite`)."""
