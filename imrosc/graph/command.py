"""``imrosc graph``: print the node graph that bags and graph files describe.

Arguments ending in ``.yaml`` or ``.yml`` are graph files (``docs/graph.md``), except a ROS 2
bag's own ``metadata.yaml``; everything else is a bag or a directory of bags. The merged graph
goes to stdout, diagnostics to stderr. Exit status: 0 when clean, 1 when some input had errors
(the graph of the good inputs is still printed), 2 when no input could be read at all.
"""

from __future__ import annotations

import sys
from pathlib import Path

import click

from imrosc.diagnostics import Diagnostic, finalize, has_errors
from imrosc.graph.file import load_graph_file
from imrosc.graph.model import Graph
from imrosc.progress import ProgressFactory, bag_progress, quiet_option
from imrosc.remote import bag_arguments

__all__ = [
    "EXIT_CLEAN",
    "EXIT_ERRORS",
    "EXIT_UNREADABLE",
    "collect_graph",
    "graph_command",
    "is_graph_file",
]

EXIT_CLEAN, EXIT_ERRORS, EXIT_UNREADABLE = 0, 1, 2
_GRAPH_SUFFIXES = (".yaml", ".yml")
_ROS2_METADATA = "metadata.yaml"


def is_graph_file(path: Path) -> bool:
    """Whether a command-line argument names a graph file rather than bags."""
    return path.suffix in _GRAPH_SUFFIXES and path.name != _ROS2_METADATA


def collect_graph(
    inputs: tuple[Path, ...], progress_factory: ProgressFactory | None = None
) -> tuple[Graph | None, list[Diagnostic]]:
    """The merged graph of the inputs (None when none could be read) and every diagnostic."""
    from imrosc.graph.bags import read_bag_graphs  # rosbags is slow to import

    files = [path for path in inputs if is_graph_file(path)]
    bag_paths = [path for path in inputs if not is_graph_file(path)]
    graphs: list[Graph] = []
    problems: list[Diagnostic] = []
    if bag_paths:
        bags = read_bag_graphs(bag_paths, progress_factory)
        problems += bags.diagnostics
        if bags.read:
            graphs.append(bags.graph)
    for path in files:
        graph, reported = load_graph_file(path)
        problems += reported
        if graph is not None:
            graphs.append(graph)
    return (Graph.merge(*graphs) if graphs else None), finalize(problems)


@click.command("graph")
@click.argument("inputs", nargs=-1, required=True, metavar="BAG_OR_FILE...", callback=bag_arguments)
@click.option(
    "--format",
    "output_format",
    type=click.Choice(["text", "yaml"]),
    default="text",
    show_default=True,
    help="text: one line per edge; yaml: a graph file that imrosc reads back.",
)
@quiet_option
def graph_command(inputs: tuple[Path, ...], output_format: str, quiet: bool) -> None:
    """Print the node graph recorded in bags and given in graph files.

    BAG_OR_FILE is a ROS 1 .bag, a ROS 2 bag directory, a directory of bags, or a graph file
    (.yaml/.yml). Sources: architecture records from `imrosc record`, the callerid of ROS 1
    connections (publishers only), graph files.

    Exit status: 0 when clean, 1 when an input has errors, 2 when no input could be read.
    """
    with bag_progress("reading", quiet) as factory:
        graph, problems = collect_graph(inputs, factory)
    for problem in problems:
        click.echo(problem.as_text(), err=True)
    if graph is None:
        sys.exit(EXIT_UNREADABLE)
    click.echo(graph.render_yaml() if output_format == "yaml" else graph.render_text(), nl=False)
    if not graph.nodes:  # say why, rather than print an empty graph
        click.echo(
            "imrosc graph: no node found: the inputs record no publisher (ROS 2 bags hold no "
            "callerids; imrosc record records the graph); imrosc info lists a bag's topics",
            err=True,
        )
    sys.exit(EXIT_ERRORS if has_errors(problems) else EXIT_CLEAN)
