"""The graph model: queries, merging, documents and the two renderings."""

from __future__ import annotations

from ruamel.yaml import YAML

from imrosc.graph.file import parse_graph_text
from imrosc.graph.model import Graph, Node
from tests.graph import arch

SNAPSHOT = arch(
    {
        "/a/car_pose": (["/a/car"], ["/a/car_ctrl", "/a/arb"]),
        "/a/cmd": (["/a/car_ctrl"], ["/a/car"]),
    },
    {"/a/execute_task": ["/a/car"]},
)
RECORDS = Graph.from_snapshot(SNAPSHOT, "records")
CALLERS = Graph.build(
    [Node("/vicon", publishes=frozenset({"/vicon/car"})), Node("/a/car", frozenset({"/x"}))],
    ["callerid"],
    knows_subscriptions=False,
)


def test_queries_are_sorted() -> None:
    assert RECORDS.publishers("/a/car_pose") == ("/a/car",)
    assert RECORDS.subscribers("/a/car_pose") == ("/a/arb", "/a/car_ctrl")
    assert RECORDS.servers("/a/execute_task") == ("/a/car",)
    assert RECORDS.topics() == ("/a/car_pose", "/a/cmd")
    assert RECORDS.services() == ("/a/execute_task",)
    assert RECORDS.publishers("/unknown") == ()
    assert list(RECORDS.nodes) == ["/a/arb", "/a/car", "/a/car_ctrl"]


def test_a_snapshot_knows_subscriptions() -> None:
    assert RECORDS.knows_subscriptions
    assert RECORDS.sources == ("records",)
    assert RECORDS.nodes["/a/car"] == Node(
        "/a/car", frozenset({"/a/car_pose"}), frozenset({"/a/cmd"}), frozenset({"/a/execute_task"})
    )


def test_merge_unites_edges_and_keeps_sources_in_order_once() -> None:
    merged = Graph.merge(RECORDS, CALLERS, RECORDS)
    assert merged.sources == ("records", "callerid")
    assert merged.knows_subscriptions
    assert merged.nodes["/a/car"].publishes == {"/a/car_pose", "/x"}
    assert merged.publishers("/vicon/car") == ("/vicon",)
    assert list(merged.nodes) == sorted(merged.nodes)
    assert not Graph.merge(CALLERS).knows_subscriptions


def test_merging_nothing_is_the_empty_graph() -> None:
    assert Graph.merge() == Graph({}, (), False)
    assert Graph.merge(RECORDS) == RECORDS


def test_document_is_sorted_and_leaves_out_empty_lists() -> None:
    graph = Graph.merge(RECORDS, Graph.build([Node("/idle")], ["file"], True))
    assert graph.to_document() == {
        "version": 1,
        "nodes": {
            "/a/arb": {"subscribes": ["/a/car_pose"]},
            "/a/car": {
                "publishes": ["/a/car_pose"],
                "subscribes": ["/a/cmd"],
                "serves": ["/a/execute_task"],
            },
            "/a/car_ctrl": {"publishes": ["/a/cmd"], "subscribes": ["/a/car_pose"]},
            "/idle": {},
        },
    }


def test_text_rendering() -> None:
    assert CALLERS.render_text() == (
        "# sources: callerid; subscriptions unknown\n"
        "/a/car\n"
        "  publishes /x\n"
        "/vicon\n"
        "  publishes /vicon/car\n"
    )
    assert Graph.merge().render_text() == "# sources: none\n"


def test_yaml_loads_back_to_the_same_graph() -> None:
    graph = Graph.merge(RECORDS, CALLERS, Graph.build([Node("/idle")], ["file"], True))
    text = graph.render_yaml()
    loaded, problems = parse_graph_text(text, "out.yaml")
    assert problems == []
    assert loaded is not None
    assert loaded.nodes == graph.nodes
    assert loaded.knows_subscriptions
    assert loaded.sources == ("file",)
    assert YAML(typ="safe").load(text) == graph.to_document()


def test_empty_graph_yaml_loads_back() -> None:
    loaded, problems = parse_graph_text(Graph.merge().render_yaml(), "empty.yaml")
    assert problems == []
    assert loaded is not None
    assert loaded.nodes == {}


def test_unusual_names_are_quoted_in_yaml() -> None:
    odd = Graph.build([Node("/a: b", frozenset({"#x", "/ok"}))], ["callerid"], False)
    text = odd.render_yaml()
    assert '"/a: b":' in text
    assert '- "#x"' in text
    assert "- /ok" in text
    assert YAML(typ="safe").load(text) == odd.to_document()


def test_renderings_are_deterministic() -> None:
    first = Graph.merge(RECORDS, CALLERS)
    second = Graph.merge(CALLERS, RECORDS)
    assert first.nodes == second.nodes
    assert first.render_text().splitlines()[1:] == second.render_text().splitlines()[1:]
    assert first.render_yaml().splitlines()[1:] == second.render_yaml().splitlines()[1:]
