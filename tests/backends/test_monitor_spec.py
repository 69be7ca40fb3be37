"""The monitor spec shared by the monitor backends: what it holds, what it refuses.

Also the helpers the ``ros1`` and launch tests share: small invariants documents built from
real message layouts, configurations around them, and the landing example's invariants
inferred once per session from simulated bags.
"""

from __future__ import annotations

import json
import re
import shutil
from collections.abc import Iterator, Sequence
from pathlib import Path

import pytest

from imrosc import ir
from imrosc.backends.monitor import (
    MonitorSpec,
    SpecError,
    check_path,
    flat_expression,
    monitor_spec,
    ros_types,
)
from imrosc.backends.registry import BuildInputs
from imrosc.build import BuildResult, load_graph
from imrosc.lower import lower
from imrosc.passes.context import PassContext
from imrosc.passes.pipeline import run_passes
from imrosc.schema.loader import load_config
from tests.backends.monitor_support import (
    EXAMPLES,
    ROOT,
    build_ros1,
    config_text,
    invariants_document,
    write_case,
)

FIXTURES = ROOT / "tests" / "fixtures" / "monitor"


# -- helpers shared by the backend tests ----------------------------------------------------


def spec_of(
    config: Path, graph_files: Sequence[Path] = ()
) -> tuple[MonitorSpec | None, BuildInputs]:
    """The monitor spec of a configuration (and the inputs, with their diagnostics)."""
    loaded, problems = load_config(config)
    assert loaded is not None, problems
    graph, _ = load_graph(graph_files, [])
    project = run_passes(lower(loaded), PassContext(path=loaded.path, graph=graph))
    inputs = BuildInputs(project, graph=graph)
    return monitor_spec(inputs), inputs


# -- the spec -------------------------------------------------------------------------------


def test_landing_spec_names_types_relays_actions_and_violation_map(landing_sim: Path) -> None:
    spec, inputs = spec_of(
        landing_sim / "landing_sim.xml", [landing_sim / "landing_sim.graph.yaml"]
    )
    assert spec is not None, [d.as_text() for d in inputs.diagnostics]
    assert (spec.package, spec.node, spec.watchdog) == (
        "landing_sim_monitor",
        "landing_sim_monitor",
        "landing_sim_monitor_watchdog",
    )
    assert spec.period == 0.5
    topics = {t.name: t for t in spec.topics}
    pose = topics["/a/car_pose"]
    assert (pose.package, pose.ros1_type, pose.ros2_type) == (
        "geometry_msgs",
        "geometry_msgs/PoseStamped",
        "geometry_msgs/msg/PoseStamped",
    )
    assert pose.relay is None
    assert spec.topic_relays == {
        "/a/cmd_subject_ctrl_state": "/m/a/cmd_subject_ctrl_state",
        "/a/task_waypose": "/m/a/task_waypose",
    }
    assert {s.name: s.block for s in spec.services} == {
        "/a/execute_task": False,
        "/a/poll_status": False,
    }
    (action,) = spec.actions
    assert (action.id, action.target, action.destination, action.ros1_type) == (
        "f",
        "topic",
        "/m/a/cmd_subject_ctrl_state",  # a blocked topic: straight to its subscribers
        "std_msgs/UInt8",
    )
    assert action.value == {"data": 3}
    assert spec.violations == {"a": ("f",), "e": ("f",), "v": ("f",)}
    assert set(spec.params) == {
        "/a/car_ctrl/landing_radius",
        "/a/car_ctrl/landing_time",
        "/a/car_ctrl/poll_rate",
    }
    assert spec.depends == ("geometry_msgs", "sensor_msgs", "std_msgs")
    runtime = spec.runtime_document("banner")
    assert json.loads(json.dumps(runtime)) == runtime
    assert runtime["violations"] == {"a": ["f"], "e": ["f"], "v": ["f"]}


@pytest.mark.parametrize(
    ("path", "kind", "derived", "expected"),
    [
        ("data", "uint", None, "float(m.data)"),
        ("header.frame_id", "string", None, "str(m.header.frame_id)"),
        ("values[3]", "float", None, "float(at_(m.values, 3))"),
        ("ranges", "uint", "len", "len_(m.ranges)"),
        ("ranges", "float", "std", "std_(m.ranges)"),
    ],
)
def test_flat_expressions(path: str, kind: str, derived: str | None, expected: str) -> None:
    assert flat_expression(path, kind, derived) == expected


@pytest.mark.parametrize(
    "path",
    [
        "pose.x; import os",
        "pose.x)",
        "__class__",
        "pose.__dict__",
        "_private",
        "for.x",
        "a[1][2]",
        "a[-1]",
        "a[1].b",
        "a..b",
        "",
        "pose.x\n",
        "pos\u00e9",
    ],
)
def test_unsafe_field_paths_are_refused(path: str) -> None:
    with pytest.raises(SpecError):
        check_path(path)


@pytest.mark.parametrize(
    "msgtype", ["geometry_msgs/msg/Pose Stamped", "a/b/c/d", "x'); import os", "Pose", "/a/B"]
)
def test_type_names_that_are_not_pkg_type_are_refused(msgtype: str) -> None:
    with pytest.raises(SpecError):
        ros_types(msgtype)


def test_ros1_name_of_a_ros1_style_type() -> None:
    assert ros_types("std_msgs/UInt8") == ("std_msgs", "std_msgs/UInt8", "std_msgs/msg/UInt8")


def _codes(result: BuildResult) -> set[tuple[str, str]]:
    return {(d.code, Path(d.path).name) for d in result.diagnostics}


def test_bad_strings_in_the_invariants_file_are_diagnostics_naming_it(tmp_path: Path) -> None:
    document = invariants_document({"/cmd": "std_msgs/msg/UInt8"})
    document["topics"]["/cmd"]["variables"][0]["path"] = "data; __import__('os')"
    document["topics"]["/odd name"] = {"type": "std_msgs/msg/UInt8", "variables": []}
    document["topics"]["/ok"] = {"type": "std_msgs/msg/UInt 8", "variables": []}
    config = write_case(tmp_path, config_text(), document)
    result = build_ros1(config)
    assert not result.ok and result.files == {}
    assert {("bad-field-path", "demo.inv"), ("bad-name", "demo.inv")} <= _codes(result)
    assert ("bad-type-name", "demo.inv") in _codes(result)
    line = next(d for d in result.diagnostics if d.code == "bad-field-path").line
    text = (tmp_path / "demo.inv").read_text().splitlines()
    assert "__import__" in text[line - 1]


def test_no_monitor_is_a_diagnostic(tmp_path: Path) -> None:
    config = write_case(tmp_path, config_text(monitor=""), None)
    result = build_ros1(config)
    assert not result.ok
    assert _codes(result) == {("monitor-missing", "demo.xml")}


@pytest.mark.parametrize(
    ("content", "reason"),
    [
        (None, "cannot read"),
        ("{not json", "not JSON"),
        ('{"format": "other"}', "not an imrosc invariants file"),
        (
            '{"format": "imrosc-invariants", "version": 1, "topics": {},'
            ' "points": {"a": {"kind": "publish"}}, "invariants": []}',
            "malformed: $.points.a: missing 'variables'",
        ),
    ],
)
def test_an_unusable_invariants_file_is_a_diagnostic(
    tmp_path: Path, content: str | None, reason: str
) -> None:
    config = write_case(tmp_path, config_text(), None)
    if content is not None:
        (tmp_path / "demo.inv").write_text(content)
    result = build_ros1(config)
    (diagnostic,) = result.diagnostics
    assert diagnostic.code == "invariants-unreadable"
    assert diagnostic.path == str(config)
    assert reason in diagnostic.message and "demo.inv" in diagnostic.message


def test_a_project_name_that_is_no_package_name_is_refused(tmp_path: Path) -> None:
    document = {**invariants_document({"/cmd": "std_msgs/msg/UInt8"}), "project": "Landing Sim"}
    config = write_case(tmp_path, config_text(project="Landing Sim"), document)
    assert _codes(build_ros1(config)) == {("bad-package-name", "demo.xml")}


def test_invariants_of_another_project_are_a_warning(tmp_path: Path) -> None:
    document = invariants_document({"/cmd": "std_msgs/msg/UInt8"})  # inferred for "demo"
    config = write_case(tmp_path, config_text(project="other"), document)
    result = build_ros1(config)
    assert _codes(result) == {("project-mismatch", "demo.xml")} and result.ok
    (warning,) = result.diagnostics
    assert "was inferred for project 'demo', not 'other'" in warning.message


def test_an_action_on_a_topic_of_unknown_type_is_noted_and_resolved_at_run_time(
    tmp_path: Path,
) -> None:
    document = invariants_document({"/cmd": "std_msgs/msg/UInt8"})
    monitor = (
        '<monitor inv="demo.inv"><action id="f"><topic>/elsewhere</topic>'
        "<value>{data: 1}</value></action><violation>a -> f</violation></monitor>"
    )
    config = write_case(tmp_path, config_text(monitor=monitor), document)
    result = build_ros1(config)
    assert result.ok
    assert _codes(result) == {("action-type-unknown", "demo.xml")}
    spec = json.loads(result.files["demo_monitor/scripts/imrosc_monitor/spec.json"])
    assert spec["actions"]["f"]["type"] is None
    assert spec["actions"]["f"]["destination"] == "/elsewhere"


def test_the_alarm_attributes_reach_the_spec_and_only_the_given_ones(tmp_path: Path) -> None:
    document = invariants_document({"/cmd": "std_msgs/msg/UInt8"})
    monitor = '<monitor inv="demo.inv" alarm_persist="5" alarm_window="0.25"/>'
    config = write_case(tmp_path, config_text(monitor=monitor), document)
    result = build_ros1(config)
    assert result.ok, result.diagnostics
    spec = json.loads(result.files["demo_monitor/scripts/imrosc_monitor/spec.json"])
    assert spec["alarms"] == {"persist": 5, "window": 0.25}
    plain = write_case(tmp_path / "plain", config_text(), document)
    spec = json.loads(build_ros1(plain).files["demo_monitor/scripts/imrosc_monitor/spec.json"])
    assert spec["alarms"] == {}
    off = '<monitor inv="demo.inv" alarm_severe="0"/>'
    severe = write_case(tmp_path / "severe", config_text(monitor=off), document)
    spec = json.loads(build_ros1(severe).files["demo_monitor/scripts/imrosc_monitor/spec.json"])
    assert spec["alarms"] == {"severe": 0.0}


def test_the_alarm_attributes_are_lowered_and_round_trip_through_the_ir() -> None:
    loaded, problems = load_config(EXAMPLES / "uav_landing.xml")
    assert loaded is not None, problems
    project = lower(loaded)
    assert project.monitor is not None
    overrides = project.monitor.alarms
    assert overrides == ir.AlarmOverrides(persist=3, seconds=0.3, distinct=2, window=0.5, severe=1)
    assert overrides.given() == {
        "persist": 3,
        "seconds": 0.3,
        "distinct": 2,
        "window": 0.5,
        "severe": 1,
    }
    assert ir.project_from_json(ir.to_json(project)) == project
    assert ir.AlarmOverrides(distinct=0).given() == {"distinct": 0}


def test_a_blocked_service_is_relayed_and_blocked(tmp_path: Path) -> None:
    document = invariants_document({"/cmd": "std_msgs/msg/UInt8"})
    scope = '<publish id="a">/cmd</publish>\n    <call id="c">/srv</call>'
    monitor = '<monitor inv="demo.inv"><block>/srv, /cmd</block></monitor>'
    config = write_case(tmp_path, config_text(scope=scope, monitor=monitor), document)
    spec, inputs = spec_of(config)
    assert spec is not None, inputs.diagnostics
    assert [(s.name, s.relay, s.block) for s in spec.services] == [("/srv", "/m/srv", True)]
    assert spec.topic_relays == {"/cmd": "/m/cmd"}


def test_a_blocked_topic_no_invariant_watches_is_relayed_unchecked(tmp_path: Path) -> None:
    document = invariants_document({"/cmd": "std_msgs/msg/UInt8"})
    monitor = '<monitor inv="demo.inv"><block>/raw</block></monitor>'
    config = write_case(tmp_path, config_text(monitor=monitor), document)
    spec, _ = spec_of(config)
    assert spec is not None
    raw = next(t for t in spec.topics if t.name == "/raw")
    assert (raw.flattener, raw.relay, raw.ros1_type) == (None, "/m/raw", None)


# -- the diagnostic fixtures of the monitor backends ----------------------------------------

_EXPECT = re.compile(
    r"^(?P<file>[^:]+):(?P<line>\d+): (?P<severity>\w+): \[(?P<code>[a-z0-9-]+)\]$"
)


def fixture_cases() -> Iterator[Path]:
    yield from sorted(p for p in FIXTURES.iterdir() if p.is_dir())


@pytest.mark.parametrize("case", list(fixture_cases()), ids=lambda p: p.name)
def test_monitor_fixture_reports_exactly_its_expectations(case: Path, tmp_path: Path) -> None:
    """Each ``tests/fixtures/monitor/<case>/`` is built with ``--backend ros1``; ``build.expect``
    lists every diagnostic as ``FILE:LINE: severity: [code]``."""
    folder = tmp_path / case.name
    shutil.copytree(case, folder)
    graph = [folder / "graph.yaml"] if (folder / "graph.yaml").exists() else []
    result = build_ros1(folder / "config.xml", graph)
    got = {
        (Path(d.path).relative_to(folder).as_posix(), d.line, d.severity.value, d.code)
        for d in result.diagnostics
    }
    lines = (folder / "build.expect").read_text().splitlines()
    expected = set()
    for line in lines:
        found = _EXPECT.match(line)
        assert found, line
        expected.add((found["file"], int(found["line"]), found["severity"], found["code"]))
    assert got == expected, [d.as_text() for d in result.diagnostics]
    if any(severity == "error" for _, _, severity, _ in expected):
        assert result.files == {}
