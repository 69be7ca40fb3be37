"""``imrosc record``: record a configuration's scope from a running ROS 1 or ROS 2 system."""

from __future__ import annotations

import contextlib
import os
import signal
import sys
import threading
from collections.abc import Callable, Iterator, Mapping
from pathlib import Path
from types import FrameType
from typing import TYPE_CHECKING, NoReturn, Protocol

import click

from imrosc.diagnostics import Diagnostic, render_text
from imrosc.graph.model import Graph

if TYPE_CHECKING:
    from imrosc.record.master import SystemState
    from imrosc.record.scope import CompiledScope, Scope
    from imrosc.record.session import Outcome

EXIT_CLEAN, EXIT_ERRORS, EXIT_USAGE, EXIT_ENVIRONMENT = 0, 1, 2, 4
"""As every command (README, "Exit status"): 2 an input or an output refused, 4 the
system refused a write."""
PYTHON_VARIABLE = "IMROSC_ROS_PYTHON"
ROS2_VARIABLE = "IMROSC_ROS2_PYTHON"
HELP = """Record CONFIG's scope from the running ROS 1 or ROS 2 system.

\b
ROS 1 (the default) records into OUTPUT/NAME.bag; ROS 2 (--ros2, or ROS_VERSION=2
as a sourced ROS 2 setup sets it) into the MCAP bag OUTPUT/NAME/ (see ROS 2 below).

\b
Starts 'rosbag record' on the topics of the scope (publish points, their input
topics, condition topics) and imrosc's recording node, which publishes the
node graph (/imrosc/arch) and the parameters (/imrosc/params) at start and on
every change, and relays the services of the <call> points, publishing every
call (/imrosc/srvs). 'imrosc infer' reads all of it back from the bag.

\b
Relaying a service needs its server to serve it as /rec/SERVICE instead; the
recording node then offers SERVICE itself and forwards. In the launch file, add
to the server's <node> (and only there: clients keep calling SERVICE):
    <remap from="/a/execute_task" to="/rec/a/execute_task"/>
--launch FILE writes such a copy of FILE (FILE is never modified). A node
started by hand takes '/a/execute_task:=/rec/a/execute_task' instead. Without
the remap the calls are not recorded (imrosc says so); the rest still is.

\b
Recording stops after --duration seconds or on Ctrl-C (SIGINT) or SIGTERM:
the recording node first (calls in flight are answered and recorded), then
rosbag, which closes and indexes the bag. Exit status: 0 when the bag was
written, 1 otherwise.

\b
ROS 2: a bag tap (an rclpy node under the ROS 2 Python: --python, else
$IMROSC_ROS2_PYTHON, else this Python if it has rclpy) subscribes to the
scope's topics with the publishers' QoS and hands every message to imrosc,
which writes it into the MCAP bag at once; imrosc's ROS 2 recorder node
publishes the graph, the parameters and the service calls, which it learns
from service introspection (no remap: enable introspection with contents on
the servers or clients). Ctrl-C stops the recorder, then the tap, and imrosc
closes the bag: every message received is in it. --launch, --server and
--all-params are ROS 1 only.
"""


def _ros_python() -> str:
    return os.environ.get(PYTHON_VARIABLE) or "/usr/bin/python3"


def wants_ros2(ros1: bool | None, environment: Mapping[str, str]) -> bool:
    """Whether to record on ROS 2: ``--ros1`` (True) or ``--ros2`` (False) if given, else
    ``ROS_VERSION`` (which a sourced ROS setup sets), else ROS 1.

    >>> wants_ros2(None, {"ROS_VERSION": "2"}), wants_ros2(True, {"ROS_VERSION": "2"})
    (True, False)
    >>> wants_ros2(None, {}), wants_ros2(False, {})
    (False, True)
    """
    if ros1 is not None:
        return not ros1
    return environment.get("ROS_VERSION", "").strip() == "2"


def _fail(message: str, status: int = EXIT_ERRORS) -> NoReturn:
    click.echo(f"imrosc record: {message}", err=True)
    sys.exit(status)


def _warn(message: str) -> None:
    click.echo(f"imrosc record: warning: {message}", err=True)


class _Session(Protocol):
    def run(self, stop: threading.Event, duration: float | None) -> None: ...
    def finish(self) -> Outcome: ...


def drive(
    session: _Session,
    start: Callable[[threading.Event], bool],
    heading: Callable[[str], str],
    duration: float | None,
) -> tuple[Outcome, str | None]:
    """A recording on either middleware, until ``duration`` or Ctrl-C: ``start`` it, print
    ``heading(how long)``, run it and finish it; its outcome and what failed while it ran
    (the bag then holds what was recorded until then). A failure to finish ends the command."""
    from imrosc.record.session import RecordError

    failure: str | None = None
    with stop_on_signals() as stop:
        try:
            if start(stop):
                click.echo(heading(f"for {duration:g} s" if duration else "until Ctrl-C"))
                session.run(stop, duration)
        except RecordError as error:
            failure = str(error)
        try:
            outcome = session.finish()
        except RecordError as error:
            _fail(f"{failure}; {error}" if failure else str(error))
    return outcome, failure


@contextlib.contextmanager
def stop_on_signals() -> Iterator[threading.Event]:
    """An event set by SIGINT or SIGTERM (imrosc's handlers while the block runs)."""
    stop = threading.Event()
    previous = {number: signal.getsignal(number) for number in (signal.SIGINT, signal.SIGTERM)}

    def on_signal(number: int, frame: FrameType | None) -> None:
        if not stop.is_set():
            click.echo("stopping...", err=True)
        stop.set()

    for number in previous:
        signal.signal(number, on_signal)
    try:
        yield stop
    finally:
        for number, handler in previous.items():
            signal.signal(number, handler)


def _scope(config: Path, graph: Graph | None, name: str | None) -> tuple[Scope, CompiledScope, str]:
    """The configuration's scope (compiled with ``graph``) and the bag's name (``name``, else
    the project's, made a file name); a configuration with errors or nothing to record ends
    the command (on either middleware)."""
    from imrosc.record.scope import compile_scope

    compiled = compile_scope(config, graph)
    _report(compiled.diagnostics)
    if compiled.scope is None or compiled.project is None:
        unreadable = any(d.code == "io-error" for d in compiled.diagnostics)
        sys.exit(EXIT_USAGE if unreadable else EXIT_ERRORS)
    scope, project = compiled.scope, compiled.project
    if scope.empty:
        _fail(f"{config}: the scope has nothing to record (no <publish>, <call>, <param>, <arch>)")
    bag_name = name or "".join(c if c.isalnum() or c in "-_." else "_" for c in project.name)
    return scope, compiled, bag_name


def _report(diagnostics: list[Diagnostic]) -> None:
    if diagnostics:
        click.echo(render_text(diagnostics, 1), nl=False, err=True)


def _existing_bags(folder: Path) -> list[Path]:
    if not folder.is_dir():
        return []
    return sorted(
        p for p in folder.iterdir() if p.name.endswith((".bag", ".bag.active")) and p.is_file()
    )


def _refuse_full(output: Path, existing: list[Path], force: bool) -> None:
    """Refuse an output folder that holds bags already (``existing``) unless ``force``."""
    if existing and not force:
        _fail(
            f"{output} holds a bag already ({existing[0].name}): record into a new folder, "
            f"or use --force",
            EXIT_USAGE,
        )


def _parse_servers(values: tuple[str, ...]) -> dict[str, set[str]]:
    from imrosc.schema.names import resolve_name

    servers: dict[str, set[str]] = {}
    for value in values:
        service, sep, node = value.partition("=")
        if not sep or not service.strip() or not node.strip():
            raise click.BadParameter(f"{value!r} is not SERVICE=NODE", param_hint="--server")
        servers.setdefault(resolve_name(service.strip()), set()).add(resolve_name(node.strip()))
    return servers


def _launch_servers(
    services: tuple[str, ...],
    given: Mapping[str, set[str]],
    graph: Graph | None,
    prefix: str,
) -> tuple[dict[str, set[str]], list[str]]:
    """The server nodes of each service: given by --server, else what the graph (files and
    master) says serves the service or its ``/rec/`` name; the services nobody serves."""
    found: dict[str, set[str]] = {}
    unknown = []
    for service in services:
        nodes = set(given.get(service, ()))
        if not nodes and graph is not None:
            relayed = f"{prefix}{service}"
            nodes = {
                n.name for n in graph.nodes.values() if service in n.serves or relayed in n.serves
            }
            nodes = {n for n in nodes if not n.startswith("/imrosc_")}
        if nodes:
            found[service] = nodes
        else:
            unknown.append(service)
    return found, unknown


def _write_launch(
    launch: Path,
    launch_out: Path | None,
    services: tuple[str, ...],
    servers: Mapping[str, set[str]],
    graph: Graph | None,
    prefix: str,
    force: bool,
    inputs: tuple[Path, ...],
) -> None:
    """Write the copy of ``launch`` whose servers serve under ``prefix``: never over one of
    the command's ``inputs`` (the launch file itself, the configuration, graph files) nor
    an imrosc file of another kind, nor a file imrosc did not write unless ``force``."""
    from imrosc.build import OverwriteRefusedError, write_files
    from imrosc.outputs import LAUNCH, mark
    from imrosc.record.launch import record_launch_name, rewrite_for_recording

    if not services:
        _warn(f"--launch {launch}: the scope has no <call>, so there is no server to remap")
        return
    found, unknown = _launch_servers(services, servers, graph, prefix)
    if unknown:
        _fail(
            f"--launch: no graph says which node serves {', '.join(unknown)}; pass "
            f"--server SERVICE=NODE, or --graph FILE, or run the system while imrosc record starts"
        )
    target = launch_out or record_launch_name(launch)
    banner = (
        f"{mark(LAUNCH)} (imrosc record) from {launch.name}: the servers of "
        f"the recorded services serve them under {prefix}/ for the recording node to relay"
    )
    rewritten = rewrite_for_recording(launch, found, prefix=prefix, banner=banner)
    _report(rewritten.diagnostics)
    if rewritten.content is None:  # a launch file that cannot be read: an input error
        sys.exit(
            EXIT_USAGE if any(d.code == "io-error" for d in rewritten.diagnostics) else EXIT_ERRORS
        )
    for service, node in rewritten.missing:
        _warn(f"{launch}: no <node> {node} (the server of {service}) to remap; remap it by hand")
    try:
        write_files(
            target.parent,
            {target.name: rewritten.content},
            force=force,
            kind=LAUNCH,
            inputs=(launch, *inputs),
        )
    except OverwriteRefusedError as refused:
        _fail(str(refused), EXIT_USAGE)
    except OSError as error:
        _fail(f"{target}: {error.strerror}", EXIT_ENVIRONMENT)
    done = ", ".join(f"{service} on {node}" for node, service in rewritten.remapped) or "nothing"
    click.echo(f"wrote {target}: remapped {done}")
    click.echo(f"start the system with: roslaunch {target}")


@click.command("record", help=HELP)
@click.argument("config", type=click.Path(dir_okay=False, path_type=Path))
@click.option(
    "-o",
    "--output",
    required=True,
    type=click.Path(file_okay=False, path_type=Path),
    help="Folder of the bag (created if missing).",
)
@click.option("--name", help="Name of the bag (ROS 1: without .bag) [default: the project's name].")
@click.option(
    "--duration",
    type=click.FloatRange(min=0, min_open=True),
    help="Seconds to record [default: until Ctrl-C].",
)
@click.option(
    "--period",
    type=click.FloatRange(min=0, min_open=True),
    default=1.0,
    show_default=True,
    help="Seconds between two looks at the graph (architecture and parameters).",
)
@click.option(
    "--all",
    "all_topics",
    is_flag=True,
    help="Record every topic (rosbag record -a; ROS 2: every topic that is not hidden).",
)
@click.option(
    "--all-params", is_flag=True, help="Record every parameter, not only the scope's (ROS 1)."
)
@click.option(
    "--graph",
    "graph_files",
    multiple=True,
    type=click.Path(dir_okay=False, path_type=Path),
    help="A graph file, for relative topics and --launch when the master does not know yet.",
)
@click.option(
    "--launch",
    type=click.Path(dir_okay=False, path_type=Path),
    help="The system's roslaunch file: write a copy with the servers remapped to /rec/.",
)
@click.option(
    "--launch-out",
    type=click.Path(dir_okay=False, path_type=Path),
    help="Where --launch writes the copy [default: beside it, as NAME.record.launch].",
)
@click.option(
    "--server",
    "servers",
    multiple=True,
    metavar="SERVICE=NODE",
    help="The node that serves SERVICE, for --launch (repeatable).",
)
@click.option(
    "--ros1/--ros2",
    "ros1",
    default=None,
    help="The middleware [default: ROS 2 when ROS_VERSION=2, else ROS 1].",
)
@click.option(
    "--python",
    help=(
        "The Python that has rospy (ROS 1) or rclpy (ROS 2); the recording nodes run under it "
        f"[default: ROS 1: ${PYTHON_VARIABLE} or /usr/bin/python3; ROS 2: ${ROS2_VARIABLE}, "
        "or this Python if it has rclpy]."
    ),
)
@click.option(
    "--force",
    is_flag=True,
    help="Record into a folder that holds a bag already; overwrite a --launch copy.",
)
def record(
    config: Path,
    output: Path,
    name: str | None,
    duration: float | None,
    period: float,
    all_topics: bool,
    all_params: bool,
    graph_files: tuple[Path, ...],
    launch: Path | None,
    launch_out: Path | None,
    servers: tuple[str, ...],
    ros1: bool | None,
    python: str | None,
    force: bool,
) -> None:
    if name is not None and (not name or "/" in name or name.startswith(".")):
        raise click.BadParameter(f"{name!r} is not a file name", param_hint="--name")
    if wants_ros2(ros1, os.environ):
        ros1_only = {
            "--launch": launch is not None,
            "--launch-out": launch_out is not None,
            "--server": bool(servers),
            "--all-params": all_params,
        }
        for option, value in ros1_only.items():
            if value:
                raise click.UsageError(
                    f"{option} is for ROS 1 only (ROS 2 records calls "
                    "from service introspection, and the scope's parameters)"
                )
        from imrosc.record.command_ros2 import record_ros2

        record_ros2(config, output, name, duration, period, all_topics, graph_files, python, force)
        return
    _record_ros1(
        config,
        output,
        name,
        duration,
        period,
        all_topics,
        all_params,
        graph_files,
        launch,
        launch_out,
        servers,
        python or _ros_python(),
        force,
    )


def _record_ros1(
    config: Path,
    output: Path,
    name: str | None,
    duration: float | None,
    period: float,
    all_topics: bool,
    all_params: bool,
    graph_files: tuple[Path, ...],
    launch: Path | None,
    launch_out: Path | None,
    servers: tuple[str, ...],
    python: str,
    force: bool,
) -> None:
    from imrosc.build import load_graph
    from imrosc.record.master import MasterError, master_uri, system_state
    from imrosc.record.session import (
        RecordError,
        Recording,
        Settings,
        child_environment,
        find_rosbag_record,
    )

    given = _parse_servers(servers)
    if launch is not None:
        try:
            launch.open("rb").close()
        except OSError as error:  # before the servers, which the file itself cannot tell
            _fail(f"--launch {launch}: cannot read it: {error.strerror}", EXIT_USAGE)
    uri = master_uri()
    state = None
    master_problem = None
    try:
        state = system_state(uri)
    except MasterError as error:
        master_problem = str(error)
    graph, problems = load_graph(graph_files, ())
    _report(problems)
    if state is not None:
        live = state.graph(hidden={n for n in _all_nodes(state) if n.startswith("/imrosc_")})
        graph = live if graph is None else Graph.merge(graph, live)
    scope, compiled, bag_name = _scope(config, graph, name)
    if output.exists() and not output.is_dir():
        _fail(f"{output}: exists and is not a folder", EXIT_USAGE)
    existing = _existing_bags(output)
    _refuse_full(output, existing, force)
    if launch is not None:
        _write_launch(
            launch, launch_out, scope.services, given, graph, "/rec", force, (config, *graph_files)
        )
    if master_problem is not None:
        _fail(master_problem)
    if not all_topics:
        for warning in compiled.warnings:
            _warn(warning)
    env = child_environment(os.environ, uri)
    settings = Settings(output, bag_name, period, all_topics, all_params, python)
    try:
        program = find_rosbag_record(python, env)
        output.mkdir(parents=True, exist_ok=True)
    except RecordError as error:
        _fail(str(error))
    except OSError as error:
        _fail(f"{output}: {error.strerror}", EXIT_ENVIRONMENT)
    for stale in (settings.bag, settings.bag.with_name(settings.bag.name + ".active")):
        if stale.exists():
            stale.unlink()
    session = Recording(scope, settings, env, uri, say=click.echo, warn=_warn)
    outcome, failure = drive(
        session,
        lambda stop: session.start(program, stop),
        lambda length: f"recording {scope.describe()} into {settings.bag} {length}",
        duration,
    )
    _summary(outcome, scope.topics if not all_topics else (), scope.services)
    if failure is not None:
        _fail(failure)  # the bag holds what was recorded until then
    sys.exit(EXIT_CLEAN)


def _all_nodes(state: SystemState) -> set[str]:
    found: set[str] = set()
    for table in (state.publishers, state.subscribers, state.services):
        for nodes in table.values():
            found |= nodes
    return found


def _summary(
    outcome: Outcome, topics: tuple[str, ...], services: tuple[str, ...], ros2: bool = False
) -> None:
    from imrosc import records

    counts = outcome.messages
    total = sum(counts.values())
    calls = counts.get(records.SRVS_TOPIC, 0)
    arch = counts.get(records.ARCH_TOPIC, 0)
    params = counts.get(records.PARAMS_TOPIC, 0)
    robot = sum(1 for t in counts if not t.startswith(records.RECORD_PREFIX))
    click.echo(
        f"wrote {outcome.bag}: {total} messages in {outcome.seconds:.1f} s: {robot} "
        f"topic{'s' * (robot != 1)}, {calls} service call{'s' * (calls != 1)}, {arch} "
        f"architecture and {params} parameter snapshot{'s' * (params != 1)}"
    )
    for topic in topics:
        if not counts.get(topic):
            _warn(f"no message on {topic} was recorded")
    for service in services:
        if outcome.calls.get(service):
            continue
        if ros2:
            _warn(
                f"no call of {service} was recorded: are there calls, and does its server or "
                f"client enable service introspection (see docs/record.md)?"
            )
        elif service in outcome.relayed:
            _warn(f"no call of {service} was recorded")
        else:
            _warn(
                f"no call of {service} was recorded: no node served /rec{service}; remap its "
                f"server (see imrosc record --help)"
            )
    for topic, published in sorted(outcome.published.items()):
        stored = counts.get(topic, 0)
        if stored < published:
            _warn(f"{published - stored} of {published} records on {topic} are not in the bag")
