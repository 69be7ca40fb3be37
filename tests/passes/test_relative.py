"""Relative grouping on the graph of thesis Figure 3.6 (section 3.3)."""

from __future__ import annotations

from pathlib import Path

from imrosc import ir
from tests.passes.support import CASES, run_case


def grouped(case: str) -> set[str]:
    project, _ = run_case(CASES / "group_relative" / case)
    point = project.points[0]
    assert isinstance(point, ir.PublishPoint)
    return {point.topic, *(i.name for i in point.inputs)}


def test_relative_1_groups_four_topics() -> None:
    assert grouped("figure-3.6-relative-1") == {
        "/a/cmd_subject_ctrl_state",
        "/a/car_pose",
        "/a/subject_ctrl_state",
        "/a/subject_pose",
    }


def test_relative_2_groups_six_topics() -> None:
    assert grouped("figure-3.6-relative-2") == grouped("figure-3.6-relative-1") | {
        "/a/subject_status",
        "/vicon/car",
    }


def test_cyclic_graph_terminates_with_every_topic_once() -> None:
    assert grouped("cyclic-graph") == {"/t1", "/t2", "/t3"}


def test_explicit_topics_join_the_group(tmp_path: Path) -> None:
    project, _ = run_case(CASES / "group_relative" / "explicit-topics")
    first, second = project.points[0], project.points[1]
    assert isinstance(first, ir.PublishPoint) and isinstance(second, ir.PublishPoint)
    assert ir.InputTopic("/a/car_pose", 1, explicit=True) in first.inputs
    assert ir.InputTopic("/vicon/car", 1, explicit=True) in first.inputs
    assert second.inputs == (ir.InputTopic("/a/subject_pose", 1, explicit=True),)
