"""``imrosc demo``: the pipeline on the embedded example configurations.

For now the demo checks the three example configurations shipped in the package (the
thesis' water sampling, UAV landing and crop surveying systems) and says what each later
stage of the pipeline will do with them.
"""

from __future__ import annotations

import importlib.resources
from pathlib import Path

import click

from imrosc.check import check_files
from imrosc.diagnostics import has_errors, render_text

STAGES = (
    ("check", "validate each configuration against grammar/imros.xsd and its semantics", True),
    ("build --backend plan", "lower it to the IR and write the translator plan and job", True),
    ("infer", "translate the bags into program points and infer the invariants", False),
    ("classify", "score each invariant on successful and failed runs, keep the useful", False),
    ("build --backend ros1|ros2", "render a monitor package that checks them live", False),
    ("replay", "run the monitor's engine over a faulty run and show the violations", False),
)


def example_configs() -> list[Path]:
    """The example configurations shipped inside the package."""
    folder = importlib.resources.files("imrosc.demo").joinpath("examples")
    return sorted(Path(str(entry)) for entry in folder.iterdir() if entry.name.endswith(".xml"))


def run_demo() -> int:
    """Run the stages that exist on the embedded examples; return the exit status."""
    configs = example_configs()
    click.echo(f"imrosc demo: {len(configs)} example configurations")
    for config in configs:
        click.echo(f"  {config}")
    diagnostics = check_files(configs)
    click.echo("\n$ imrosc check " + " ".join(c.name for c in configs))
    click.echo(render_text(diagnostics, len(configs)), nl=False)
    click.echo("\nPipeline stages:")
    for command, what, ready in STAGES:
        state = "ready" if ready else "coming"
        click.echo(f"  [{state:>6}] imrosc {command}: {what}")
    return 1 if has_errors(diagnostics) else 0
