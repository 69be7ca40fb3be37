"""What the wheel ships: the grammar and the examples are the very files of the repository."""

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
def test_wheel_ships_the_grammar_and_the_examples_unchanged(tmp_path: Path) -> None:
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
