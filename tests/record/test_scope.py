"""The scope of a recording: what a configuration needs, with the graph the recorder has."""

from __future__ import annotations

from pathlib import Path

from imrosc.build import load_graph
from imrosc.graph.model import Graph, Node
from imrosc.record.master import SystemState
from imrosc.record.scope import Scope, compile_scope

ROOT = Path(__file__).resolve().parent.parent.parent
EXAMPLES = ROOT / "examples"

CONFIG = """<imROS project="relay">
  <scope>
    <publish id="a" relative="2" conds="1">/cmd</publish>
    <publish id="b">
      <topic>/odom</topic>
      <topic>/imu</topic>
      <param>/odom_node/rate</param>
    </publish>
    <call id="c"><service>/task</service><param>/limits/speed</param></call>
    <param id="p">/gain</param>
    <arch id="d">pub,srv</arch>
    <temporal id="e" events="a,c"/>
    <condition id="1"><topic>/mode</topic><value>mode == 2</value></condition>
    <condition id="2"><topic>/unused</topic><value>unused == 2</value></condition>
  </scope>
</imROS>
"""

GRAPH = Graph.build(
    [
        Node("/ctrl", publishes=frozenset({"/cmd"}), subscribes=frozenset({"/pose", "/goal"})),
        Node("/loc", publishes=frozenset({"/pose"}), subscribes=frozenset({"/gps"})),
        Node("/gps_driver", publishes=frozenset({"/gps"})),
        Node("/planner", publishes=frozenset({"/goal"}), subscribes=frozenset({"/map"})),
    ],
    ("master",),
    knows_subscriptions=True,
)


def write(tmp_path: Path, text: str = CONFIG) -> Path:
    path = tmp_path / "relay.xml"
    path.write_text(text, encoding="utf-8")
    return path


def test_the_scope_holds_every_name_the_points_read(tmp_path: Path) -> None:
    compiled = compile_scope(write(tmp_path), GRAPH)
    assert [d.code for d in compiled.diagnostics] == ["unused-condition"]  # a warning
    assert compiled.warnings == []
    assert compiled.scope == Scope(
        topics=("/cmd", "/goal", "/gps", "/imu", "/map", "/mode", "/odom", "/pose"),
        services=("/task",),
        params=("/gain", "/limits/speed", "/odom_node/rate"),
        arch=("pub", "srv"),
    )
    assert compiled.scope.describe() == (
        "8 topics, 1 service, 3 parameters, architecture (pub, srv)"
    )


def test_relative_inputs_come_from_the_live_master(tmp_path: Path) -> None:
    state = SystemState.parse(
        [
            [["/cmd", ["/ctrl"]], ["/pose", ["/loc"]], ["/imrosc/arch", ["/imrosc_recorder_9"]]],
            [["/pose", ["/ctrl", "/imrosc_rosbag_9"]], ["/gps", ["/loc"]]],
            [["/task", ["/ctrl"]]],
        ]
    )
    graph = state.graph(hidden={"/imrosc_recorder_9", "/imrosc_rosbag_9"})
    assert set(graph.nodes) == {"/ctrl", "/loc"}
    compiled = compile_scope(write(tmp_path), graph)
    assert compiled.scope is not None
    assert {"/pose", "/gps"} <= set(compiled.scope.topics)
    assert "/imrosc/arch" not in compiled.scope.topics


def test_without_a_publisher_relative_inputs_are_a_warning_not_an_error(tmp_path: Path) -> None:
    for graph in (None, Graph.build([], ("master",), knows_subscriptions=True)):
        compiled = compile_scope(write(tmp_path), graph)
        assert compiled.scope is not None, compiled.diagnostics
        assert "/pose" not in compiled.scope.topics
        assert "/cmd" in compiled.scope.topics
        (warning,) = compiled.warnings
        assert warning.startswith(f"{tmp_path / 'relay.xml'}:3:5: relative=2 on /cmd:")
        assert "--graph" in warning and "--all" in warning


def test_the_landing_example_with_its_graph_file() -> None:
    graph, problems = load_graph([EXAMPLES / "landing_sim.graph.yaml"], ())
    assert problems == []
    compiled = compile_scope(EXAMPLES / "landing_sim.xml", graph)
    scope = compiled.scope
    assert scope is not None and compiled.warnings == []
    # a's inputs (relative="1") and the condition's topic are in
    assert {"/a/car_pose", "/a/subject_ctrl_state", "/a/subject_pose"} <= set(scope.topics)
    assert scope.services == ("/a/execute_task", "/a/poll_status")
    assert scope.params == (
        "/a/car_ctrl/landing_radius",
        "/a/car_ctrl/landing_time",
        "/a/car_ctrl/poll_rate",
    )
    assert scope.arch == ("pub", "sub", "srv")


def test_an_empty_arch_means_every_kind_and_unused_conditions_are_not_recorded(
    tmp_path: Path,
) -> None:
    config = write(
        tmp_path,
        '<imROS project="p"><scope><arch id="d"/>'
        '<condition id="1"><topic>/x</topic><value>x == 1</value></condition>'
        "</scope></imROS>",
    )
    compiled = compile_scope(config, None)
    assert compiled.scope == Scope(arch=("pub", "sub", "srv"))
    assert not compiled.scope.empty


def test_a_scope_with_only_a_condition_records_nothing(tmp_path: Path) -> None:
    config = write(
        tmp_path,
        '<imROS project="p"><scope>'
        '<condition id="1"><topic>/x</topic><value>x == 1</value></condition>'
        "</scope></imROS>",
    )
    compiled = compile_scope(config, None)
    assert compiled.scope is not None and compiled.scope.empty


def test_configuration_errors_give_diagnostics_and_no_scope(tmp_path: Path) -> None:
    config = write(tmp_path, '<imROS project="p"><scope><publish id="A">/x</publish></scope>')
    compiled = compile_scope(config, None)
    assert compiled.scope is None
    assert compiled.diagnostics
    assert all(d.path == str(config) for d in compiled.diagnostics)
    missing = compile_scope(tmp_path / "missing.xml", None)
    assert missing.scope is None
    assert [d.code for d in missing.diagnostics] == ["io-error"]
