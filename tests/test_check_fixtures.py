"""Fixture-pair tests: each file under tests/fixtures/check/ says what it must trigger.

An expectation is an XML comment at the end of the line the diagnostic must point at,
mypy style: ``<!-- error: [bad-id] -->`` or ``<!-- warning: [unused-condition] -->``
(several may follow each other). A file that cannot carry comments (an unreadable path)
has a sidecar ``NAME.expect`` with lines ``LINE: severity: [code]``. A comment
``<!-- fixture: max-bytes=N -->`` lowers the size cap for that fixture.
The run must produce exactly the expected (line, severity, code) triples.
"""

from __future__ import annotations

import re
from pathlib import Path

import pytest

from imrosc.check import check_file
from imrosc.codes import CODES
from imrosc.schema.loader import MAX_CONFIG_BYTES

FIXTURES = Path(__file__).parent / "fixtures" / "check"
_EXPECT = re.compile(r"<!-- (error|warning): \[([a-z0-9-]+)\] -->")
_SIDE = re.compile(r"^(\d+): (error|warning): \[([a-z0-9-]+)\]$")
_MAX_BYTES = re.compile(r"<!-- fixture: max-bytes=(\d+) -->")

Expectation = tuple[int, str, str]


def fixture_paths() -> list[Path]:
    return sorted(p for p in FIXTURES.iterdir() if p.suffix == ".xml")


def expectations(path: Path) -> tuple[set[Expectation], int]:
    sidecar = path.with_suffix(".expect")
    if sidecar.exists():
        lines = sidecar.read_text(encoding="utf-8").splitlines()
        found = {_SIDE.fullmatch(line) for line in lines}
        return {(int(m[1]), m[2], m[3]) for m in found if m}, MAX_CONFIG_BYTES
    text = path.read_bytes().decode("utf-8", "replace")
    expected = {
        (number, m[1], m[2])
        for number, line in enumerate(text.splitlines(), start=1)
        for m in _EXPECT.finditer(line)
    }
    cap = _MAX_BYTES.search(text)
    return expected, int(cap[1]) if cap else MAX_CONFIG_BYTES


@pytest.mark.parametrize("path", fixture_paths(), ids=lambda p: p.stem)
def test_fixture_triggers_exactly_its_expectations(path: Path) -> None:
    expected, max_bytes = expectations(path)
    assert expected, f"{path.name} states no expectation"
    found = check_file(path, label=path.name, max_bytes=max_bytes)
    got = {(d.line, d.severity.value, d.code) for d in found}
    assert got == expected, "\n".join(d.as_text() for d in found)


@pytest.mark.parametrize("path", fixture_paths(), ids=lambda p: p.stem)
def test_fixture_is_named_after_a_code_it_triggers(path: Path) -> None:
    code = path.stem.split(".")[0]
    assert code in {c.name for c in CODES}, f"{path.name} is not named after a code"
    assert code in {e[2] for e in expectations(path)[0]}


_ANY_EXPECTATION = re.compile(r"(?:error|warning|note): \[([a-z0-9-]+)\]")


def test_every_code_has_a_fixture() -> None:
    """Every registered code is expected by some fixture under tests/fixtures/ (any stage)."""
    covered = {
        code
        for path in (FIXTURES.parent).rglob("*")
        if path.is_file() and path.suffix in {".xml", ".yaml", ".expect"}
        for code in _ANY_EXPECTATION.findall(path.read_bytes().decode("utf-8", "replace"))
    }
    missing = sorted({c.name for c in CODES} - covered)
    assert not missing, f"codes without a fixture: {missing}"
