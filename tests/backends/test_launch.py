"""Launch rewriting: subscribers of blocked topics remapped to the monitor's relays, clients
of relayed services to its services, the monitor included, the original left alone."""

from __future__ import annotations

import os
import shutil
import subprocess
from pathlib import Path

import pytest
from lxml import etree

from imrosc.backends.launch import (
    FAIL_OPEN_ARG,
    Interception,
    MonitorLaunch,
    Rewritten,
    rewrite_ros1,
)
from imrosc.backends.registry import GENERATED_MARK
from imrosc.graph.model import Graph, Node
from tests.backends.launch_support import BLOCKED, landing_graph
from tests.backends.monitor_support import EXAMPLES, build_ros1, write_package  # noqa: F401

SYSTEM = """<?xml version="1.0"?>
<!-- the landing system -->
<launch>
  <arg name="sim" default="true"/>
  <node pkg="vicon_bridge" type="vicon" name="vicon"/>
  <group ns="a">
    <node pkg="landing" type="car" name="car"/>
    <node pkg="landing" type="car_ctrl" name="car_ctrl"/>
    <node pkg="landing" type="state_machine" name="ctrl_state_machine">
      <param name="rate" value="10"/>
    </node>
    <node pkg="landing" type="pid" name="pid_ctrl">
      <remap from="waypose" to="task_waypose"/>
    </node>
  </group>
  <node pkg="landing" type="launch" name="launch_ctrl" ns="a"/>
  <node pkg="landing" type="recorder" name="recorder"/>
  <node pkg="landing" type="spy" name="$(anon spy)"/>
  <include file="$(find landing)/launch/extra.launch"/>
</launch>
"""
MONITOR = MonitorLaunch("landing_sim_monitor", "landing_sim_monitor.launch")
ROS_PYTHON = Path("/usr/bin/python3")


def rewrite(
    tmp_path: Path,
    text: str = SYSTEM,
    interception: Interception | None = None,
    graph: Graph | None = None,
) -> Rewritten:
    path = tmp_path / "system.launch"
    path.write_text(text)
    return rewrite_ros1(
        path,
        interception=interception or Interception(BLOCKED, {}),
        graph=graph or landing_graph(),
        monitor=MONITOR,
        banner=f"{GENERATED_MARK} 0 (backend ros1) from demo.xml; do not edit",
    )


def remaps_of(content: bytes) -> dict[str, list[tuple[str, str]]]:
    root = etree.fromstring(content)
    found: dict[str, list[tuple[str, str]]] = {}
    for node in root.iter("node"):
        found[node.get("name", "")] = [
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
    for publisher_or_other in ("car_ctrl", "car", "vicon", "launch_ctrl", "recorder"):
        assert remaps[publisher_or_other] == [], publisher_or_other


def test_the_original_is_unchanged_and_the_copy_parses_and_includes_the_monitor(
    tmp_path: Path,
) -> None:
    rewritten = rewrite(tmp_path)
    assert (tmp_path / "system.launch").read_text() == SYSTEM
    assert rewritten.content is not None
    assert rewritten.content.startswith(b'<?xml version="1.0" encoding="UTF-8"?>\n<!-- ')
    assert GENERATED_MARK.encode() in rewritten.content[:4096]
    root = etree.fromstring(rewritten.content)
    assert root.tag == "launch"
    (include,) = [i for i in root.iter("include") if "landing_sim_monitor" in i.get("file", "")]
    assert include.get("file") == "$(find landing_sim_monitor)/launch/landing_sim_monitor.launch"
    (passed,) = include.iter("arg")
    assert (passed.get("name"), passed.get("value")) == ("fail_open", f"$(arg {FAIL_OPEN_ARG})")
    args = {a.get("name"): a.get("default") for a in root.iterchildren("arg")}
    assert args == {FAIL_OPEN_ARG: "false", "sim": "true"}
    assert b"<!-- the landing system -->" in rewritten.content  # comments kept


def test_what_cannot_be_rewritten_is_reported(tmp_path: Path) -> None:
    rewritten = rewrite(tmp_path)
    found = {(d.line, d.code) for d in rewritten.diagnostics}
    assert found == {
        (17, "launch-unknown-node"),  # /recorder: not in the graph
        (18, "launch-unknown-node"),  # $(anon spy)
        (19, "launch-unrewritten"),  # the include
    }
    assert all(d.path == str(tmp_path / "system.launch") for d in rewritten.diagnostics)


def test_relayed_services_remap_every_known_client_but_not_the_server(tmp_path: Path) -> None:
    interception = Interception({}, {"/a/execute_task": "/m/a/execute_task"})
    rewritten = rewrite(tmp_path, interception=interception)
    assert rewritten.content is not None
    remaps = remaps_of(rewritten.content)
    assert remaps["car"] == []  # /a/car serves it
    for client in ("vicon", "car_ctrl", "ctrl_state_machine", "launch_ctrl"):
        assert remaps[client] == [("/a/execute_task", "/m/a/execute_task")], client
    assert remaps["pid_ctrl"] == [
        ("waypose", "task_waypose"),
        ("/a/execute_task", "/m/a/execute_task"),
    ]


def test_a_node_that_publishes_and_subscribes_a_blocked_topic_is_left_alone(
    tmp_path: Path,
) -> None:
    loop = Node("/a/car_ctrl", subscribes=frozenset({"/a/task_waypose"}))
    graph = Graph.merge(landing_graph(), Graph.build([loop], ("file",), knows_subscriptions=True))
    rewritten = rewrite(tmp_path, graph=graph)
    assert "/a/car_ctrl" not in rewritten.remaps
    assert (8, "launch-unrewritten") in {(d.line, d.code) for d in rewritten.diagnostics}


def test_scope_remaps_and_dirname_are_reported(tmp_path: Path) -> None:
    text = SYSTEM.replace(
        '<group ns="a">',
        '<group ns="a">\n    <remap from="cmd" to="cmd_subject_ctrl_state"/>\n'
        '    <param name="map" value="$(dirname)/map.yaml"/>',
    )
    rewritten = rewrite(tmp_path, text=text)
    messages = [d.message for d in rewritten.diagnostics if d.code == "launch-unrewritten"]
    assert any("outside a node" in m for m in messages)
    assert any("$(dirname)" in m for m in messages)


@pytest.mark.parametrize(
    ("content", "reason"),
    [
        (None, "cannot read"),
        (
            b'<!DOCTYPE launch [<!ENTITY x SYSTEM "file:///etc/passwd">]><launch>&x;</launch>',
            "DOCTYPE",
        ),
        (b"<launch><node></launch>", "not well-formed"),
        (b"<roslaunch/>", "not <launch>"),
        (b"<launch>\xff</launch>", "not UTF-8"),
        (b"<launch>" + b" " * (1 << 20) + b"</launch>", "larger than"),
    ],
)
def test_a_launch_file_that_cannot_be_read_safely_is_a_launch_error(
    tmp_path: Path, content: bytes | None, reason: str
) -> None:
    path = tmp_path / "system.launch"
    if content is not None:
        path.write_bytes(content)
    rewritten = rewrite_ros1(
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


def _roslaunch_available() -> bool:
    if not ROS_PYTHON.exists():
        return False
    done = subprocess.run(
        [str(ROS_PYTHON), "-c", "import roslaunch.config"], capture_output=True, check=False
    )
    return done.returncode == 0


def test_the_backend_writes_the_rewritten_launch_into_the_package(
    landing_sim: Path,
    tmp_path: Path,
) -> None:
    folder = tmp_path / "system"
    shutil.copytree(landing_sim, folder, ignore=shutil.ignore_patterns("bags"))
    config = folder / "landing_sim.xml"
    config.write_text(
        config.read_text().replace('period="0.5">', 'period="0.5" launch="launch/system.launch">')
    )
    (folder / "launch").mkdir()
    system = SYSTEM.replace('  <include file="$(find landing)/launch/extra.launch"/>\n', "")
    (folder / "launch" / "system.launch").write_text(system)
    result = build_ros1(config, [folder / "landing_sim.graph.yaml"])
    assert result.ok, [d.as_text() for d in result.diagnostics]
    name = "landing_sim_monitor/launch/system_monitored.launch"
    remaps = remaps_of(result.files[name])
    assert ("/a/cmd_subject_ctrl_state", "/m/a/cmd_subject_ctrl_state") in remaps[
        "ctrl_state_machine"
    ]
    assert ("/a/execute_task", "/m/a/execute_task") in remaps["car_ctrl"]  # a client
    assert (folder / "launch" / "system.launch").read_text() == system
    if not _roslaunch_available():
        return
    out = write_package(result.files, tmp_path / "out")
    script = (
        "import roslaunch.config, sys\n"
        "config = roslaunch.config.load_config_default([sys.argv[1]], None)\n"
        "print(sorted(n.namespace + n.name for n in config.nodes))\n"
    )
    environment = {**os.environ, "ROS_PACKAGE_PATH": str(out.parent)}
    done = subprocess.run(
        [str(ROS_PYTHON), "-c", script, str(out / "launch" / "system_monitored.launch")],
        capture_output=True,
        text=True,
        check=False,
        env=environment,
        timeout=120,
    )
    assert done.returncode == 0, done.stderr
    assert "/landing_sim_monitor" in done.stdout and "/a/pid_ctrl" in done.stdout


def test_without_a_graph_the_launch_file_is_not_rewritten(
    landing_sim: Path,
    tmp_path: Path,
) -> None:
    folder = tmp_path / "system"
    shutil.copytree(landing_sim, folder, ignore=shutil.ignore_patterns("bags"))
    config = folder / "landing_sim.xml"
    text = config.read_text().replace('relative="1" ', "")  # relative grouping needs a graph
    config.write_text(text.replace('period="0.5">', 'period="0.5" launch="system.launch">'))
    (folder / "system.launch").write_text(SYSTEM)
    result = build_ros1(config)
    assert not result.ok and result.files == {}
    assert "launch-without-graph" in {d.code for d in result.diagnostics}
