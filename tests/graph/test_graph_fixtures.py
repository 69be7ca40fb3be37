"""Fixture tests: each file under tests/fixtures/graph/ says what loading it must report.

An expectation is a YAML comment at the end of the line the diagnostic must point at, mypy
style: ``# error: [graph-invalid]`` or ``# warning: [relative-name]``. A comment
``# fixture: max-bytes=N`` lowers the size cap for that fixture. Loading must report exactly
the expected (line, severity, code) triples, and each fixture is named after a code it
triggers (``graph-invalid.<what>.yaml`` for variants).
"""

from __future__ import annotations

import re
from pathlib import Path

import pytest

from imrosc.codes import BY_NAME
from imrosc.graph.file import MAX_GRAPH_BYTES, load_graph_file

FIXTURES = Path(__file__).parent.parent / "fixtures" / "graph"
_EXPECT = re.compile(r"# (error|warning): \[([a-z0-9-]+)\]")
_MAX_BYTES = re.compile(r"# fixture: max-bytes=(\d+)")

Expectation = tuple[int, str, str]


def fixture_paths() -> list[Path]:
    return sorted(FIXTURES.glob("*.yaml"))


def expectations(path: Path) -> tuple[set[Expectation], int]:
    text = path.read_text(encoding="utf-8")
    expected = {
        (number, m[1], m[2])
        for number, line in enumerate(text.splitlines(), start=1)
        for m in _EXPECT.finditer(line)
    }
    cap = _MAX_BYTES.search(text)
    return expected, int(cap[1]) if cap else MAX_GRAPH_BYTES


@pytest.mark.parametrize("path", fixture_paths(), ids=lambda p: p.stem)
def test_fixture_reports_exactly_its_expectations(path: Path) -> None:
    expected, max_bytes = expectations(path)
    assert expected, f"{path.name} states no expectation"
    _, found = load_graph_file(path, label=path.name, max_bytes=max_bytes)
    got = {(d.line, d.severity.value, d.code) for d in found}
    assert got == expected, "\n".join(d.as_text() for d in found)
    assert all(d.path == path.name for d in found)


@pytest.mark.parametrize("path", fixture_paths(), ids=lambda p: p.stem)
def test_fixture_is_named_after_a_code_it_triggers(path: Path) -> None:
    code = path.name.split(".")[0]
    assert code in BY_NAME, f"{path.name} is not named after a code"
    assert code in {e[2] for e in expectations(path)[0]}


def test_the_graph_codes_have_fixtures() -> None:
    covered = {p.name.split(".")[0] for p in fixture_paths()}
    assert {"graph-syntax", "graph-invalid", "bad-name", "relative-name"} <= covered
