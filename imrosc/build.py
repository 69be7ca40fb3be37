"""``imrosc build``: check, lower, run the passes (:mod:`imrosc.frontend`), render a backend,
write its files.

Writing never destroys what a user had (:mod:`imrosc.outputs`): a file is written atomically
and overwritten only if it carries imrosc's generated-file mark, unless ``force`` is given;
no file is written outside the output folder. Outputs are byte-identical across runs; a
file whose content is :class:`~imrosc.backends.registry.Executable` gets its execute bits.
"""

from __future__ import annotations

import os
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path

from imrosc import ir
from imrosc.backends.registry import (
    BuildInputs,
    Executable,
    TopicType,
    load,
)
from imrosc.bags import BagError, discover_bags, open_bag
from imrosc.diagnostics import Diagnostic, finalize, has_errors, make
from imrosc.frontend import lowered, passed
from imrosc.graph.bags import BagGraphs, read_bag_graphs
from imrosc.graph.file import load_graph_file
from imrosc.graph.model import Graph
from imrosc.msgtypes import flatten
from imrosc.outputs import OutputRefusedError, file_kind, target, write_atomic
from imrosc.progress import ProgressFactory


@dataclass
class BuildResult:
    """The passed IR (if the configuration got that far) and every diagnostic."""

    project: ir.Project | None
    diagnostics: list[Diagnostic] = field(default_factory=list)
    files: dict[str, bytes] = field(default_factory=dict)

    @property
    def ok(self) -> bool:
        """Whether nothing stopped the build."""
        return self.project is not None and not has_errors(self.diagnostics)


def load_graph(
    graph_files: Sequence[Path],
    bags: Sequence[Path],
    progress_factory: ProgressFactory | None = None,
    read: BagGraphs | None = None,
) -> tuple[Graph | None, list[Diagnostic]]:
    """Merge the graph of every graph file and bag given (``read``: the bags' graphs, read
    already); None if there is none."""
    graphs: list[Graph] = []
    problems: list[Diagnostic] = []
    for path in graph_files:
        graph, found = load_graph_file(path)
        problems += found
        if graph is not None:
            graphs.append(graph)
    if read is None and bags:
        read = read_bag_graphs(bags, progress_factory)
    if read is not None:
        problems += read.diagnostics
        if read.graph.nodes:
            graphs.append(read.graph)
    return (Graph.merge(*graphs) if graphs else None), problems


NEEDS_GRAPH = frozenset({"relative-without-graph", "launch-without-graph"})
"""The codes of what a graph would have told. When bags were the only graph source and none
of them could be read, these errors only repeat the bags' own (``bag-error``): they are left
out, so that the command fails as one none of whose bags could be read (exit 2)."""


def without_graph_errors(problems: list[Diagnostic]) -> list[Diagnostic]:
    """``problems`` less those a graph would have prevented (:data:`NEEDS_GRAPH`)."""
    return [d for d in problems if d.code not in NEEDS_GRAPH]


def topic_types(bags: Sequence[Path]) -> tuple[dict[str, TopicType], list[Diagnostic]]:
    """The message type of every topic recorded in the bags (first bag that has it wins)."""
    found: dict[str, TopicType] = {}
    problems: list[Diagnostic] = []
    for path in bags:
        paths, missing = discover_bags(path)
        problems += missing
        for bag in paths:
            try:
                with open_bag(bag) as reader:
                    for connection in reader.connections:
                        if connection.topic not in found:
                            fields = flatten(reader.typestore, connection.msgtype)
                            found[connection.topic] = TopicType(connection.msgtype, fields)
            except BagError as error:
                problems.append(make(str(bag), 1, 1, "bag-error", error.message))
    return dict(sorted(found.items())), problems


def build(
    config_path: Path,
    backend: str,
    *,
    graph_files: Sequence[Path] = (),
    bags: Sequence[Path] = (),
    inv: Path | None = None,
    progress_factory: ProgressFactory | None = None,
) -> BuildResult:
    """Run the compiler up to the backend's files (nothing is written). ``inv`` is the
    invariants file the monitor deploys instead of its ``<monitor inv>`` (a refined file
    of ``imrosc classify``, say)."""
    project, problems = lowered(config_path)
    if project is None:
        return BuildResult(None, finalize(problems))
    read = read_bag_graphs(bags, progress_factory) if bags else None
    graph, found = load_graph(graph_files, bags, read=read)
    types, found_types = topic_types(bags)
    problems += found + found_types
    project, found_passes = passed(project, graph)
    none_read = read is not None and not read.read and not graph_files
    if inv is not None and project.monitor is not None:
        base = Path(project.source).parent.absolute()
        deployed = os.path.relpath(inv.absolute(), base)
        project = replace(project, monitor=replace(project.monitor, inv=deployed))
    problems += found_passes
    inputs = BuildInputs(project, tuple(str(b) for b in bags), types, graph)
    renderer = load(backend)
    files = renderer(inputs) if not has_errors(problems) else {}
    problems += inputs.diagnostics
    if none_read:
        problems = without_graph_errors(problems)
    if has_errors(problems):
        files = {}
    return BuildResult(project, finalize(problems), files)


OverwriteRefusedError = OutputRefusedError
"""The old name of :class:`imrosc.outputs.OutputRefusedError`."""


def generated_by_imrosc(path: Path) -> bool:
    """Whether the file at ``path`` carries imrosc's generated-file mark near its top."""
    return file_kind(path) is not None


def write_files(
    out: Path,
    files: Mapping[str, bytes],
    *,
    force: bool = False,
    kind: str | None = None,
    inputs: Iterable[Path] = (),
) -> list[Path]:
    """Write ``files`` under ``out``, each atomically (:mod:`imrosc.outputs`); refuse, before
    writing any, to clobber a file imrosc did not write (unless ``force``), an imrosc file of
    another kind than ``kind`` (``None``: any), one of the command's ``inputs``, or to write
    through a dangling link, or outside ``out``.

    :class:`~imrosc.backends.registry.Executable` contents are made executable.
    """
    inputs = tuple(inputs)
    root = os.path.abspath(out)
    targets: dict[str, Path] = {}
    for name in files:
        path = out / name
        inside = os.path.abspath(path)
        if os.path.commonpath([root, inside]) != root or inside == root:
            raise OutputRefusedError(path, f"is outside the output folder {out}")
        targets[name] = target(path, kind, inputs=inputs, force=force)
    written = []
    for name, path in sorted(targets.items()):
        content = files[name]
        if not (path.exists() and path.read_bytes() == content):
            write_atomic(path, content, executable=isinstance(content, Executable))
        elif isinstance(content, Executable):
            write_atomic(path, content, executable=True)
        written.append(out / name)
    return written
