"""The layout rules of ``docs/architecture.md`` that a reader of the imports can check: a test
file imports no other test file, and inference, translation and calibration never import the
backends or the stage drivers above them."""

from __future__ import annotations

import ast
from collections.abc import Iterator
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
ABOVE = ("backends", "cli", "build", "detect", "classify", "demo")
"""What sits above inference, translation and calibration (calibration replays held-out bags
with :class:`imrosc.replay.Replayer`, the checker ``imrosc replay`` drives)."""


def imported(path: Path) -> Iterator[tuple[int, str]]:
    """The absolute modules a file imports (``from a.b import c`` gives ``a.b.c`` and
    ``a.b``), with their lines."""
    for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"), str(path))):
        if isinstance(node, ast.Import):
            for alias in node.names:
                yield node.lineno, alias.name
        elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
            yield node.lineno, node.module
            for alias in node.names:
                yield node.lineno, f"{node.module}.{alias.name}"


def test_imported_gives_the_modules_and_names_a_file_imports(tmp_path: Path) -> None:
    probe = tmp_path / "probe.py"
    probe.write_text("import a.b\nfrom tests.x import test_y, z\nfrom . import w\n")
    assert sorted(imported(probe)) == [
        (1, "a.b"),
        (2, "tests.x"),
        (2, "tests.x.test_y"),
        (2, "tests.x.z"),
    ]


def test_no_test_file_imports_another() -> None:
    found = []
    for path in sorted((ROOT / "tests").rglob("*.py")):
        for line, module in imported(path):
            parts = module.split(".")
            if parts[0] == "tests" and parts[-1].startswith("test_"):
                found.append(f"{path.relative_to(ROOT)}:{line} imports {module}")
    assert found == []


@pytest.mark.parametrize("package", ["infer", "translate", "calibrate"])
def test_a_lower_stage_imports_nothing_above_it(package: str) -> None:
    above = {f"imrosc.{name}" for name in ABOVE}
    found = []
    for path in sorted((ROOT / "imrosc" / package).rglob("*.py")):
        for line, module in imported(path):
            if any(module == name or module.startswith(name + ".") for name in above):
                found.append(f"{path.relative_to(ROOT)}:{line} imports {module}")
    assert found == []
