"""The ``imrosc`` command line."""

from __future__ import annotations

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")  # BLAS threads stall a loaded 2-core machine

import contextlib
import errno
import sys
from collections.abc import Iterable, Iterator, Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any, NoReturn

import click

from imrosc import __version__
from imrosc.backends.registry import names as backend_names
from imrosc.check import check_files
from imrosc.codes import Severity
from imrosc.diagnostics import RENDERERS, Diagnostic, has_errors
from imrosc.graph.command import graph_command
from imrosc.outputs import BUILD, REPORT, OutputRefusedError, mark
from imrosc.progress import bag_progress, quiet_option
from imrosc.remote import bag_arguments

if TYPE_CHECKING:
    from imrosc.fleet import Fleet

EXIT_CLEAN, EXIT_ERRORS, EXIT_USAGE = 0, 1, 2
"""0: done, nothing found; 1: findings (errors in a configuration, alarms, bags that could not
be read among others); 2: usage and input errors (the command line, an input file missing or
malformed, an output refused because writing it would destroy a file)."""
EXIT_VIOLATIONS = 3
"""``imrosc replay``: violations that raised no alarm."""
EXIT_ENVIRONMENT = 4
"""The system refused: an output cannot be written (permission denied, disk full, a path
through a regular file, a read-only file system). The README has the table."""
EXIT_UNCHECKED = 5
"""``imrosc replay``, ``imrosc classify``: nothing worse, but a publish point checked no
sample in some run (its invariants went unchecked there). Precedence: 1, then 3, then 5."""


def fail(command: str, message: str, status: int) -> NoReturn:
    """One line on stderr, ``imrosc COMMAND: message``, and exit with ``status``."""
    click.echo(f"imrosc {command}: {message}", err=True)
    sys.exit(status)


def os_problem(error: OSError) -> str:
    """An OS error in one line: the file, then what went wrong."""
    what = error.strerror or str(error)
    return f"{error.filename}: {what}" if error.filename is not None else what


def folder_name(project: str) -> str:
    """A project name as one folder name: letters, digits, ``_`` and ``-`` (``../../x``, as
    it is, would put ``build/../../x-plan`` outside ``build/``; it gives ``x``)."""
    import re

    return re.sub(r"[^A-Za-z0-9_-]+", "_", project).strip("_") or "project"


class _Main(click.Group):
    """The command group: an OS error a command did not handle (a folder it cannot create, a
    disk that filled up) ends it with one line on stderr and :data:`EXIT_ENVIRONMENT`, never
    a traceback."""

    def invoke(self, ctx: click.Context) -> Any:
        try:
            return super().invoke(ctx)
        except OSError as error:
            if error.errno == errno.EPIPE:  # click's own handling of a closed stdout
                raise
            fail(ctx.invoked_subcommand or "", os_problem(error), EXIT_ENVIRONMENT)
        except RecursionError:
            fail(ctx.invoked_subcommand or "", "input nested too deeply", EXIT_USAGE)


graph_option = click.option(
    "--graph",
    "graph_files",
    multiple=True,
    type=click.Path(dir_okay=False, path_type=Path),
    help="A graph file (YAML) saying who publishes, subscribes and serves what.",
)


bags_option = click.option(
    "--bags",
    multiple=True,
    metavar="BAG",
    callback=bag_arguments,
    help="Bags, folders, globs or URLs to read (instead of the <detect> bags, where there "
    "are some).",
)


scheduler_option = click.option(
    "--scheduler",
    envvar="IMROSC_SCHEDULER",
    metavar="ADDRESS",
    help="A Dask scheduler (tcp://host:8786): each bag is a task on its cluster "
    "(docs/fleet.md) [env: IMROSC_SCHEDULER].",
)


@contextlib.contextmanager
def cluster(command: str, address: str | None) -> Iterator[Fleet | None]:
    """A client of the Dask cluster at ``address`` (none without one); a cluster
    that cannot be used ends the command with one line and :data:`EXIT_USAGE`."""
    if not address:
        yield None
        return
    from imrosc.fleet import FleetError, connect

    try:
        with connect(address) as fleet:
            yield fleet
    except FleetError as error:
        fail(command, str(error), EXIT_USAGE)


@click.group(cls=_Main, context_settings={"help_option_names": ["-h", "--help"]})
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


_UNREADABLE = frozenset({"io-error", "invariants-unreadable"})
"""The codes of an input file that could not be read or is malformed (not a configuration's
findings): a missing configuration, a monitor's invariants file that is missing or bad."""


def _stopped(diagnostics: list[Diagnostic]) -> int:
    """The exit status of a command its inputs stopped: 2 when a file could not be read or
    is malformed (an input error, as ``check`` and README's "Exit status" say: a configuration
    that cannot be read, an invariants file ``build`` deploys), else 1 (errors in the
    configuration)."""
    return EXIT_USAGE if any(d.code in _UNREADABLE for d in diagnostics) else EXIT_ERRORS


def _none_read(bags: Sequence[Path], diagnostics: list[Diagnostic]) -> bool:
    """Whether bags were named, none of them could be read and nothing else is wrong (an
    input error, exit 2, as an unreadable configuration is; some read and some not, or errors
    in the configuration too: findings, exit 1)."""
    from imrosc.bags import discover_bags

    errors = [d for d in diagnostics if d.severity is Severity.ERROR]
    failed = {d.path for d in errors if d.code == "bag-error"}
    if not bags or not failed or any(d.code != "bag-error" for d in errors):
        return False
    found = [bag for path in bags for bag in discover_bags(path)[0]]
    return all(str(bag) in failed for bag in found)


def _report(diagnostics: list[Diagnostic], output_format: str) -> None:
    """Diagnostics of a stage other than check go to stderr, in the chosen format."""
    if diagnostics:
        click.echo(RENDERERS[output_format](diagnostics, 1), nl=False, err=True)


@main.command()
@click.argument("config", type=click.Path(path_type=Path))
@click.option(
    "--backend",
    type=click.Choice(backend_names()),
    default="plan",
    show_default=True,
    help="plan: translator plan and inference job; ros1/ros2: a monitor package; or a "
    "backend another package registers (entry points imrosc.backends).",
)
@click.option(
    "-o",
    "--output",
    type=click.Path(file_okay=False, path_type=Path),
    help="Output directory [default: build/PROJECT-BACKEND].",
)
@graph_option
@click.option(
    "--bags",
    multiple=True,
    metavar="BAG",
    callback=bag_arguments,
    help="Bags, folders, globs or URLs whose graph (architecture records, callerid) and "
    "message types the build uses; the <detect> bags are not read.",
)
@click.option(
    "--inv",
    type=click.Path(dir_okay=False, path_type=Path),
    help="The invariants file the monitor deploys instead of its <monitor inv> "
    "(e.g. classify's refined file).",
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
@quiet_option
def build(
    config: Path,
    backend: str,
    output: Path | None,
    graph_files: tuple[Path, ...],
    bags: tuple[Path, ...],
    inv: Path | None,
    emit_ir: bool,
    force: bool,
    output_format: str,
    quiet: bool,
) -> None:
    """Compile CONFIG and render a backend's files."""
    import json

    from imrosc import ir
    from imrosc.backends.registry import BackendError, is_monitor
    from imrosc.build import build as run_build
    from imrosc.build import write_files

    try:
        monitor = is_monitor(backend)
    except BackendError as error:
        fail("build", str(error), EXIT_USAGE)
    if inv is not None and not monitor:
        raise click.UsageError(
            f"--inv names the invariants a monitor deploys: backend {backend} renders none"
        )
    with bag_progress("reading", quiet) as factory:
        result = run_build(
            config, backend, graph_files=graph_files, bags=bags, inv=inv, progress_factory=factory
        )
    _report(result.diagnostics, output_format)
    if not result.ok or result.project is None:
        sys.exit(
            EXIT_USAGE if _none_read(bags, result.diagnostics) else _stopped(result.diagnostics)
        )
    if emit_ir:
        click.echo(json.dumps(ir.to_json(result.project), indent=2))
        return
    out = output or Path("build") / f"{folder_name(result.project.name)}-{backend}"
    try:
        written = write_files(
            out,
            result.files,
            force=force,
            kind=BUILD,
            inputs=(config, *graph_files, *bags, *([inv] if inv is not None else [])),
        )
    except OutputRefusedError as refused:
        fail("build", str(refused), EXIT_USAGE)
    for path in written:
        click.echo(f"wrote {path}")
    if monitor and result.files:
        package = out / next(iter(result.files)).split("/", 1)[0]
        click.echo(f"monitor package {package} (see docs/monitor.md)")


main.add_command(graph_command)


@main.command()
@click.argument("config", type=click.Path(path_type=Path))
@click.option("-j", "--jobs", type=click.IntRange(min=1), help="Worker processes [default: cores].")
@graph_option
@bags_option
@click.option(
    "-o",
    "--output",
    type=click.Path(dir_okay=False, path_type=Path),
    help="Invariants file [default: detect/@inv].",
)
@click.option(
    "--budget",
    type=click.FloatRange(0.0, 0.5),
    help="Per-run false-alarm budget of calibration; 0: exact extremes, every violation an "
    "alarm [default: detect/@budget, 0.05].",
)
@click.option("--force", is_flag=True, help="Overwrite an output file imrosc did not write.")
@scheduler_option
@quiet_option
def infer(
    config: Path,
    jobs: int | None,
    graph_files: tuple[Path, ...],
    bags: tuple[Path, ...],
    output: Path | None,
    budget: float | None,
    force: bool,
    scheduler: str | None,
    quiet: bool,
) -> None:
    """Infer the invariants of CONFIG's <detect> bags, calibrate them across the bags
    (docs/calibration.md) and write the invariants file; with --scheduler, each bag is a
    task on a Dask cluster (docs/fleet.md)."""
    from imrosc.build import write_files
    from imrosc.detect import run_detect
    from imrosc.invariants import dumps
    from imrosc.outputs import INVARIANTS, target

    def before_work(default: Path, read: Sequence[Path]) -> None:
        """Refuse the invariants file once the bags are known, before any is read."""
        target(output or default, INVARIANTS, inputs=(config, *graph_files, *read), force=force)

    try:
        with cluster("infer", scheduler) as fleet, bag_progress("inferring", quiet) as factory:
            result = run_detect(
                config,
                workers=jobs,
                graph_files=graph_files,
                bags=list(bags) or None,
                progress_factory=factory,
                budget=budget,
                before_work=before_work,
                reducer=fleet,
                replays=fleet.replay_held_out if fleet is not None else None,
                noter=fleet.note_bags if fleet is not None else None,
            )
    except OutputRefusedError as refused:
        fail("infer", str(refused), EXIT_USAGE)
    _report(result.diagnostics, "text")
    if result.document is None or result.output is None:
        sys.exit(_stopped(result.diagnostics))
    written = output or result.output
    catalog, inferred = result.catalog, result.result
    assert catalog is not None and inferred is not None
    good = len(catalog.bags) - len(inferred.failed)
    if not good:  # invariants of nothing would replace the file's good ones
        fail("infer", f"no bag could be read: {written} not written", EXIT_USAGE)
    try:
        write_files(
            written.parent,
            {written.name: dumps(result.document).encode()},
            force=force,
            kind=INVARIANTS,
            inputs=(config, *graph_files, *catalog.bags),
        )
    except OutputRefusedError as refused:
        fail("infer", str(refused), EXIT_USAGE)
    counts = result.counts()
    total = sum(counts.values())
    summary = ", ".join(f"{n} {group}" for group, n in counts.items())
    rate = inferred.messages / max(result.seconds, 1e-9)
    click.echo(f"wrote {written}: {total} invariants: {summary}")
    click.echo(
        f"from {good} bag{'s' * (good != 1)}, {inferred.messages:,} messages in "
        f"{result.seconds:.1f} s ({rate:,.0f} msg/s)"
        + (f", calibrated in {result.calibration_seconds:.1f} s" if result.calibration else "")
    )
    if scheduler:
        click.echo(f"on the Dask cluster at {scheduler}")
    skipped = sorted({d.path for d in result.diagnostics if d.code == "bag-error"})
    if skipped:
        click.echo(f"skipped {len(skipped)} bag{'s' * (len(skipped) != 1)}: {', '.join(skipped)}")
    for message in result.skipped_points:
        click.echo(f"skipped {message}")
    for line in result.nonfinite():
        click.echo(line)
    if inferred.discovered:
        shown = ", ".join(sorted({d.key for d in inferred.discovered}))
        click.echo(f"conditions found: {shown}")
    if result.calibration is not None:
        click.echo(result.calibration.summary())
    sys.exit(EXIT_ERRORS if has_errors(result.diagnostics) else EXIT_CLEAN)


@main.command("export-daikon")
@click.argument("config", type=click.Path(path_type=Path))
@click.option("-o", "--output", required=True, type=click.Path(file_okay=False, path_type=Path))
@graph_option
@bags_option
@click.option("--force", is_flag=True, help="Overwrite .decls/.dtrace files imrosc did not write.")
@quiet_option
def export_daikon(
    config: Path,
    output: Path,
    graph_files: tuple[Path, ...],
    bags: tuple[Path, ...],
    force: bool,
    quiet: bool,
) -> None:
    """Write the program points of CONFIG's bags as Daikon .decls/.dtrace files."""
    from imrosc.detect import prepare
    from imrosc.export_daikon import export, targets

    prepared, diagnostics = prepare(config, graph_files=graph_files, bags=list(bags) or None)
    _report(diagnostics, "text")
    if prepared is None:
        sys.exit(_stopped(diagnostics))
    catalog = prepared.catalog
    if not catalog.bags:
        fail("export-daikon", f"no bag could be read: nothing written to {output}", EXIT_USAGE)
    try:
        paths = targets(output, catalog.bags, force=force, inputs=(config, *catalog.bags))
    except OutputRefusedError as refused:
        fail("export-daikon", str(refused), EXIT_USAGE)
    with bag_progress("exporting", quiet) as factory:
        written = export(
            prepared.specs,
            prepared.layouts,
            catalog.callerids,
            catalog.bags,
            paths,
            factory(len(catalog.bags)),
        )
    for path in written:
        click.echo(f"wrote {path}")
    sys.exit(EXIT_ERRORS if has_errors(diagnostics) else EXIT_CLEAN)


@main.command()
@click.argument("bags", nargs=-1, required=True, callback=bag_arguments)
@click.option(
    "--format",
    "output_format",
    type=click.Choice(["text", "json"]),
    default="text",
    show_default=True,
)
@quiet_option
def info(bags: tuple[Path, ...], output_format: str, quiet: bool) -> None:
    """What BAGS hold (ROS 1 bags, ROS 2 bag folders, or folders of them): per bag its
    format, time span and messages; per topic its type, messages, mean rate, publishers and
    the variables a <publish> of it would watch. Exit status 1 when a bag cannot be read
    (each named on stderr), 2 when none can; a bag cut short is read as far as it goes, with
    a warning."""
    import json

    from imrosc.info import collect, render

    with bag_progress("reading", quiet) as factory:
        infos, problems = collect(list(bags), factory)
    for problem in problems:
        click.echo(f"imrosc info: {problem.as_text()}", err=True)
    if output_format == "json":
        click.echo(json.dumps([i.as_json() for i in infos], indent=2))
    elif infos:
        click.echo(render(infos), nl=False)
    if has_errors(problems):
        sys.exit(EXIT_ERRORS if infos else EXIT_USAGE)


@main.command()
@click.argument("inv", type=click.Path(path_type=Path))
@click.option("--family", "families", multiple=True, help="Only this family (repeatable).")
@click.option("--point", "points", multiple=True, help="Only this program point (repeatable).")
@click.option("--ids", is_flag=True, help="Prefix each invariant with its id.")
def show(inv: Path, families: tuple[str, ...], points: tuple[str, ...], ids: bool) -> None:
    """Print an invariants file, Daikon style, grouped by program point."""
    from imrosc.invariants import InvariantsFileError, load
    from imrosc.show import render, unknown_filter

    try:
        doc = load(inv)
    except InvariantsFileError as error:
        fail("show", str(error), EXIT_USAGE)
    problem = unknown_filter(doc, families=families, points=points)
    if problem is not None:
        fail("show", f"{inv}: {problem}", EXIT_USAGE)
    try:
        text = render(doc, families=families, points=points, ids=ids)
    except (KeyError, IndexError, TypeError, ValueError, OverflowError) as error:
        fail("show", f"{inv}: malformed: {type(error).__name__}: {error}", EXIT_USAGE)
    click.echo(text, nl=False)


@main.command()
@click.option(
    "-o",
    "--output",
    type=click.Path(file_okay=False, path_type=Path),
    default=Path("imrosc-demo"),
    show_default=True,
    help="Where the demo writes its bags and outputs.",
)
@click.option("--runs", type=click.IntRange(min=2), default=6, show_default=True)
@click.option("-j", "--jobs", type=click.IntRange(min=1), help="Worker processes [default: cores].")
@quiet_option
def demo(output: Path, runs: int, jobs: int | None, quiet: bool) -> None:
    """Run the pipeline on the embedded example: a simulated UAV landing system."""
    from imrosc.demo import run_demo

    sys.exit(run_demo(output, runs, jobs, quiet))


format_option = click.option(
    "--format",
    "output_format",
    type=click.Choice(["text", "json", "html"]),
    default="text",
    show_default=True,
    help="Report format (html: one self-contained file with plots).",
)
report_option = click.option(
    "-o",
    "--output",
    "report_path",
    type=click.Path(dir_okay=False, path_type=Path),
    help="Write the report to this file instead of standard output.",
)


def _report_target(command: str, path: Path | None, force: bool, inputs: Iterable[Path]) -> None:
    """Refuse a report path at once (before any work or other output) if writing it would
    destroy a file (:mod:`imrosc.outputs`)."""
    from imrosc.outputs import target

    if path is not None:
        try:
            target(path, REPORT, inputs=inputs, force=force)
        except OutputRefusedError as refused:
            fail(command, str(refused), EXIT_USAGE)


def _emit(
    command: str,
    document: dict[str, object],
    output_format: str,
    path: Path | None,
    force: bool,
    inputs: Iterable[Path] = (),
) -> None:
    """Render a result document and print it or write it (never over a foreign file, another
    kind of imrosc file or an input; atomically)."""
    from imrosc.build import write_files
    from imrosc.report import render

    text = render(document, output_format)  # type: ignore[arg-type]
    if path is None:
        click.echo(text, nl=False)
        return
    if output_format == "text":  # so that the next run may overwrite it
        text = f"# {mark(REPORT)}\n{text}"
    try:
        write_files(
            path.parent, {path.name: text.encode()}, force=force, kind=REPORT, inputs=inputs
        )
    except OutputRefusedError as refused:
        fail(command, str(refused), EXIT_USAGE)
    click.echo(f"wrote {path}", err=True)


@main.command()
@click.argument("inv", type=click.Path(dir_okay=False, path_type=Path))
@click.argument("bags", nargs=-1, required=True, callback=bag_arguments)
@format_option
@click.option("--json", "as_json", is_flag=True, help="Same as --format json.")
@report_option
@click.option("--no-plots", is_flag=True, help="Leave the plot data out (smaller reports).")
@click.option("--force", is_flag=True, help="Overwrite a report file imrosc did not write.")
@scheduler_option
@quiet_option
def replay(
    inv: Path,
    bags: tuple[Path, ...],
    output_format: str,
    as_json: bool,
    report_path: Path | None,
    no_plots: bool,
    force: bool,
    scheduler: str | None,
    quiet: bool,
) -> None:
    """Run the monitor's engine over BAGS as if live and print the violation timeline;
    with --scheduler, each bag is a task on a Dask cluster (docs/fleet.md).

    Exit status: 0 no violation, 1 an alarm (or a bag that could not be read among
    readable ones), 3 violations that raised no alarm, 5 a point that checked no sample in
    some run (its invariants went unchecked there); the first that applies, in that order;
    2 when no bag could be read.
    """
    from imrosc.bags import discover_bags
    from imrosc.invariants import InvariantsFileError, load
    from imrosc.replay import replay_document

    _report_target("replay", report_path, force, (inv, *bags))
    try:
        document = load(inv)
    except InvariantsFileError as error:
        fail("replay", str(error), EXIT_USAGE)
    found: list[Path] = []
    problems: list[Diagnostic] = []
    for path in bags:
        more, bad = discover_bags(path)
        found += more
        problems += bad
    _report(problems, "text")
    try:
        with cluster("replay", scheduler) as fleet, bag_progress("replaying", quiet) as factory:
            report, results = replay_document(
                inv,
                document,
                found,
                plots=not no_plots,
                progress=factory(len(found)),
                elsewhere=fleet.replay_runs if fleet is not None else None,
            )
    except (KeyError, IndexError, TypeError, ValueError, OverflowError) as error:
        fail("replay", f"{inv}: malformed: {type(error).__name__}: {error}", EXIT_USAGE)
    shown = "json" if as_json else output_format
    every = shown != "text" or report_path is not None  # else the report on stdout says them
    for result in results:
        if result.error is not None:  # in the report, and on stderr as every error is
            named = str(result.error)
            named = named if named.startswith(f"{result.bag}: ") else f"{result.bag}: {named}"
            click.echo(f"imrosc replay: {named}", err=True)
        for warning in result.warnings:
            if every or warning == result.recovered:  # a damaged bag is said on stderr too
                click.echo(f"imrosc replay: {result.bag}: warning: {warning}", err=True)
    _emit("replay", report, shown, report_path, force, (inv, *bags, *found))
    broken = any(r.alarms or r.error for r in results) or has_errors(problems)
    violated = any(r.violations for r in results)
    unchecked = any(r.unchecked for r in results)
    read = any(r.error is None for r in results)
    sys.exit(
        EXIT_USAGE  # no bag could be read: an input error, as in every command
        if broken and not read
        else EXIT_ERRORS
        if broken
        else EXIT_VIOLATIONS
        if violated
        else EXIT_UNCHECKED
        if unchecked
        else EXIT_CLEAN
    )


@main.command()
@click.argument("config", type=click.Path(dir_okay=False, path_type=Path))
@click.option("-j", "--jobs", type=click.IntRange(min=1), help="Worker processes [default: cores].")
@click.option(
    "--inv",
    type=click.Path(dir_okay=False, path_type=Path),
    help="Invariants file to check [default: check/@inv].",
)
@click.option(
    "--refined",
    type=click.Path(dir_okay=False, path_type=Path),
    help="Where to write the refined invariants [default: <inv>.refined.inv].",
)
@click.option(
    "--cross-validate",
    "cross_validate",
    type=click.IntRange(min=2),
    metavar="K",
    help="Score the <success> runs that are <detect> runs against invariants inferred from "
    "the other K-1 folds of the <detect> bags (run-level false alarms).",
)
@format_option
@report_option
@click.option("--force", is_flag=True, help="Overwrite output files imrosc did not write.")
@scheduler_option
@quiet_option
def classify(
    config: Path,
    jobs: int | None,
    inv: Path | None,
    refined: Path | None,
    cross_validate: int | None,
    output_format: str,
    report_path: Path | None,
    force: bool,
    scheduler: str | None,
    quiet: bool,
) -> None:
    """Score each invariant on CONFIG's <check> runs (or compare data sets) and keep the
    useful ones; with fault onsets, score the alarms and their delays too; with
    --scheduler, each run is a task on a Dask cluster (docs/fleet.md).

    Exit status: 0 done, 1 a run that could not be read, 5 a point that checked no sample
    in some run (its invariants went unchecked there); 2 when no run could be read.
    """
    from imrosc.build import write_files
    from imrosc.classify import CheckStageError, run_check
    from imrosc.invariants import dumps
    from imrosc.outputs import INVARIANTS, target

    inputs = (config, *((inv,) if inv is not None else ()))
    _report_target("classify", report_path, force, inputs)
    if refined is not None:
        try:
            target(refined, INVARIANTS, inputs=inputs, force=force)
        except OutputRefusedError as refused:
            fail("classify", str(refused), EXIT_USAGE)

    def before_work(refined_path: Path | None, read: Path) -> None:
        """Refuse the outputs before any bag is read: the refined file, then the report."""
        every = (*inputs, read)
        if refined_path is not None:
            target(refined_path, INVARIANTS, inputs=every, force=force)
        if report_path is None:
            return
        if refined_path is not None and os.path.abspath(refined_path) == os.path.abspath(
            report_path
        ):
            raise OutputRefusedError(report_path, "is also the refined invariants file")
        target(report_path, REPORT, inputs=(*every, *filter(None, [refined_path])), force=force)

    try:
        with cluster("classify", scheduler) as fleet, bag_progress("classifying", quiet) as factory:
            result = run_check(
                config,
                inv=inv,
                output=refined,
                workers=jobs,
                cross_validate=cross_validate,
                before_work=before_work,
                progress_factory=factory,
                cluster=fleet,
            )
    except CheckStageError as error:
        fail("classify", str(error), EXIT_USAGE)
    except OutputRefusedError as refused:
        fail("classify", str(refused), EXIT_USAGE)
    _report(result.diagnostics, "text")
    for run in result.report.get("runs", ()):
        for warning in run.get("warnings", ()):
            click.echo(f"imrosc classify: {run['bag']}: warning: {warning}", err=True)
    for bag, warnings in result.report.get("warnings", {}).items():  # comparing data sets
        for warning in warnings:
            click.echo(f"imrosc classify: {bag}: warning: {warning}", err=True)
    for unread in result.report.get("errors", ()):  # each names its bag
        click.echo(f"imrosc classify: {unread['error']}", err=True)
    if not result.report:
        sys.exit(_stopped(result.diagnostics))
    unread = has_errors(result.diagnostics) or bool(result.report.get("errors"))
    if "runs" in result.report and not result.report["runs"] and unread:
        fail("classify", "no bag could be read: nothing written", EXIT_USAGE)
    inputs = (config, *result.inputs)
    refined_path = result.output if result.refined is not None else None
    same = refined_path is not None and report_path is not None
    if same and os.path.abspath(str(refined_path)) == os.path.abspath(str(report_path)):
        fail("classify", f"{report_path}: is also the refined invariants file", EXIT_USAGE)
    # both outputs are checked before either is written
    _report_target("classify", report_path, force, (*inputs, *filter(None, [refined_path])))
    if result.refined is not None and refined_path is not None:
        try:
            write_files(
                refined_path.parent,
                {refined_path.name: dumps(result.refined).encode()},
                force=force,
                kind=INVARIANTS,
                inputs=inputs,
            )
        except OutputRefusedError as refused:
            fail("classify", str(refused), EXIT_USAGE)
        kept = len(result.refined["invariants"])
        click.echo(f"wrote {refined_path}: kept {kept} of {len(result.report['scores'])}", err=True)
    _emit("classify", result.report, output_format, report_path, force, inputs)
    errors = has_errors(result.diagnostics) or bool(result.report.get("errors"))
    unchecked = bool(result.report.get("unchecked")) or any(
        run.get("unchecked") for run in result.report.get("runs", ())
    )
    sys.exit(EXIT_ERRORS if errors else EXIT_UNCHECKED if unchecked else EXIT_CLEAN)


@main.command()
@click.argument("config", type=click.Path(dir_okay=False, path_type=Path))
@click.option(
    "--folds",
    type=click.IntRange(min=2),
    help="Number of folds [default: one per bag, i.e. leave-one-out].",
)
@click.option("-j", "--jobs", type=click.IntRange(min=1), help="Worker processes [default: cores].")
@bags_option
@format_option
@report_option
@click.option("--force", is_flag=True, help="Overwrite a report file imrosc did not write.")
@scheduler_option
@quiet_option
def stability(
    config: Path,
    folds: int | None,
    jobs: int | None,
    bags: tuple[Path, ...],
    output_format: str,
    report_path: Path | None,
    force: bool,
    scheduler: str | None,
    quiet: bool,
) -> None:
    """Cross-validate inference over CONFIG's <detect> bags: how many invariants learnt from
    the other bags does each held-out bag violate (per family)? With --scheduler, each bag
    is a task on a Dask cluster (docs/fleet.md)."""
    from imrosc.classify import CheckStageError
    from imrosc.stability import run_stability

    _report_target("stability", report_path, force, (config, *bags))
    inputs: list[Path] = [config, *bags]

    def before_work(found: Sequence[Path]) -> None:
        """Refuse the report path once the bags are known (a <detect> bag is an input)."""
        inputs.extend(found)
        _report_target("stability", report_path, force, inputs)

    try:
        with (
            cluster("stability", scheduler) as fleet,
            bag_progress("cross-validating", quiet) as factory,
        ):
            report, problems = run_stability(
                config,
                folds=folds,
                workers=jobs,
                bags=list(bags) or None,
                progress_factory=factory,
                cluster=fleet,
                before_work=before_work,
            )
    except CheckStageError as error:
        fail("stability", str(error), EXIT_USAGE)
    _report(problems, "text")
    if report is None:
        if _none_read(inputs[1 + len(bags) :], problems):  # the <detect> bags it found
            fail("stability", "no bag could be read: nothing cross-validated", EXIT_USAGE)
        errors = [d for d in problems if d.severity is Severity.ERROR]
        if errors and all(d.code == "bag-error" for d in errors):
            fail(
                "stability",
                "no round both trained on a bag it could read and checked one: nothing "
                "cross-validated",
                EXIT_ERRORS,
            )
        sys.exit(_stopped(problems))
    _emit("stability", report, output_format, report_path, force, inputs)
    sys.exit(EXIT_ERRORS if has_errors(problems) else EXIT_CLEAN)


from imrosc.record.command import record  # noqa: E402  (imports nothing heavy)

main.add_command(record)
