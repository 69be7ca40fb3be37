"""``imrosc classify`` and ``imrosc stability`` with ``--scheduler`` on the shared LocalCluster:
each run a task, the reports and the refined file byte for byte those of one process, bad
bags reported as in one process, a worker killed mid-run."""

from __future__ import annotations

import shutil
from pathlib import Path
from typing import Any

import pytest
from click.testing import CliRunner, Result

from imrosc.classify import observe_runs
from imrosc.cli import main
from imrosc.fleet import Fleet
from imrosc.invariants import load
from tests.fleet.tasks import VICTIM, kill_once_observing, marker
from tests.translate import good_run

pytestmark = pytest.mark.slow

CONFIG = """<imROS project="p">
  <scope>
    <publish id="a"><topic>/out</topic><topic>/in</topic></publish>
  </scope>
  <detect inv="p.inv" budget="0.2"><bag>bags/train</bag></detect>
  <check inv="p.inv">
    <success>bags/ok</success>
    <success>bags/train/r2.bag</success>
    <fail onset="1.5">bags/bad</fail>
  </check>
</imROS>
"""


@pytest.fixture(scope="module")
def project(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A configuration, its training, successful and failed runs (one failed bag truncated,
    a file that is not a bag among the successful ones) and the invariants learnt."""
    folder = tmp_path_factory.mktemp("checked")
    (folder / "p.xml").write_text(CONFIG)
    for name in ("train", "ok", "bad"):
        (folder / "bags" / name).mkdir(parents=True)
    for run in range(4):
        good_run(folder / "bags" / "train" / f"r{run}.bag", 10.0 * run)
    good_run(folder / "bags" / "ok" / "s1.bag", 50.0)
    good_run(folder / "bags" / "ok" / "s2.bag", 60.0)
    good_run(folder / "bags" / "bad" / "f1.bag", 70.0, odd=True)
    whole = (folder / "bags" / "bad" / "f1.bag").read_bytes()
    (folder / "bags" / "bad" / "f2.bag").write_bytes(whole[:600])
    (folder / "bags" / "ok" / "notes.bag").write_text("not a bag\n")
    done = CliRunner().invoke(main, ["infer", str(folder / "p.xml"), "-j", "1", "-q"])
    assert done.exit_code == 0, done.output
    return folder / "p.xml"


def run(*arguments: str) -> Result:
    return CliRunner().invoke(main, [*arguments, "-q"])


def test_classify_on_the_cluster_writes_what_one_process_writes(
    project: Path, address: str, tmp_path: Path
) -> None:
    common = ["classify", str(project), "--format", "json", "--refined", str(tmp_path / "r.inv")]
    alone = run(*common, "-j", "1")
    refined = (tmp_path / "r.inv").read_bytes()
    fleet = run(*common, "--scheduler", address)
    assert fleet.exit_code == alone.exit_code == 1, fleet.output  # the bags that are none
    assert fleet.stdout == alone.stdout
    assert '"error": "' in fleet.stdout  # the bags that could not be read, reported
    assert (tmp_path / "r.inv").read_bytes() == refined
    assert f'"bag": "{project.parent / "bags" / "ok" / "notes.bag"}",' in fleet.stdout


def test_a_learnt_detector_on_the_cluster_is_the_one_process_learns(
    project: Path, address: str, tmp_path: Path
) -> None:
    """The runs' samples come back from the workers: the detectors (if any is learnt on
    these few runs) and the report are those of one process."""
    config = tmp_path / "p.xml"
    shutil.copytree(project.parent, tmp_path, dirs_exist_ok=True)
    config.write_text(
        CONFIG.replace('<check inv="p.inv">', '<check inv="p.inv" detector="logistic">')
    )
    common = ["classify", str(config), "--format", "json", "--refined", str(tmp_path / "r.inv")]
    alone = run(*common, "-j", "1")
    refined = (tmp_path / "r.inv").read_bytes()
    fleet = run(*common, "--scheduler", address)
    assert fleet.stdout == alone.stdout and '"detectors": [' in fleet.stdout
    assert (tmp_path / "r.inv").read_bytes() == refined


def test_classify_cross_validated_on_the_cluster(
    project: Path, address: str, tmp_path: Path
) -> None:
    common = ["classify", str(project), "--format", "json", "--cross-validate", "2"]
    common += ["--refined", str(tmp_path / "r.inv")]
    alone = run(*common, "-j", "1")
    refined = (tmp_path / "r.inv").read_bytes()
    fleet = run(*common, "--scheduler", address)
    assert fleet.exit_code == alone.exit_code, fleet.output
    assert '"cross_validation"' in fleet.stdout
    assert fleet.stdout == alone.stdout
    assert (tmp_path / "r.inv").read_bytes() == refined


def test_stability_on_the_cluster_reports_what_one_process_reports(
    project: Path, address: str
) -> None:
    common = ["stability", str(project), "--format", "json", "--folds", "2"]
    alone = run(*common, "-j", "1")
    fleet = run(*common, "--scheduler", address)
    assert alone.exit_code == fleet.exit_code == 0, alone.output
    assert fleet.stdout == alone.stdout
    assert '"rounds"' in fleet.stdout


def test_a_worker_killed_while_observing_a_run_gives_the_same_outcomes(
    project: Path, client: Any, address: str, tmp_path: Path
) -> None:
    bags = [tmp_path / "s0.bag", tmp_path / f"s1-{VICTIM}.bag", tmp_path / "s2.bag"]
    for bag, source in zip(bags, ["s1.bag", "s2.bag", "s1.bag"], strict=True):
        shutil.copyfile(project.parent / "bags" / "ok" / source, bag)
    document = load(project.parent / "p.inv")
    alone = observe_runs(document, bags, workers=1)
    fleet = observe_runs(
        document, bags, cluster=Fleet(client, address, observe=kill_once_observing)
    )
    assert marker(bags[1]).exists(), "no worker was killed"
    assert repr(fleet) == repr(alone)
