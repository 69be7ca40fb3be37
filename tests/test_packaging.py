"""What the wheel ships: the grammar, the examples and the backends' templates are the very
files of the repository, and imrosc's backends are entry points."""

from __future__ import annotations

import subprocess
import sys
import zipfile
from pathlib import Path

import pytest

from imrosc.schema.validate import grammar_text

ROOT = Path(__file__).parent.parent


def test_installed_grammar_is_the_repository_grammar() -> None:
    assert grammar_text() == (ROOT / "grammar" / "imros.xsd").read_bytes()


@pytest.mark.slow
def test_wheel_ships_the_grammar_the_examples_and_the_templates_unchanged(tmp_path: Path) -> None:
    subprocess.run(
        [
            *(sys.executable, "-m", "pip", "wheel", "--no-deps", "--no-build-isolation", "-q"),
            *("-w", str(tmp_path), str(ROOT)),
        ],
        check=True,
        capture_output=True,
    )
    (wheel,) = tmp_path.glob("imrosc-*.whl")
    with zipfile.ZipFile(wheel) as archive:
        assert archive.read("imrosc/schema/imros.xsd") == grammar_text()
        packaged = sorted((ROOT / "imrosc" / "demo" / "examples").iterdir())
        assert {p.name for p in packaged} >= {"landing_sim.xml", "water_sampling.xml"}
        for example in packaged:  # each a symlink to the repository's example
            shipped = archive.read(f"imrosc/demo/examples/{example.name}")
            assert shipped == (ROOT / "examples" / example.name).read_bytes()
        for template in sorted((ROOT / "imrosc").rglob("*.j2")):
            name = template.relative_to(ROOT).as_posix()
            assert archive.read(name) == template.read_bytes(), name
        (points,) = [n for n in archive.namelist() if n.endswith(".dist-info/entry_points.txt")]
        declared = archive.read(points).decode()
    backends = declared.split("[imrosc.backends]\n", 1)[1].split("\n\n", 1)[0].splitlines()
    assert backends == [f"{name} = imrosc.backends.{name}" for name in ("plan", "ros1", "ros2")]
