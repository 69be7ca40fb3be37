"""The front end every compiling command goes through (``imrosc.frontend``): load, check,
lower, then the passes with the command's graph."""

from __future__ import annotations

from pathlib import Path

from imrosc import frontend
from imrosc.build import build
from imrosc.classify import load_project
from imrosc.diagnostics import has_errors
from imrosc.graph.file import load_graph_file
from imrosc.passes.pipeline import PASSES
from imrosc.record.scope import compile_scope

EXAMPLES = Path(__file__).resolve().parent.parent / "examples"


def test_compile_config_is_what_build_and_record_compile() -> None:
    config = EXAMPLES / "landing_sim.xml"
    graph, problems = load_graph_file(EXAMPLES / "landing_sim.graph.yaml")
    assert graph is not None and not problems
    compiled = frontend.compile_config(config, graph)
    assert compiled.project is not None and not has_errors(compiled.problems)
    assert compiled.project.passes == tuple(run.__name__ for run in PASSES)
    built = build(config, "plan", graph_files=[EXAMPLES / "landing_sim.graph.yaml"])
    assert built.ok and built.project == compiled.project
    assert compile_scope(config, graph).project == compiled.project


def test_the_two_steps_are_compile_config() -> None:
    config = EXAMPLES / "uav_landing.xml"
    lowered, problems = frontend.lowered(config)
    assert lowered is not None and lowered.passes == ()
    project, found = frontend.passed(lowered, None)
    assert frontend.compile_config(config, None) == (project, problems, found)
    assert load_project(config)[0] == lowered  # classify and stability: the points as written


def test_a_configuration_with_errors_goes_no_further(tmp_path: Path) -> None:
    config = tmp_path / "bad.xml"
    config.write_text('<imROS project="p"><scope><publish id="A">/x</publish></scope></imROS>')
    compiled = frontend.compile_config(config, None)
    assert compiled.project is None and compiled.pass_problems == []
    assert [d.code for d in compiled.problems] == ["bad-id"]
    assert frontend.lowered(config)[0] is None
