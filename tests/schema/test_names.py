"""Tests for ROS graph-name validation."""

from __future__ import annotations

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from imrosc.schema.names import (
    BAD_NAME,
    RELATIVE_NAME,
    ROS2_INCOMPATIBLE_NAME,
    NameProblem,
    check_graph_name,
    is_global_name,
    resolve_name,
)


def codes(name: str, kind: str = "topic") -> list[tuple[str, int]]:
    return [(problem.code, problem.offset) for problem in check_graph_name(name, kind)]


@pytest.mark.parametrize(
    "name",
    ["/a", "/a/b", "/a/cmd_subject_ctrl_state", "/a/pump_control", "/A_b/c9", "/x/y_/z"],
)
def test_valid_global_names_have_no_problem(name: str) -> None:
    assert check_graph_name(name, "topic") == []


@pytest.mark.parametrize(
    ("name", "offset"),
    [
        ("", 0),
        ("/", 0),
        ("//a", 1),
        ("/a//b", 3),
        ("/a/", 2),
        ("a/", 1),
        ("1abc", 0),
        ("_abc", 0),
        ("/a b", 2),
        ("/a-b", 2),
        ("/a.b", 2),
        ("/é", 1),
        ("/a\x00", 2),
        ("/a/b\n", 4),
        ("~private", 0),
        ("~", 0),
        (" /a", 0),
    ],
)
def test_bad_names_give_one_bad_name_problem(name: str, offset: int) -> None:
    assert codes(name) == [(BAD_NAME, offset)]


def test_messages_name_the_kind_and_the_problem() -> None:
    [problem] = check_graph_name("/a//b", "topic")
    assert problem == NameProblem(BAD_NAME, "topic name '/a//b' has an empty token", 3)
    [problem] = check_graph_name("~x", "parameter")
    assert "private names are not allowed in a configuration" in problem.message
    assert problem.message.startswith("parameter name")
    [problem] = check_graph_name("/", "service")
    assert "service" in problem.message


def test_relative_name_is_a_warning_with_its_resolution() -> None:
    [problem] = check_graph_name("scan", "topic")
    assert problem.code == RELATIVE_NAME
    assert problem.offset == 0
    assert problem.message == (
        "topic name 'scan' is relative; imrosc resolves it against the root namespace as '/scan'"
    )
    assert codes("a/b", "service") == [(RELATIVE_NAME, 0)]


@pytest.mark.parametrize(
    ("name", "offset"),
    [("/a/1b", 3), ("/1b", 1), ("/a__b", 2), ("/a/b__", 4), ("/a/__b", 3)],
)
def test_ros2_incompatible_names(name: str, offset: int) -> None:
    assert codes(name) == [(ROS2_INCOMPATIBLE_NAME, offset)]


def test_relative_and_ros2_incompatible_together() -> None:
    assert codes("a__b") == [(RELATIVE_NAME, 0), (ROS2_INCOMPATIBLE_NAME, 1)]


def test_long_names_are_shortened_in_messages() -> None:
    [problem] = check_graph_name("/" + "a" * 500 + "//", "topic")
    assert len(problem.message) < 200
    assert problem.offset == 502


def test_is_global_name() -> None:
    assert is_global_name("/a")
    assert not is_global_name("a")
    assert not is_global_name("~a")
    assert not is_global_name("")


@pytest.mark.parametrize(
    ("name", "namespace", "resolved"),
    [
        ("scan", "/", "/scan"),
        ("/scan", "/robot", "/scan"),
        ("scan", "/robot", "/robot/scan"),
        ("scan", "robot/", "/robot/scan"),
        ("a/b", "/r1/", "/r1/a/b"),
        ("~x", "/ns/node", "/ns/node/x"),
        ("~/x", "/ns/node", "/ns/node/x"),
        ("", "/ns", "/ns"),
        ("", "", "/"),
    ],
)
def test_resolve_name(name: str, namespace: str, resolved: str) -> None:
    assert resolve_name(name, namespace) == resolved


def test_resolve_name_default_namespace_is_root() -> None:
    assert resolve_name("scan") == "/scan"


_NAME_CHARS = st.sampled_from("ab_Z09/~ -\x00é")


@settings(deadline=None)
@given(st.one_of(st.text(), st.text(_NAME_CHARS)), st.sampled_from(["topic", "service"]))
def test_check_graph_name_never_raises(name: str, kind: str) -> None:
    problems = check_graph_name(name, kind)
    for problem in problems:
        assert 0 <= problem.offset <= len(name)
        assert problem.message
        assert problem.code in {BAD_NAME, RELATIVE_NAME, ROS2_INCOMPATIBLE_NAME}
    if any(problem.code == BAD_NAME for problem in problems):
        assert len(problems) == 1
    else:
        resolved = resolve_name(name)
        assert is_global_name(resolved)
        expected = [problem.code for problem in problems if problem.code != RELATIVE_NAME]
        assert [problem.code for problem in check_graph_name(resolved, kind)] == expected


@settings(deadline=None)
@given(st.text(), st.text())
def test_resolve_name_never_raises(name: str, namespace: str) -> None:
    assert resolve_name(name, namespace).startswith("/")
