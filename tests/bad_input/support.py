"""The small project the catalogue of bad inputs runs its commands in: a configuration,
training, successful and failed bags and the invariants learnt from them (``template``, made
once per module), copied fresh for every case (``project``); ``snapshot`` tells whether a
file changed; ``COMMANDS`` are the commands that read bags, each with the bag it is given
damaged, and ``run`` runs one in a project."""

from __future__ import annotations

import hashlib
import os
import shutil
from collections.abc import Iterator
from pathlib import Path

import pytest
from click.testing import CliRunner

from imrosc.cli import main
from tests.translate import good_run

CONFIG = """<imROS project="p">
  <scope>
    <publish id="a"><topic>/out</topic><topic>/in</topic></publish>
  </scope>
  <detect inv="p.inv" budget="0"><bag>bags/train</bag></detect>
  <check inv="p.inv">
    <success>bags/ok</success>
    <fail>bags/bad</fail>
  </check>
</imROS>
"""


@pytest.fixture(scope="module")
def template(tmp_path_factory: pytest.TempPathFactory) -> Path:
    folder = tmp_path_factory.mktemp("project")
    (folder / "p.xml").write_text(CONFIG)
    for name in ("train", "ok", "bad"):
        (folder / "bags" / name).mkdir(parents=True)
    good_run(folder / "bags" / "train" / "r1.bag", 0.0)
    good_run(folder / "bags" / "train" / "r2.bag", 10.0)
    good_run(folder / "bags" / "ok" / "s1.bag", 20.0)
    good_run(folder / "bags" / "bad" / "f1.bag", 30.0, odd=True)
    done = CliRunner().invoke(main, ["infer", str(folder / "p.xml"), "-j", "1", "-q"])
    assert done.exit_code == 0, done.output
    return folder


def snapshot(folder: Path) -> dict[str, str]:
    """Every file (and link) under ``folder``: its content's hash (a link: its target)."""
    found: dict[str, str] = {}
    for path in sorted(folder.rglob("*")):
        key = str(path.relative_to(folder))
        if path.is_symlink():
            found[key] = "-> " + os.readlink(path)
        elif path.is_file():
            found[key] = hashlib.sha1(path.read_bytes()).hexdigest()
    return found


@pytest.fixture
def project(template: Path, tmp_path: Path) -> Iterator[Path]:
    folder = tmp_path / "project"
    shutil.copytree(template, folder, symlinks=True)
    yield folder


RECOVERED = "recovered"
"""The word of the warning that a damaged bag was read in part."""

COMMANDS: dict[str, tuple[tuple[str, ...], str, set[int]]] = {
    # the command, the bag it reads that is damaged, the statuses it may give (a run cut
    # short may break what the whole run kept: replay's 1 and 3)
    "infer": (("infer", "{d}/p.xml", "-j", "1", "-q"), "bags/train/r2.bag", {0}),
    "replay": (("replay", "{d}/p.inv", "{d}/bags/ok/s1.bag"), "bags/ok/s1.bag", {0, 1, 3}),
    "classify": (("classify", "{d}/p.xml", "-j", "1"), "bags/bad/f1.bag", {0}),
    "stability": (("stability", "{d}/p.xml", "-j", "1", "-q"), "bags/train/r1.bag", {0}),
    "info": (("info", "{d}/bags/ok/s1.bag"), "bags/ok/s1.bag", {0, 1, 3}),
    "export-daikon": (
        ("export-daikon", "{d}/p.xml", "-o", "{d}/daikon", "-q"),
        "bags/train/r1.bag",
        {0},
    ),
}


def run(project: Path, args: tuple[str, ...]) -> tuple[int, str, str]:
    """Run an imrosc command in ``project`` (``{d}``): its status, stdout and stderr."""
    result = CliRunner().invoke(main, [arg.replace("{d}", str(project)) for arg in args])
    assert result.exception is None or isinstance(result.exception, SystemExit), result.output
    assert "Traceback" not in result.output
    return result.exit_code, result.stdout, result.stderr
