"""The launch files the launch rewriting tests share."""

from __future__ import annotations

from imrosc.graph.file import load_graph_file
from imrosc.graph.model import Graph
from tests.backends.monitor_support import EXAMPLES

BLOCKED = {
    "/a/cmd_subject_ctrl_state": "/m/a/cmd_subject_ctrl_state",
    "/a/task_waypose": "/m/a/task_waypose",
}


def landing_graph() -> Graph:
    graph, problems = load_graph_file(EXAMPLES / "landing_sim.graph.yaml")
    assert graph is not None, problems
    return graph
