"""``imrosc infer --scheduler`` on a LocalCluster of two worker processes (loopback): the same
invariants file as ``-j 1`` byte for byte, bad bags reported as in one process, workers killed
mid-run, and a scheduler that cannot be used."""

from __future__ import annotations

import copy
import importlib
import shutil
import socket
import sys
import tempfile
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import pytest
from click.testing import CliRunner, Result
from hypothesis import given, settings
from hypothesis import strategies as st

from imrosc.calibrate.envelope import FoldDocument
from imrosc.calibrate.rule import HeldOut, Job, built
from imrosc.calibrate.rule import _replay as held_out_here
from imrosc.cli import main
from imrosc.demo import example_configs
from imrosc.detect import prepare, run_detect
from imrosc.fleet import Fleet
from imrosc.fleet import cluster as fleet_cluster
from imrosc.infer.engine import infer
from imrosc.invariants import dumps
from imrosc.sim import write_run
from tests.fleet.tasks import POISON, kill_always, kill_once, marker

distributed: Any = importlib.import_module("distributed")  # the [test] extra installs Dask
dask: Any = importlib.import_module("dask")

pytestmark = pytest.mark.slow

RUNS = 6


@pytest.fixture(scope="module")
def project(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The simulated landing system's configuration and short runs of it: ROS 1 bags and
    one MCAP bag, of different lengths (every family, conditions found in the data)."""
    base = tmp_path_factory.mktemp("fleet")
    config = next(p for p in example_configs() if p.name == "landing_sim.xml")
    shutil.copyfile(config, base / config.name)
    for run in range(RUNS):
        name = f"r{run}" if run == 3 else f"r{run}.bag"
        write_run(
            base / "runs" / name,
            seed=40 + run,
            fmt="mcap" if run == 3 else "ros1",
            duration=2.0 + 0.5 * run,
        )
    return base / config.name


def runs(project: Path) -> list[Path]:
    """The runs (not the marks of the workers killed reading them)."""
    return sorted(p for p in (project.parent / "runs").iterdir() if p.name.startswith("r"))


def infer_cli(project: Path, bags: list[Path], output: Path, *options: str) -> Result:
    arguments = ["infer", str(project), "-q", "-o", str(output), *options]
    for bag in bags:
        arguments += ["--bags", str(bag)]
    return CliRunner().invoke(main, arguments)


def shown(result: Result) -> list[str]:
    """What ``infer`` printed, less its timing, the cluster's address and the output."""
    return [
        line.split(": ", 1)[1] if line.startswith("wrote ") else line
        for line in result.output.splitlines()
        if not line.startswith(("from ", "on the Dask cluster"))
    ]


_reference: dict[tuple[str, ...], bytes] = {}


@settings(max_examples=4, deadline=None)
@given(data=st.data())
def test_the_invariants_file_is_the_one_of_one_process_byte_for_byte(
    project: Path, address: str, data: st.DataObject
) -> None:
    every = runs(project)
    chosen = data.draw(
        st.lists(st.sampled_from(every), min_size=1, max_size=len(every), unique=True), "bags"
    )
    with tempfile.TemporaryDirectory() as folder:
        key = tuple(sorted(str(b) for b in chosen))
        if key not in _reference:
            alone = infer_cli(project, chosen, Path(folder) / "one.inv", "-j", "1")
            assert alone.exit_code == 0, alone.output
            _reference[key] = (Path(folder) / "one.inv").read_bytes()
        fleet = infer_cli(project, chosen, Path(folder) / "fleet.inv", "--scheduler", address)
        assert fleet.exit_code == 0, fleet.output
        assert f"on the Dask cluster at {address}" in fleet.output
        assert (Path(folder) / "fleet.inv").read_bytes() == _reference[key]


def test_bad_bags_are_reported_and_skipped_as_in_one_process(
    project: Path, address: str, tmp_path: Path
) -> None:
    bags = tmp_path / "bags"
    bags.mkdir()
    for run in runs(project):
        (shutil.copytree if run.is_dir() else shutil.copyfile)(run, bags / run.name)
    (bags / "notes.bag").write_text("not a bag\n")
    whole = (bags / "r1.bag").read_bytes()
    (bags / "truncated.bag").write_bytes(whole[:3000])
    alone = infer_cli(project, [bags], tmp_path / "one.inv", "-j", "1")
    fleet = infer_cli(project, [bags], tmp_path / "fleet.inv", "--scheduler", address)
    assert alone.exit_code == fleet.exit_code == 1
    assert f"{bags / 'notes.bag'}:1:1: error:" in fleet.output
    assert shown(fleet) == shown(alone)
    assert (tmp_path / "fleet.inv").read_bytes() == (tmp_path / "one.inv").read_bytes()


def test_a_bag_the_workers_cannot_read_is_a_failed_bag_as_in_one_process(
    project: Path, client: Any, address: str
) -> None:
    prepared, _ = prepare(project, bags=runs(project))
    assert prepared is not None
    catalog = prepared.catalog
    bags = [*catalog.bags[:3], project.parent / "runs" / "gone.bag"]
    arguments = (bags, prepared.specs, prepared.layouts, catalog.callerids)
    tunables = prepared.project.detect.tunables if prepared.project.detect else None
    assert tunables is not None
    alone = infer(*arguments, tunables, workers=1, calibrate=True)
    fleet = infer(*arguments, tunables, calibrate=True, reducer=Fleet(client, address))
    assert list(fleet.failed) == list(alone.failed) == [bags[-1]]
    assert fleet.failed == alone.failed
    assert (fleet.messages, fleet.empty) == (alone.messages, alone.empty)
    assert repr(fleet.invariants(tunables)) == repr(alone.invariants(tunables))
    assert [(u.bag, u.span, repr(u.invariants)) for u in fleet.units] == [
        (u.bag, u.span, repr(u.invariants)) for u in alone.units
    ]


def test_a_worker_killed_mid_task_gives_the_same_invariants(
    project: Path, client: Any, address: str
) -> None:
    bags = runs(project)
    alone = run_detect(project, workers=1, bags=bags)
    cluster = Fleet(client, address, task=kill_once)
    fleet = run_detect(project, bags=bags, reducer=cluster, replays=cluster.replay_held_out)
    assert marker(bags[1].absolute()).exists(), "no worker was killed"
    assert fleet.document is not None and alone.document is not None
    assert dumps(fleet.document) == dumps(alone.document)
    assert fleet.diagnostics == alone.diagnostics


def test_the_folds_documents_built_on_the_workers_replay_as_in_one_process(
    project: Path, client: Any, address: str
) -> None:
    """Calibration sends the envelopes once and each fold's document is built on a worker
    (:class:`~imrosc.calibrate.envelope.FoldDocument`); a document given as it is (``classify``'s
    rule) is sent sealed from Dask's walk of its arguments. Both give every held-out unit
    as the folds' documents built and replayed in this process do."""
    cluster = Fleet(client, address)
    seen: list[tuple[list[Any], list[Any], list[Any]]] = []

    def replays(jobs: Sequence[Job]) -> list[list[HeldOut]]:
        assert all(isinstance(learnt, FoldDocument) for learnt, _, _ in jobs)
        built_here = [(built(learnt), bags, fold) for learnt, bags, fold in jobs]
        on_workers = cluster.replay_held_out(jobs)
        sent = cluster.replay_held_out(built_here)
        here = [held_out_here(job) for job in built_here]
        seen.append((copy.deepcopy(on_workers), sent, here))  # calibration settles them after
        return on_workers

    result = run_detect(project, bags=runs(project), reducer=cluster, replays=replays)
    assert result.calibration is not None
    [(on_workers, sent, here)] = seen
    assert len(on_workers) > 1 and any(on_workers)
    assert on_workers == sent == here


def test_a_bag_that_kills_every_worker_is_reported_and_skipped(
    project: Path, client: Any, address: str, tmp_path: Path
) -> None:
    good = runs(project)[:3]
    poisoned = tmp_path / f"{POISON}.bag"
    shutil.copyfile(good[0], poisoned)
    # without calibration: with a fourth bag, good or bad, the runs are its units, with
    # three the runs' halves
    alone = run_detect(project, workers=1, bags=good, budget=0.0)
    fleet = run_detect(
        project,
        bags=[*good, poisoned],
        reducer=Fleet(client, address, task=kill_always),
        budget=0.0,
    )
    errors = [d for d in fleet.diagnostics if d.code == "bag-error"]
    assert [d.path for d in errors] == [str(poisoned)]
    assert "Dask workers died while reading it, on every try" in errors[0].message
    assert fleet.document is not None and alone.document is not None
    assert dumps(fleet.document) == dumps(alone.document)


def _free_port() -> int:
    with socket.socket() as probe:
        probe.bind(("127.0.0.1", 0))
        port: int = probe.getsockname()[1]
        return port


def test_a_scheduler_out_of_reach_is_one_line_and_a_usage_error(
    project: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setattr(fleet_cluster, "CONNECT_TIMEOUT", 1.0)
    unreachable = f"tcp://127.0.0.1:{_free_port()}"
    arguments = ["infer", str(project), "-q", "-o", str(tmp_path / "x.inv")]
    result = CliRunner().invoke(main, arguments, env={"IMROSC_SCHEDULER": unreachable})
    assert result.exit_code == 2
    assert result.output.startswith(f"imrosc infer: {unreachable}: cannot reach the Dask sched")
    assert len(result.output.splitlines()) == 1
    wrong = CliRunner().invoke(main, [*arguments, "--scheduler", "nonsense://x"])
    assert wrong.exit_code == 2
    assert "nonsense://x: not a Dask scheduler address" in wrong.output
    assert not (tmp_path / "x.inv").exists()


def test_without_dask_the_scheduler_option_says_what_to_install(
    project: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setitem(sys.modules, "distributed", None)
    arguments = ["infer", str(project), "-q", "-o", str(tmp_path / "x.inv")]
    result = CliRunner().invoke(main, [*arguments, "--scheduler", "tcp://127.0.0.1:8786"])
    assert result.exit_code == 2
    assert result.output == (
        "imrosc infer: --scheduler needs Dask (dask and distributed): pip install 'imrosc[fleet]'\n"
    )


def test_replay_on_the_cluster_reports_what_one_process_reports(
    project: Path, address: str, tmp_path: Path
) -> None:
    bags = runs(project)
    inv = tmp_path / "some.inv"
    assert infer_cli(project, bags[:3], inv, "-j", "1").exit_code == 0
    (tmp_path / "notes.bag").write_text("not a bag\n")
    arguments = ["replay", str(inv), *map(str, bags), str(tmp_path / "notes.bag"), "--json", "-q"]
    alone = CliRunner().invoke(main, arguments)
    fleet = CliRunner().invoke(main, [*arguments, "--scheduler", address])
    assert alone.exit_code == fleet.exit_code == 1  # the bag that is not one
    assert fleet.stdout == alone.stdout
    assert '"error": null' in fleet.stdout
