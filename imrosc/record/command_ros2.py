"""``imrosc record --ros2``: record a configuration's scope from a running ROS 2 system into
an MCAP bag (``OUTPUT/NAME/``), with the session of :mod:`imrosc.record.session_ros2`."""

from __future__ import annotations

import os
import shutil
import sys
from pathlib import Path

import click

from imrosc.bags import ROS2_METADATA, ROS2_STORAGE_SUFFIXES
from imrosc.graph.model import Graph
from imrosc.record.command import (
    EXIT_CLEAN,
    EXIT_ENVIRONMENT,
    EXIT_USAGE,
    _existing_bags,
    _fail,
    _refuse_full,
    _report,
    _scope,
    _summary,
    _warn,
    drive,
)

__all__ = ["record_ros2"]

GRAPH_SOURCE = "ros2 graph"


def is_ros2_bag(folder: Path) -> bool:
    """Whether ``folder`` is a ROS 2 bag, or what is left of one (storage files without
    ``metadata.yaml``: a recording that was killed)."""
    if not folder.is_dir():
        return False
    names = list(folder.iterdir())
    if any(p.name == ROS2_METADATA for p in names):
        return True
    return bool(names) and all(p.suffix in ROS2_STORAGE_SUFFIXES for p in names)


def existing_ros2_bags(folder: Path) -> list[Path]:
    """The bags in ``folder``: ROS 1 files and ROS 2 bag folders."""
    found = _existing_bags(folder)
    if folder.is_dir():
        found += sorted(
            p for p in folder.iterdir() if not p.name.startswith(".") and is_ros2_bag(p)
        )
    return found


def _check_output(output: Path, bag: Path, force: bool) -> None:
    """Refuse an output folder that is a file or holds a bag already (unless ``force``);
    with ``force``, the bag of the same name is removed (nothing else is)."""
    if output.exists() and not output.is_dir():
        _fail(f"{output}: exists and is not a folder", EXIT_USAGE)
    if bag.is_symlink() or (bag.exists() and not is_ros2_bag(bag)):
        _fail(f"{bag}: exists and is not a ROS 2 bag; choose another --name", EXIT_USAGE)
    existing = existing_ros2_bags(output)
    _refuse_full(output, existing, force)
    if bag.exists():
        try:
            shutil.rmtree(bag)
        except OSError as error:
            _fail(f"{bag}: cannot remove the old bag: {error.strerror}", EXIT_ENVIRONMENT)


def record_ros2(
    config: Path,
    output: Path,
    name: str | None,
    duration: float | None,
    period: float,
    all_topics: bool,
    graph_files: tuple[Path, ...],
    python: str | None,
    force: bool,
) -> None:
    """The ROS 2 recording of ``imrosc record`` (the options as the command has them)."""
    from imrosc import records
    from imrosc.build import load_graph
    from imrosc.record.scope import Scope, compile_scope
    from imrosc.record.session import RecordError
    from imrosc.record.session_ros2 import (
        Settings2,
        TapRecording,
        check_python,
        choose_python,
    )

    files, problems = load_graph(graph_files, ())
    _report(problems)
    scope, _, bag_name = _scope(config, files, name)
    _check_output(output, output / bag_name, force)
    try:
        interpreter = choose_python(python, os.environ)
        check_python(interpreter, os.environ)
        output.mkdir(parents=True, exist_ok=True)
    except RecordError as error:
        _fail(str(error))
    except OSError as error:
        _fail(f"{output}: {error.strerror}", EXIT_ENVIRONMENT)
    settings = Settings2(output, bag_name, period, all_topics, interpreter)
    final: list[Scope] = [scope]
    warned: list[bool] = []

    def choose(arch: str) -> tuple[str, ...]:
        """The scope's topics with the graph the tap saw (relative inputs); the warnings
        of the graph the recording starts with."""
        graph = files
        try:
            live = Graph.from_snapshot(records.decode_arch(arch), GRAPH_SOURCE)
            graph = live if graph is None else Graph.merge(graph, live)
        except records.RecordError as error:
            _warn(f"the ROS 2 graph cannot be read ({error}); recording without it")
        again = compile_scope(config, graph)
        if again.scope is not None:
            final[0] = again.scope
        if not all_topics and not warned:
            warned.append(True)
            for warning in again.warnings:
                _warn(warning)
        return final[0].topics

    session = TapRecording(scope, settings, os.environ, choose, say=click.echo, warn=_warn)
    outcome, failure = drive(
        session,
        session.start,
        lambda length: (
            f"recording {final[0].describe()} into {settings.bag} (ROS 2, MCAP) {length}"
        ),
        duration,
    )
    _summary(outcome, final[0].topics if not all_topics else (), scope.services, ros2=True)
    if failure is not None:
        _fail(failure)  # the bag holds what was recorded until then
    sys.exit(EXIT_CLEAN)
