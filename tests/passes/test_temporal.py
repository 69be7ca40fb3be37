"""Temporal labelling: placeholders bound to the permutations of Algorithm 9."""

from __future__ import annotations

from imrosc import ir
from tests.passes.support import CASES, run_case


def temporal(case: str) -> ir.TemporalPoint:
    project, _ = run_case(CASES / "label_events" / case)
    (point,) = [p for p in project.points if isinstance(p, ir.TemporalPoint)][:1]
    return point


def test_ab_star_over_three_events_gives_six_orderings() -> None:
    point = temporal("ab-star")
    assert [c.text for c in point.patterns[0].concrete] == [
        "(ab)*",
        "(ac)*",
        "(ba)*",
        "(bc)*",
        "(ca)*",
        "(cb)*",
    ]
    assert [(label.id, label.event, label.name) for label in point.labels] == [
        ("a", "publish", "/a/cmd_subject_ctrl_state"),
        ("b", "publish", "/a/task_waypose"),
        ("c", "call", "/a/execute_task"),
    ]


def test_three_placeholders_over_three_events_and_a_pattern_of_names() -> None:
    point = temporal("mixed")
    unions, named = point.patterns
    assert len(unions.concrete) == 6
    assert unions.concrete[0].text == "((s|i)+y)*"
    assert [c.text for c in named.concrete] == ["(siy)*"]
