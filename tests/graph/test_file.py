"""The graph file loader: good files load exactly, bad ones give a diagnostic, never a traceback."""

from __future__ import annotations

import time
from pathlib import Path

import pytest

from imrosc.graph.file import MAX_GRAPH_BYTES, load_graph_file, parse_graph_text
from imrosc.graph.model import Graph, Node

GOOD = """\
# The example of docs/graph.md.
version: 1
nodes:
  /a/car_ctrl:
    publishes: [/a/cmd_subject_ctrl_state]
    subscribes: [/a/car_pose, /a/subject_ctrl_state, /a/subject_pose]
    serves: [/a/poll_status]
  /a/car:
    publishes: [/a/car_pose]
    serves: [/a/execute_task]
  /vicon:
    publishes:
      - /vicon/car
      - /vicon/subject
  /a/idle_node: {}
  /a/empty:
"""


def codes(text: str) -> list[tuple[int, int, str]]:
    _, found = parse_graph_text(text, "g.yaml")
    return [(d.line, d.column, d.code) for d in found]


def test_a_good_file_loads_exactly(tmp_path: Path) -> None:
    path = tmp_path / "graph.yaml"
    path.write_text(GOOD, encoding="utf-8")
    graph, problems = load_graph_file(path)
    assert problems == []
    assert graph == Graph(
        {
            "/a/car": Node(
                "/a/car", frozenset({"/a/car_pose"}), serves=frozenset({"/a/execute_task"})
            ),
            "/a/car_ctrl": Node(
                "/a/car_ctrl",
                frozenset({"/a/cmd_subject_ctrl_state"}),
                frozenset({"/a/car_pose", "/a/subject_ctrl_state", "/a/subject_pose"}),
                frozenset({"/a/poll_status"}),
            ),
            "/a/empty": Node("/a/empty"),
            "/a/idle_node": Node("/a/idle_node"),
            "/vicon": Node("/vicon", frozenset({"/vicon/car", "/vicon/subject"})),
        },
        ("file",),
        True,
    )


def test_the_docs_example_is_a_good_file() -> None:
    docs = (Path(__file__).parents[2] / "docs" / "graph.md").read_text(encoding="utf-8")
    example = docs.split("```yaml\n", 1)[1].split("```", 1)[0]
    graph, problems = parse_graph_text(example, "graph.md")
    assert problems == []
    assert graph is not None
    assert graph.subscribers("/a/car_pose") == ("/a/car_ctrl",)


def test_relative_names_are_resolved_with_a_warning() -> None:
    graph, problems = parse_graph_text("version: 1\nnodes:\n  car: {publishes: [pose]}\n", "g")
    assert [d.code for d in problems] == ["relative-name", "relative-name"]
    assert graph is not None
    assert graph.publishers("/pose") == ("/car",)


def test_bad_entries_are_left_out_and_the_rest_is_used() -> None:
    text = "version: 1\nnodes:\n  /a: {publishes: [/t, 'b a d', 3]}\n  /b//c: {}\n  /d: []\n"
    graph, problems = parse_graph_text(text, "g")
    assert graph is not None
    assert list(graph.nodes) == ["/a"]
    assert graph.nodes["/a"].publishes == {"/t"}
    assert [d.code for d in problems] == ["bad-name", "graph-invalid", "bad-name", "graph-invalid"]


def test_columns_point_at_the_offending_character() -> None:
    text = 'version: 1\nnodes:\n  /a: {publishes: [/ok, "/x y"]}\n'
    assert codes(text) == [(3, 28, "bad-name")]
    assert codes("version: 1\nnodes:\n  /a:\n    publishes: [/a//b]\n") == [(4, 20, "bad-name")]


@pytest.mark.parametrize(
    ("text", "expected"),
    [
        ("", [(1, 1, "graph-invalid")]),
        ("---\n", [(1, 1, "graph-invalid")]),
        ("just a string\n", [(1, 1, "graph-invalid")]),
        ("version: 1\n", [(1, 1, "graph-invalid")]),
        ("version: 1\nnodes:\n", [(2, 1, "graph-invalid")]),
        ("version: 1.0\nnodes: {}\n", [(1, 10, "graph-invalid")]),
        ("version: 1\nnodes: {}\n? [a]\n: 1\n", [(3, 3, "graph-invalid")]),
        ("version: 1\nnodes: {/a: {publishes: }}\n", [(2, 14, "graph-invalid")]),
        ("version: [\n", [(2, 1, "graph-syntax")]),
        ("version: 1\nnodes: {}\n\x07\n", [(3, 1, "graph-syntax")]),
        (
            "version: 1\nnodes: {}\nx: &a 1\ny: *a\nz: !t 3\n",
            [(3, 4, "graph-invalid"), (4, 4, "graph-invalid"), (5, 4, "graph-invalid")],
        ),
        ("version: 1\nnodes: {}\n...\n---\nversion: 1\n", [(4, 1, "graph-invalid")]),
    ],
)
def test_bad_files_give_one_diagnostic_each(
    text: str, expected: list[tuple[int, int, str]]
) -> None:
    graph, problems = parse_graph_text(text, "g.yaml")
    assert [(d.line, d.column, d.code) for d in problems] == expected
    assert all("\n" not in d.message for d in problems)
    if any(d.code == "graph-syntax" for d in problems):
        assert graph is None


def test_deep_nesting_is_refused_before_composing() -> None:
    text = "version: 1\nnodes: " + "[" * 5000 + "]" * 5000 + "\n"
    graph, problems = parse_graph_text(text, "g")
    assert graph is None
    assert [(d.code, "nested deeper" in d.message) for d in problems] == [("graph-invalid", True)]


def test_a_billion_laughs_is_refused_fast() -> None:
    lines = ["version: 1", "nodes: {}", 'l0: &l0 ["lol", "lol", "lol", "lol", "lol"]']
    lines += [f"l{i}: &l{i} [" + ", ".join([f"*l{i - 1}"] * 10) + "]" for i in range(1, 30)]
    started = time.monotonic()
    graph, problems = parse_graph_text("\n".join(lines) + "\n", "g")
    assert time.monotonic() - started < 2
    assert graph is None
    assert {d.code for d in problems} == {"graph-invalid"}
    assert len(problems) == 30 + 29  # each anchor and the first use of each alias


def test_a_missing_file_is_an_io_error(tmp_path: Path) -> None:
    graph, problems = load_graph_file(tmp_path / "none.yaml")
    assert graph is None
    assert [(d.code, d.path) for d in problems] == [("io-error", str(tmp_path / "none.yaml"))]
    assert problems[0].message.startswith("cannot read graph file:")


def test_a_directory_is_an_io_error(tmp_path: Path) -> None:
    graph, problems = load_graph_file(tmp_path, label="dir.yaml")
    assert graph is None
    assert [(d.code, d.message) for d in problems] == [
        ("io-error", "cannot read graph file: it is a directory")
    ]


def test_the_size_cap(tmp_path: Path) -> None:
    assert MAX_GRAPH_BYTES == 1024 * 1024
    path = tmp_path / "big.yaml"
    path.write_text("version: 1\nnodes: {}\n" + "#" * 100 + "\n", encoding="utf-8")
    graph, problems = load_graph_file(path, max_bytes=50)
    assert graph is None
    assert [(d.code, d.line) for d in problems] == [("graph-invalid", 1)]
    assert load_graph_file(path, max_bytes=1000)[1] == []


def test_encodings(tmp_path: Path) -> None:
    path = tmp_path / "g.yaml"
    path.write_bytes(b"\xef\xbb\xbfversion: 1\nnodes: {}\n")
    assert load_graph_file(path)[1] == []
    path.write_bytes(b"version: 1\nnodes: {/caf\xe9: {}}\n")
    graph, problems = load_graph_file(path)
    assert graph is None
    assert [(d.line, d.column, d.code) for d in problems] == [(2, 13, "encoding-error")]
