"""The landing example on both middlewares: ``examples/uav_landing.xml`` names the system's
roslaunch file (``launch``) and its ROS 2 launch XML (``launch_ros2``); ``imrosc build``
rewrites the first for ``--backend ros1`` and the second for ``--backend ros2``.

The two launch files must describe the same system: the same nodes (names, namespaces,
package, executable, parameters, the stealing scenario's node started on the same
condition) and the same arguments, and their rewritten copies must remap the same names of
the same nodes. The ROS 2 package built from the example is started live in
``test_ros2_example_live.py``.
"""

from __future__ import annotations

import shutil
from dataclasses import dataclass
from pathlib import Path

from lxml import etree

from imrosc import ir
from imrosc.build import build
from imrosc.lower import lower
from imrosc.schema.loader import load_config
from tests.backends.example_ros2_support import (
    CONFIG,
    EXAMPLES,
    GRAPH,
    PACKAGE,
    ROS1_LAUNCH,
    ROS2_LAUNCH,
    copy_example,
)


@dataclass(frozen=True)
class LaunchNode:
    """What a launch file's ``<node>`` starts and with what."""

    pkg: str | None
    executable: str | None
    params: dict[str | None, str | None]
    conditional: bool
    remaps: list[tuple[str | None, str | None]]


def _nodes(path: Path, ros2: bool) -> dict[str, LaunchNode]:
    """Each ``<node>`` of a launch file by its full name."""
    found: dict[str, LaunchNode] = {}
    for node in etree.parse(str(path)).getroot().iter("node"):
        namespace = node.get("namespace" if ros2 else "ns", "")
        name = "/" + "/".join(p for p in (namespace.strip("/"), node.get("name", "")) if p)
        found[name] = LaunchNode(
            pkg=node.get("pkg"),
            executable=node.get("exec" if ros2 else "type"),
            params={p.get("name"): p.get("value") for p in node.iter("param")},
            conditional=node.get("if") is not None,
            remaps=sorted((r.get("from"), r.get("to")) for r in node.iter("remap")),
        )
    return found


def _args(path: Path) -> dict[str, str | None]:
    root = etree.parse(str(path)).getroot()
    return {a.get("name", ""): a.get("default") for a in root.iter("arg")}


def _substituted(value: str | None) -> str | None:
    """A parameter value with ROS 1's ``$(arg x)`` written as ROS 2's ``$(var x)``."""
    return None if value is None else value.replace("$(arg ", "$(var ")


def test_the_ros1_and_ros2_launch_files_of_the_example_start_the_same_system() -> None:
    ros1 = _nodes(EXAMPLES / ROS1_LAUNCH, ros2=False)
    ros2 = _nodes(EXAMPLES / ROS2_LAUNCH, ros2=True)
    assert set(ros1) == set(ros2)
    assert "/a/car_ctrl" in ros2 and len(ros2) == 10
    for name, node in ros1.items():
        other = ros2[name]
        assert (node.pkg, node.executable, node.conditional) == (
            other.pkg,
            other.executable,
            other.conditional,
        ), name
        assert {k: _substituted(v) for k, v in node.params.items()} == other.params, name
        assert node.remaps == other.remaps == [], name
    assert _args(EXAMPLES / ROS1_LAUNCH) == _args(EXAMPLES / ROS2_LAUNCH)


def test_launch_ros2_is_lowered_and_round_trips_through_the_ir() -> None:
    loaded, problems = load_config(EXAMPLES / CONFIG)
    assert loaded is not None, problems
    project = lower(loaded)
    assert project.monitor is not None
    assert (project.monitor.launch, project.monitor.launch_ros2) == (ROS1_LAUNCH, ROS2_LAUNCH)
    assert ir.project_from_json(ir.to_json(project)) == project


def test_each_backend_rewrites_its_own_launch_file_with_the_same_remaps(
    landing_example: Path, tmp_path: Path
) -> None:
    graph = [landing_example / GRAPH]
    rewritten: dict[str, Path] = {}
    for backend, name in (
        ("ros1", "launch/system_monitored.launch"),
        ("ros2", "launch/system_monitored.launch.xml"),
    ):
        result = build(landing_example / CONFIG, backend, graph_files=graph)
        assert result.ok, [d.as_text() for d in result.diagnostics]
        # the stealing scenario's node is not in the graph, on both
        notes = [(d.code, Path(d.path).name) for d in result.diagnostics]
        source = Path(ROS2_LAUNCH if backend == "ros2" else ROS1_LAUNCH).name
        assert notes == [("launch-unknown-node", source)], notes
        rewritten[backend] = tmp_path / f"rewritten.{backend}"
        rewritten[backend].write_bytes(result.files[f"{PACKAGE}/{name}"])
    ros1 = _nodes(rewritten["ros1"], ros2=False)
    ros2 = _nodes(rewritten["ros2"], ros2=True)
    assert {n: v.remaps for n, v in ros1.items()} == {n: v.remaps for n, v in ros2.items()}
    blocked = ("/a/cmd_subject_ctrl_state", "/m/a/cmd_subject_ctrl_state")
    assert blocked in ros2["/a/ctrl_state_machine"].remaps
    assert ("/a/car_pose", "/m/a/car_pose") in ros2["/a/car_ctrl"].remaps
    # the waypoints are not blocked (examples/uav_landing.xml says why): no relay between
    assert not any("task_waypose" in (to or "") for _, to in ros2["/a/pid_ctrl"].remaps)
    included = etree.parse(str(rewritten["ros2"])).getroot().findall("include")
    assert [i.get("file") for i in included] == [
        f"$(find-pkg-share {PACKAGE})/launch/{PACKAGE}.launch.xml"
    ]


def test_without_launch_ros2_the_ros2_backend_says_which_attribute_to_add(
    landing_example: Path, tmp_path: Path
) -> None:
    config = copy_example(tmp_path)
    shutil.copy(landing_example / "landing.inv", tmp_path / "landing.inv")
    text = config.read_text(encoding="utf-8")
    config.write_text(text.replace(f' launch_ros2="{ROS2_LAUNCH}"', ""), encoding="utf-8")
    result = build(config, "ros2", graph_files=[tmp_path / GRAPH])
    assert not result.ok
    (problem,) = [d for d in result.diagnostics if d.code == "launch-error"]
    assert "launch='launch/landing.launch'" in problem.message
    assert "<monitor launch_ros2=...>" in problem.message
    assert build(config, "ros1", graph_files=[tmp_path / GRAPH]).ok


def test_a_launch_ros2_that_is_no_launch_xml_is_named_in_the_error(
    landing_example: Path, tmp_path: Path
) -> None:
    config = copy_example(tmp_path)
    shutil.copy(landing_example / "landing.inv", tmp_path / "landing.inv")
    text = config.read_text(encoding="utf-8")
    config.write_text(text.replace(ROS2_LAUNCH, "launch/landing.launch.py"), encoding="utf-8")
    result = build(config, "ros2", graph_files=[tmp_path / GRAPH])
    (problem,) = [d for d in result.diagnostics if d.code == "launch-error"]
    assert "launch_ros2='launch/landing.launch.py'" in problem.message
    assert "<monitor launch_ros2" not in problem.message
    ros1 = build(config, "ros1", graph_files=[tmp_path / GRAPH])
    assert ros1.ok, [d.as_text() for d in ros1.diagnostics]  # ROS 1 ignores launch_ros2
