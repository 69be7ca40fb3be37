"""The ``imrosc`` command line."""

from __future__ import annotations

import sys
from pathlib import Path

import click

from imrosc import __version__
from imrosc.check import check_files
from imrosc.diagnostics import RENDERERS, Diagnostic, has_errors
from imrosc.graph.command import graph_command

EXIT_CLEAN, EXIT_ERRORS, EXIT_USAGE = 0, 1, 2


@click.group(context_settings={"help_option_names": ["-h", "--help"]})
@click.version_option(__version__, prog_name="imrosc")
def main() -> None:
    """Infer invariants of a ROS robot from bags and synthesize a monitor that checks them."""


@main.command()
@click.argument("configs", nargs=-1, required=True, type=click.Path(path_type=Path))
@click.option(
    "--format",
    "output_format",
    type=click.Choice(sorted(RENDERERS)),
    default="text",
    show_default=True,
    help="text: file:line:col lines; json: one document; github: Actions annotations.",
)
@click.option("--strict", is_flag=True, help="Treat warnings as errors.")
def check(configs: tuple[Path, ...], output_format: str, strict: bool) -> None:
    """Validate imROS configuration files and report every problem found.

    Exit status: 0 when clean, 1 when there are errors, 2 for usage or I/O errors.
    """
    diagnostics = check_files(configs, strict=strict)
    click.echo(RENDERERS[output_format](diagnostics, len(configs)), nl=False)
    if any(d.code == "io-error" for d in diagnostics):
        sys.exit(EXIT_USAGE)
    sys.exit(EXIT_ERRORS if has_errors(diagnostics) else EXIT_CLEAN)


def _report(diagnostics: list[Diagnostic], output_format: str) -> None:
    """Diagnostics of a stage other than check go to stderr, in the chosen format."""
    if diagnostics:
        click.echo(RENDERERS[output_format](diagnostics, 1), nl=False, err=True)


@main.command()
@click.argument("config", type=click.Path(path_type=Path))
@click.option(
    "--backend",
    type=click.Choice(["plan", "ros1", "ros2"]),
    default="plan",
    show_default=True,
    help="plan: translator plan and inference job; ros1/ros2: a monitor package.",
)
@click.option(
    "-o",
    "--output",
    type=click.Path(file_okay=False, path_type=Path),
    help="Output directory [default: build/PROJECT-BACKEND].",
)
@click.option(
    "--graph",
    "graph_files",
    multiple=True,
    type=click.Path(dir_okay=False, path_type=Path),
    help="A graph file (YAML) saying who publishes, subscribes and serves what.",
)
@click.option(
    "--bags",
    multiple=True,
    type=click.Path(path_type=Path),
    help="Bags (or folders) to read the graph and the message types from.",
)
@click.option("--emit-ir", is_flag=True, help="Print the IR after the passes; write nothing.")
@click.option("--force", is_flag=True, help="Overwrite output files imrosc did not write.")
@click.option(
    "--format",
    "output_format",
    type=click.Choice(sorted(RENDERERS)),
    default="text",
    help="How to print diagnostics.",
)
def build(
    config: Path,
    backend: str,
    output: Path | None,
    graph_files: tuple[Path, ...],
    bags: tuple[Path, ...],
    emit_ir: bool,
    force: bool,
    output_format: str,
) -> None:
    """Compile CONFIG and render a backend's files."""
    import json

    from imrosc import ir
    from imrosc.backends.registry import available
    from imrosc.build import OverwriteRefusedError, write_files
    from imrosc.build import build as run_build

    if backend not in available():
        raise click.UsageError(f"backend {backend!r} is not available yet")
    result = run_build(config, backend, graph_files=graph_files, bags=bags)
    _report(result.diagnostics, output_format)
    if not result.ok or result.project is None:
        sys.exit(
            EXIT_USAGE if any(d.code == "io-error" for d in result.diagnostics) else EXIT_ERRORS
        )
    if emit_ir:
        click.echo(json.dumps(ir.to_json(result.project), indent=2))
        return
    out = output or Path("build") / f"{result.project.name}-{backend}"
    try:
        written = write_files(out, result.files, force=force)
    except OverwriteRefusedError as refused:
        click.echo(f"imrosc build: {refused}", err=True)
        sys.exit(EXIT_ERRORS)
    except OSError as error:
        click.echo(f"imrosc build: {out}: {error.strerror}", err=True)
        sys.exit(EXIT_USAGE)
    for path in written:
        click.echo(f"wrote {path}")


main.add_command(graph_command)


@main.command()
def demo() -> None:
    """Run the pipeline on the embedded example system."""
    from imrosc.demo import run_demo

    sys.exit(run_demo())
