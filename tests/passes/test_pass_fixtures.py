"""Fixture pairs per pass: ``config.xml`` (+ ``graph.yaml``) in, ``expected.json`` IR out.

Each case folder ``tests/fixtures/passes/<pass>/<case>/`` runs the pipeline up to and
including ``<pass>`` and compares the IR with ``expected.json``. Expected diagnostics are
comments in ``config.xml`` (``<!-- note: [relative-cycle] -->``) on the line they point at.
Set ``IMROSC_UPDATE_GOLDEN=1`` to rewrite the expected files after a deliberate change.
"""

from __future__ import annotations

import json
import os
import re
from pathlib import Path

import pytest

from imrosc import ir
from imrosc.check import check_loaded
from imrosc.diagnostics import has_errors
from imrosc.graph.file import load_graph_file
from imrosc.lower import lower
from imrosc.passes.context import PassContext
from imrosc.passes.pipeline import PASSES, run_passes
from imrosc.schema.loader import load_config

CASES = Path(__file__).parent.parent / "fixtures" / "passes"
PASS_NAMES = [p.__name__ for p in PASSES]
_EXPECT = re.compile(r"<!-- (error|warning|note): \[([a-z0-9-]+)\] -->")
UPDATE = os.environ.get("IMROSC_UPDATE_GOLDEN") == "1"


def cases() -> list[Path]:
    return sorted(p for p in CASES.glob("*/*") if (p / "config.xml").exists())


def run_case(case: Path) -> tuple[ir.Project, set[tuple[int, str, str]]]:
    config, problems = load_config(case / "config.xml", label="config.xml")
    assert config is not None and not problems
    assert not has_errors(check_loaded(config))
    graph = None
    if (case / "graph.yaml").exists():
        graph, graph_problems = load_graph_file(case / "graph.yaml")
        assert not graph_problems
    context = PassContext(path="config.xml", graph=graph)
    upto = PASS_NAMES.index(case.parent.name) + 1
    project = run_passes(lower(config), context, PASSES[:upto])
    found = {(d.line, d.severity.value, d.code) for d in context.diagnostics}
    return project, found


@pytest.mark.parametrize("case", cases(), ids=lambda c: f"{c.parent.name}/{c.name}")
def test_pass_fixture(case: Path) -> None:
    project, found = run_case(case)
    text = (case / "config.xml").read_text(encoding="utf-8")
    expected = {
        (number, m[1], m[2])
        for number, line in enumerate(text.splitlines(), start=1)
        for m in _EXPECT.finditer(line)
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
