"""ROS 2 launch XML rewriting: subscribers of blocked topics remapped to the monitor's relays,
clients of relayed services to its services, namespaces followed through
``<push-ros-namespace>`` and ``<group>``, the monitor included, the original left alone."""

from __future__ import annotations

import shutil
from pathlib import Path

import pytest
from lxml import etree

from imrosc.backends.launch import (
    FAIL_OPEN_ARG,
    Interception,
    MonitorLaunch,
    Rewritten,
    rewrite_ros2,
)
from imrosc.backends.registry import GENERATED_MARK
from imrosc.graph.model import Graph, Node
from tests.backends.launch_support import BLOCKED, landing_graph
from tests.backends.ros2_build import build_ros2, setup_arguments

SYSTEM = """<?xml version="1.0"?>
<!-- the landing system -->
<launch>
  <arg name="sim" default="true"/>
  <node pkg="vicon_bridge" exec="vicon" name="vicon"/>
  <group>
    <push-ros-namespace namespace="a"/>
    <node pkg="landing" exec="car" name="car"/>
    <node pkg="landing" exec="car_ctrl" name="car_ctrl"/>
    <node pkg="landing" exec="state_machine" name="ctrl_state_machine">
      <param name="rate" value="10"/>
    </node>
    <node pkg="landing" exec="pid" name="pid_ctrl">
      <remap from="waypose" to="task_waypose"/>
    </node>
  </group>
  <node pkg="landing" exec="launch" name="launch_ctrl" namespace="a"/>
  <node pkg="landing" exec="recorder" name="recorder"/>
  <node pkg="landing" exec="spy" name="$(var spy)"/>
  <node pkg="landing" exec="anonymous"/>
  <include file="$(find-pkg-share landing)/launch/extra.launch.xml"/>
</launch>
"""
MONITOR = MonitorLaunch("landing_sim_monitor", "landing_sim_monitor.launch.xml")


def rewrite(
    tmp_path: Path,
    text: str = SYSTEM,
    interception: Interception | None = None,
    graph: Graph | None = None,
) -> Rewritten:
    path = tmp_path / "system.launch.xml"
    path.write_text(text)
    return rewrite_ros2(
        path,
        interception=interception or Interception(BLOCKED, {}),
        graph=graph or landing_graph(),
        monitor=MONITOR,
        banner=f"{GENERATED_MARK} 0 (backend ros2) from demo.xml; do not edit",
    )


def remaps_of(content: bytes) -> dict[str, list[tuple[str, str]]]:
    root = etree.fromstring(content)
    found: dict[str, list[tuple[str, str]]] = {}
    for node in root.iter("node"):
        found[node.get("name", node.get("exec", ""))] = [
            (r.get("from", ""), r.get("to", "")) for r in node.iter("remap")
        ]
    return found


def test_only_the_subscribers_of_blocked_topics_are_remapped(tmp_path: Path) -> None:
    rewritten = rewrite(tmp_path)
    assert rewritten.content is not None
    assert rewritten.remaps == {
        "/a/ctrl_state_machine": [("/a/cmd_subject_ctrl_state", "/m/a/cmd_subject_ctrl_state")],
        "/a/pid_ctrl": [("waypose", "/m/a/task_waypose")],  # its own remap now leads there
    }
    remaps = remaps_of(rewritten.content)
    assert remaps["ctrl_state_machine"] == [
        ("/a/cmd_subject_ctrl_state", "/m/a/cmd_subject_ctrl_state")
    ]
    assert remaps["pid_ctrl"] == [("waypose", "/m/a/task_waypose")]
    for other in ("car_ctrl", "car", "vicon", "launch_ctrl", "recorder", "anonymous"):
        assert remaps[other] == [], other


def test_the_original_is_unchanged_and_the_copy_includes_the_monitor(tmp_path: Path) -> None:
    rewritten = rewrite(tmp_path)
    assert (tmp_path / "system.launch.xml").read_text() == SYSTEM
    assert rewritten.content is not None
    assert rewritten.content.startswith(b'<?xml version="1.0" encoding="UTF-8"?>\n<!-- ')
    assert GENERATED_MARK.encode() in rewritten.content[:4096]
    root = etree.fromstring(rewritten.content)
    assert root.tag == "launch"
    (include,) = [i for i in root.iter("include") if "landing_sim_monitor" in i.get("file", "")]
    assert include.get("file") == (
        "$(find-pkg-share landing_sim_monitor)/launch/landing_sim_monitor.launch.xml"
    )
    (passed,) = include.iter("arg")
    assert (passed.get("name"), passed.get("value")) == ("fail_open", f"$(var {FAIL_OPEN_ARG})")
    args = {a.get("name"): a for a in root.iterchildren("arg")}
    assert set(args) == {FAIL_OPEN_ARG, "sim"}
    assert args[FAIL_OPEN_ARG].get("default") == "false"
    assert args[FAIL_OPEN_ARG].get("description")  # ROS 2 launch XML: description, not doc
    assert args[FAIL_OPEN_ARG].get("doc") is None
    assert b"<!-- the landing system -->" in rewritten.content  # comments kept


def test_what_cannot_be_rewritten_is_reported(tmp_path: Path) -> None:
    rewritten = rewrite(tmp_path)
    found = {(d.line, d.code) for d in rewritten.diagnostics}
    assert found == {
        (18, "launch-unknown-node"),  # /recorder: not in the graph
        (19, "launch-unknown-node"),  # $(var spy)
        (20, "launch-unknown-node"),  # no name: set in its code
        (21, "launch-unrewritten"),  # the include
    }
    messages = {d.line: d.message for d in rewritten.diagnostics}
    assert "no name attribute" in messages[20]


def test_relayed_services_remap_every_known_client_but_not_the_server(tmp_path: Path) -> None:
    interception = Interception({}, {"/a/execute_task": "/m/a/execute_task"})
    rewritten = rewrite(tmp_path, interception=interception)
    assert rewritten.content is not None
    remaps = remaps_of(rewritten.content)
    assert remaps["car"] == []  # /a/car serves it
    for client in ("vicon", "car_ctrl", "ctrl_state_machine", "launch_ctrl"):
        assert remaps[client] == [("/a/execute_task", "/m/a/execute_task")], client


NAMESPACES = """<launch>
  <node exec="x" name="ctrl_state_machine"/>
  <group>
    <push-ros-namespace namespace="a"/>
  </group>
  <node exec="x" name="pid_ctrl"/>
  <group scoped="false">
    <push_ros_namespace namespace="a"/>
  </group>
  <node exec="x" name="ctrl_state_machine"/>
  <node exec="x" name="pid_ctrl" namespace="/a"/>
  <group>
    <push-ros-namespace namespace="/elsewhere"/>
    <node exec="x" name="pid_ctrl" namespace="/a"/>
    <node exec="x" name="pid_ctrl"/>
  </group>
  <group>
    <push-ros-namespace namespace="$(var ns)"/>
    <node exec="x" name="pid_ctrl"/>
  </group>
</launch>
"""


def test_namespaces_follow_push_ros_namespace_and_group_scoping(tmp_path: Path) -> None:
    rewritten = rewrite(tmp_path, text=NAMESPACES)
    assert rewritten.remaps == {
        "/a/ctrl_state_machine": [("/a/cmd_subject_ctrl_state", "/m/a/cmd_subject_ctrl_state")],
        "/a/pid_ctrl": [("/a/task_waypose", "/m/a/task_waypose")] * 2,  # lines 11 and 14
    }
    unknown = sorted(d.line for d in rewritten.diagnostics if d.code == "launch-unknown-node")
    assert unknown == [2, 6, 15, 19]  # /ctrl_state_machine, /pid_ctrl, /elsewhere/..., $(var)


def test_private_names_resolve_in_the_node(tmp_path: Path) -> None:
    text = """<launch>
  <node exec="x" name="pid_ctrl" namespace="a">
    <remap from="~/in" to="~/waypose"/>
  </node>
</launch>
"""
    graph = Graph.build(
        [Node("/a/pid_ctrl", subscribes=frozenset({"/a/pid_ctrl/waypose"}))],
        ("file",),
        knows_subscriptions=True,
    )
    interception = Interception({"/a/pid_ctrl/waypose": "/m/a/pid_ctrl/waypose"}, {})
    rewritten = rewrite(tmp_path, text=text, interception=interception, graph=graph)
    assert rewritten.remaps == {"/a/pid_ctrl": [("~/in", "/m/a/pid_ctrl/waypose")]}


def test_set_remap_composable_nodes_argument_remaps_and_dirname_are_reported(
    tmp_path: Path,
) -> None:
    text = """<launch>
  <set_remap from="/a/task_waypose" to="/a/other"/>
  <node exec="x" name="pid_ctrl" namespace="a" ros_args="-r x:=y"/>
  <node_container pkg="rclcpp_components" exec="component_container" name="c" namespace="a">
    <composable_node pkg="landing" plugin="landing::Pid" name="pid"/>
  </node_container>
  <node exec="x" name="car" namespace="a">
    <param name="map" value="$(dirname)/map.yaml"/>
  </node>
</launch>
"""
    rewritten = rewrite(tmp_path, text=text)
    found = sorted((d.line, d.code) for d in rewritten.diagnostics)
    assert found == [
        (1, "launch-unrewritten"),  # $(dirname), reported at the root
        (2, "launch-unrewritten"),  # set_remap of a blocked topic
        (3, "launch-unrewritten"),  # remaps in ros_args come first and win
        (5, "launch-unrewritten"),  # a composable node
    ]
    messages = " ".join(d.message for d in rewritten.diagnostics)
    assert "find-pkg-share" in messages and "composable" in messages
    assert rewritten.remaps["/a/pid_ctrl"] == [("/a/task_waypose", "/m/a/task_waypose")]


@pytest.mark.parametrize(
    ("content", "reason"),
    [
        (None, "cannot read"),
        (
            b'<!DOCTYPE launch [<!ENTITY x SYSTEM "file:///etc/passwd">]><launch>&x;</launch>',
            "DOCTYPE",
        ),
        (b"<launch><node></launch>", "not well-formed"),
        (b"<launch:x xmlns:launch='urn:x'/>", "not <launch>"),
        (b"<launch>\xff</launch>", "not UTF-8"),
        (b"<launch>" + b" " * (1 << 20) + b"</launch>", "larger than"),
    ],
)
def test_a_launch_file_that_cannot_be_read_safely_is_a_launch_error(
    tmp_path: Path, content: bytes | None, reason: str
) -> None:
    path = tmp_path / "system.launch.xml"
    if content is not None:
        path.write_bytes(content)
    rewritten = rewrite_ros2(
        path,
        interception=Interception(BLOCKED, {}),
        graph=landing_graph(),
        monitor=MONITOR,
        banner="b",
    )
    assert rewritten.content is None
    (diagnostic,) = rewritten.diagnostics
    code = "io-error" if content is None else "launch-error"  # missing: an input error
    assert diagnostic.code == code and reason in diagnostic.message


def test_the_backend_writes_and_installs_the_rewritten_launch(
    landing_ros2: Path,
    tmp_path: Path,
) -> None:
    folder = tmp_path / "system"
    shutil.copytree(landing_ros2, folder, ignore=shutil.ignore_patterns("bags"))
    config = folder / "landing_sim.xml"
    config.write_text(
        config.read_text().replace(
            'period="0.5">', 'period="0.5" launch="launch/system.launch.xml">'
        )
    )
    (folder / "launch").mkdir()
    system = SYSTEM.replace(
        '  <include file="$(find-pkg-share landing)/launch/extra.launch.xml"/>\n', ""
    )
    (folder / "launch" / "system.launch.xml").write_text(system)
    result = build_ros2(config, [folder / "landing_sim.graph.yaml"])
    assert result.ok, [d.as_text() for d in result.diagnostics]
    name = "landing_sim_monitor/launch/system_monitored.launch.xml"
    remaps = remaps_of(result.files[name])
    assert ("/a/cmd_subject_ctrl_state", "/m/a/cmd_subject_ctrl_state") in remaps[
        "ctrl_state_machine"
    ]
    assert ("/a/execute_task", "/m/a/execute_task") in remaps["car_ctrl"]  # a client
    assert (folder / "launch" / "system.launch.xml").read_text() == system
    out = tmp_path / "out"
    for path, content in result.files.items():
        (out / path).parent.mkdir(parents=True, exist_ok=True)
        (out / path).write_bytes(content)
    data = dict(setup_arguments(out / "landing_sim_monitor")["data_files"])
    assert data["share/landing_sim_monitor/launch"] == [
        "launch/landing_sim_monitor.launch.xml",
        "launch/landing_sim_monitor_recorder.launch.xml",
        "launch/system_monitored.launch.xml",
    ]


def test_without_a_graph_the_launch_file_is_not_rewritten(
    landing_ros2: Path,
    tmp_path: Path,
) -> None:
    folder = tmp_path / "system"
    shutil.copytree(landing_ros2, folder, ignore=shutil.ignore_patterns("bags"))
    config = folder / "landing_sim.xml"
    text = config.read_text().replace('relative="1" ', "")  # relative grouping needs a graph
    config.write_text(text.replace('period="0.5">', 'period="0.5" launch="system.launch.xml">'))
    (folder / "system.launch.xml").write_text(SYSTEM)
    result = build_ros2(config)
    assert not result.ok and result.files == {}
    assert "launch-without-graph" in {d.code for d in result.diagnostics}
