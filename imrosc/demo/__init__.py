"""``imrosc demo``: the pipeline on the embedded example system.

The example is the thesis' landing system (section 5.1), simulated by :mod:`imrosc.sim`: the
demo writes nominal runs as bags (ROS 1, and one as a ROS 2 MCAP bag), runs that succeed and
runs with a fault for the check stage, then runs ``check``, ``build --backend plan``,
``infer``, ``classify`` and ``replay`` on ``examples/landing_sim.xml`` and builds the ROS 1
and ROS 2 monitors of the invariants classification kept, and says where each output is.
"""

from __future__ import annotations

import importlib.resources
import shutil
from pathlib import Path

import click

from imrosc.build import build, write_files
from imrosc.check import check_files
from imrosc.detect import run_detect
from imrosc.diagnostics import has_errors, render_text
from imrosc.infer.engine import default_workers
from imrosc.invariants import dumps
from imrosc.outputs import write_atomic
from imrosc.progress import ProgressFactory, bag_progress
from imrosc.report.values import plural
from imrosc.show import render
from imrosc.sim import ScenarioKind

MARKER = ".imrosc-demo"
CONFIG = "landing_sim.xml"
FAULTS: tuple[ScenarioKind, ...] = ("slowed", "spoofed", "stuck", "tilt")
COMING: tuple[tuple[str, str], ...] = ()


def example_configs() -> list[Path]:
    """The example configurations shipped inside the package."""
    folder = importlib.resources.files("imrosc.demo").joinpath("examples")
    return sorted(Path(str(entry)) for entry in folder.iterdir() if entry.name.endswith(".xml"))


def _prepare(out: Path) -> bool:
    """Create ``out`` for the demo; refuse a non-empty folder the demo did not make."""
    if out.exists() and any(out.iterdir()) and not (out / MARKER).exists():
        click.echo(
            f"imrosc demo: {out} exists and was not made by imrosc demo; choose -o", err=True
        )
        return False
    if (out / MARKER).exists():
        for child in ("bags", "build"):
            shutil.rmtree(out / child, ignore_errors=True)
    out.mkdir(parents=True, exist_ok=True)
    write_atomic(out / MARKER, b"made by imrosc demo; it may delete bags/ and build/ here\n")
    return True


def _write_bags(out: Path, runs: int) -> None:
    from imrosc.sim import Scenario, write_run, write_runs

    nominal = out / "bags" / "nominal"
    write_runs(nominal, runs=max(runs - 1, 1), seed=0, fmt="ros1")
    write_run(nominal / "nominal_mcap", seed=runs, fmt="mcap")
    write_runs(out / "bags" / "success", runs=2, seed=100, fmt="ros1")
    # each faulty run is a nominal run (same seed) with the fault from 10 s on: what breaks
    # in it is the fault's doing
    for offset, kind in enumerate(FAULTS):
        write_run(
            out / "bags" / "fail" / f"{kind}.bag",
            seed=offset % max(runs - 1, 1),
            fmt="ros1",
            scenario=Scenario(kind),
        )


def _check_stage(
    out: Path, config: Path, workers: int | None, progress: ProgressFactory
) -> Path | None:
    """Classify the invariants, then replay a faulty run with the refined ones; the refined
    invariants file (None: the stage failed)."""
    from imrosc.classify import CheckStageError, run_check
    from imrosc.replay import replay_document
    from imrosc.report import render as render_report

    report = out / "classify.html"
    click.echo(f"\n5. imrosc classify {config} --format html -o {report}")
    try:
        checked = run_check(config, workers=workers or default_workers(), progress_factory=progress)
    except CheckStageError as error:
        click.echo(f"   {error}", err=True)
        return None
    if checked.refined is None or checked.output is None:
        click.echo(render_text(checked.diagnostics, 1), nl=False)
        return None
    write_files(
        checked.output.parent, {checked.output.name: dumps(checked.refined).encode()}, force=True
    )
    write_files(out, {report.name: render_report(checked.report, "html").encode()}, force=True)
    families = checked.report["families"]
    kept = sum(f["kept"] for f in families.values())
    total = sum(f["total"] for f in families.values())
    how = (
        "the set whose union detects the most faulty runs minus its expected false alarms"
        if checked.report["select"] == "cover"
        else f"F-score >= {checked.report['threshold']}"
    )
    click.echo(
        f"   kept {kept} of {total} invariants ({how}) in {checked.output}; scores in {report}"
    )
    faulty = out / "bags" / "fail" / "spoofed.bag"
    click.echo(
        f"\n6. imrosc replay {checked.output} {faulty} --format html -o {out / 'replay.html'}"
    )
    document, runs = replay_document(checked.output, checked.refined, [faulty])
    write_files(out, {"replay.html": render_report(document, "html").encode()}, force=True)
    episodes = document["runs"][0]["episodes"]
    click.echo(
        f"   {plural(len(runs[0].violations), 'violation')} in "
        f"{plural(len(episodes), 'episode')}; "
        f"timeline and plots in {out / 'replay.html'}"
    )
    for line in render_report(document, "text").splitlines()[1:7]:
        click.echo("   " + line)
    return checked.output


def _monitors(out: Path, config: Path, inv: Path) -> bool:
    """Build the ROS 1 and ROS 2 monitor packages of the demo's <monitor>, deploying the
    invariants ``inv`` (those classification kept)."""
    graph = out / "landing_sim.graph.yaml"
    for backend in ("ros1", "ros2"):
        target = out / "build" / backend
        step = 7 if backend == "ros1" else 8
        click.echo(
            f"\n{step}. imrosc build {config} --backend {backend} --inv {inv} -o {target} "
            f"--graph {graph}"
        )
        built = build(config, backend, graph_files=[graph], inv=inv)
        if not built.ok:
            click.echo(render_text(built.diagnostics, 1), nl=False)
            return False
        written = write_files(target, built.files, force=True)
        package = sorted({p.relative_to(target).parts[0] for p in written})
        click.echo(f"   wrote {len(written)} files: the package {target / package[0]}")
    click.echo(
        f"\n   ROS 1: ROS_PACKAGE_PATH={out / 'build' / 'ros1'}:$ROS_PACKAGE_PATH "
        "roslaunch landing_sim_monitor landing_sim_monitor.launch"
    )
    click.echo(f"   ROS 2: colcon build --base-paths {out / 'build' / 'ros2'}")
    return True


def run_demo(
    out: Path = Path("imrosc-demo"),
    runs: int = 6,
    workers: int | None = None,
    quiet: bool = False,
) -> int:
    """Simulate, check, build, infer, classify, replay and build the monitors; return the
    exit status. Stages that read bags show their progress unless ``quiet``."""
    with bag_progress("reading", quiet) as progress:
        return _run(out, runs, workers, progress)


def _run(out: Path, runs: int, workers: int | None, progress: ProgressFactory) -> int:
    if not _prepare(out):
        return 2
    source = next(p for p in example_configs() if p.name == CONFIG)
    config = out / CONFIG
    shutil.copyfile(source, config)
    graph = next(p for p in example_configs() if p.name == CONFIG).with_name(
        "landing_sim.graph.yaml"
    )
    shutil.copyfile(graph, out / graph.name)
    click.echo(f"1. simulating the landing system of thesis section 5.1 into {out / 'bags'}")
    _write_bags(out, runs)
    click.echo(
        f"   {runs} nominal runs (one as a ROS 2 MCAP bag), 2 successful, {len(FAULTS)} faulty"
    )

    click.echo(f"\n2. imrosc check {config}  (and the thesis' example configurations)")
    diagnostics = check_files([config, *(p for p in example_configs() if p.name != CONFIG)])
    click.echo(render_text(diagnostics, len(example_configs())), nl=False)
    if has_errors(diagnostics):
        return 1

    click.echo(f"\n3. imrosc build {config} --backend plan --bags {out / 'bags' / 'nominal'}")
    built = build(config, "plan", bags=[out / "bags" / "nominal"], progress_factory=progress)
    if not built.ok:
        click.echo(render_text(built.diagnostics, 1), nl=False)
        return 1
    for path in write_files(out / "build" / "plan", built.files, force=True):
        click.echo(f"   wrote {path}")

    click.echo(f"\n4. imrosc infer {config}")
    result = run_detect(config, workers=workers or default_workers(), progress_factory=progress)
    if result.document is None or result.output is None:
        click.echo(render_text(result.diagnostics, 1), nl=False)
        return 1
    write_files(
        result.output.parent, {result.output.name: dumps(result.document).encode()}, force=True
    )
    counts = ", ".join(f"{n} {group}" for group, n in result.counts().items())
    click.echo(f"   wrote {result.output}: {sum(result.counts().values())} invariants: {counts}")
    spent = result.seconds + result.calibration_seconds
    click.echo(f"   ({spent:.1f} s; see them all with: imrosc show {result.output})")
    if result.calibration is not None:
        click.echo(f"   {result.calibration.summary()}")
    sample = render(result.document, points=["v"]).splitlines()[:12]
    click.echo("\n".join("   " + line for line in sample))
    refined = _check_stage(out, config, workers, progress)
    if refined is None or not _monitors(out, config, refined):
        return 1
    if COMING:
        click.echo("\nComing in later stages:")
        for command, what in COMING:
            click.echo(f"   imrosc {command}: {what}")
    return 0
