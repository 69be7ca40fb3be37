"""The pass fixture cases (``tests/fixtures/passes/<pass>/<case>/``) and how one runs."""

from __future__ import annotations

import os
import re
from pathlib import Path

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
EXPECT = re.compile(r"<!-- (error|warning|note): \[([a-z0-9-]+)\] -->")
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
