"""The ``imrosc`` command line."""

from __future__ import annotations

import sys
from pathlib import Path

import click

from imrosc import __version__
from imrosc.check import check_files
from imrosc.diagnostics import RENDERERS, has_errors

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


@main.command()
def demo() -> None:
    """Run the pipeline on the embedded example system."""
    from imrosc.demo import run_demo

    sys.exit(run_demo())
