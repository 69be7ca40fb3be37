"""Fixture pairs per pass: ``config.xml`` (+ ``graph.yaml``) in, ``expected.json`` IR out.

Each case folder ``tests/fixtures/passes/<pass>/<case>/`` runs the pipeline up to and
including ``<pass>`` and compares the IR with ``expected.json``. Expected diagnostics are
comments in ``config.xml`` (``<!-- note: [relative-cycle] -->``) on the line they point at.
Set ``IMROSC_UPDATE_GOLDEN=1`` to rewrite the expected files after a deliberate change.
"""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from imrosc import ir
from tests.passes.support import EXPECT, PASS_NAMES, UPDATE, cases, run_case


@pytest.mark.parametrize("case", cases(), ids=lambda c: f"{c.parent.name}/{c.name}")
def test_pass_fixture(case: Path) -> None:
    project, found = run_case(case)
    text = (case / "config.xml").read_text(encoding="utf-8")
    expected = {
        (number, m[1], m[2])
        for number, line in enumerate(text.splitlines(), start=1)
        for m in EXPECT.finditer(line)
    }
    assert found == expected
    got = json.dumps(ir.to_json(project), indent=2) + "\n"
    golden = case / "expected.json"
    if UPDATE or not golden.exists():
        golden.write_text(got, encoding="utf-8")
    assert got == golden.read_text(encoding="utf-8")
    assert ir.project_from_json(json.loads(got)) == project


def test_every_pass_has_fixtures() -> None:
    covered = {case.parent.name for case in cases()}
    assert covered == set(PASS_NAMES)
