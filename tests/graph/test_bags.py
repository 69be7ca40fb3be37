"""The graph in bags: callerid publishers, architecture records, and bad bags skipped loudly."""

from __future__ import annotations

from pathlib import Path

import pytest

from imrosc.bags import open_bag
from imrosc.graph.bags import (
    PublisherStart,
    graph_from_bag,
    publisher_starts,
    read_bag_graphs,
)
from imrosc.graph.model import Graph
from imrosc.records import ARCH_TOPIC, PARAMS_TOPIC
from tests.graph import SECOND, Message, arch, arch_message, write_ros1_bag, write_ros2_bag

FIXTURES = Path("/work/shared/data/fixtures/rosbag2/rosbag2_tests/resources")
needs_fixtures = pytest.mark.skipif(not FIXTURES.is_dir(), reason="shared bag fixtures missing")

TALK = [
    Message("/chatter", 1 * SECOND, "hi", "/talker"),
    Message("/chatter", 2 * SECOND, "hi", "/talker2"),
    Message("/cmd", 3 * SECOND, "go", "/ctrl"),
    Message("/rosout", 4 * SECOND, "log", "/ctrl"),
    Message("/no_caller", 5 * SECOND, "x", None),
    Message(PARAMS_TOPIC, 6 * SECOND, '{"params":{},"version":1}', "/imrosc_record"),
]
FIRST = arch(
    {"/chatter": (["/talker"], ["/listener"]), "/cmd": (["/ctrl"], ["/base"])},
    {"/reset": ["/base"]},
)
SECOND_SNAPSHOT = arch(
    {"/chatter": (["/talker", "/talker2"], ["/listener", "/logger"])},
    {"/reset": ["/base"], "/stop": ["/ctrl"]},
)


def names(graph: Graph) -> dict[str, tuple[list[str], list[str], list[str]]]:
    return {
        n.name: (sorted(n.publishes), sorted(n.subscribes), sorted(n.serves))
        for n in graph.nodes.values()
    }


def test_callerids_are_publishers(tmp_path: Path) -> None:
    found = read_bag_graphs([write_ros1_bag(tmp_path / "a.bag", TALK)])
    graph, problems = found.graph, list(found.diagnostics)
    assert problems == []
    assert names(graph) == {
        "/ctrl": (["/cmd", "/rosout"], [], []),
        "/talker": (["/chatter"], [], []),
        "/talker2": (["/chatter"], [], []),
    }
    assert graph.sources == ("callerid",)
    assert not graph.knows_subscriptions


def test_publishers_start_at_their_connections_first_message(tmp_path: Path) -> None:
    bag = write_ros1_bag(
        tmp_path / "late.bag",
        [
            Message("/t", 1 * SECOND, callerid="/a"),
            Message("/t", 2 * SECOND, callerid="/a"),
            Message("/t", 16 * SECOND, callerid="/b"),
            Message("/u", 3 * SECOND, callerid="/a"),
            arch_message(1.0, arch({})),
        ],
    )
    with open_bag(bag) as reader:
        assert publisher_starts(reader) == [
            PublisherStart(1 * SECOND, "/t", "/a"),
            PublisherStart(3 * SECOND, "/u", "/a"),
            PublisherStart(16 * SECOND, "/t", "/b"),
        ]
    ros2 = write_ros2_bag(tmp_path / "ros2", [Message("/t", SECOND)])
    with open_bag(ros2) as reader:
        assert publisher_starts(reader) == []  # no callerid in ROS 2 bags


def test_records_are_merged_over_snapshots(tmp_path: Path) -> None:
    messages = [arch_message(1.0, FIRST), arch_message(2.5, SECOND_SNAPSHOT)]
    found = read_bag_graphs([write_ros1_bag(tmp_path / "a.bag", messages)])
    graph, problems = found.graph, list(found.diagnostics)
    assert problems == []
    assert graph.sources == ("records",)
    assert graph.knows_subscriptions
    assert graph.publishers("/chatter") == ("/talker", "/talker2")
    assert graph.subscribers("/chatter") == ("/listener", "/logger")
    assert graph.subscribers("/cmd") == ("/base",)
    assert graph.servers("/reset") == ("/base",)
    assert graph.servers("/stop") == ("/ctrl",)
    assert "/imrosc_record" not in graph.nodes


def test_records_and_callerids_together_records_first(tmp_path: Path) -> None:
    bag = write_ros1_bag(tmp_path / "a.bag", [*TALK, arch_message(0.5, FIRST)])
    graph, problems = graph_from_bag(bag)
    assert problems == []
    assert graph.sources == ("records", "callerid")
    assert graph.nodes["/ctrl"].publishes == {"/cmd", "/rosout"}
    assert graph.nodes["/ctrl"].subscribes == frozenset()
    assert graph.subscribers("/chatter") == ("/listener",)


@pytest.mark.parametrize("storage", ["sqlite3", "mcap"])
def test_a_ros2_bag_with_records(tmp_path: Path, storage: str) -> None:
    messages = [arch_message(1.0, FIRST), arch_message(2.0, SECOND_SNAPSHOT), *TALK[:2]]
    bag = write_ros2_bag(tmp_path / "r2", messages, storage=storage)  # type: ignore[arg-type]
    found = read_bag_graphs([bag])
    graph, problems = found.graph, list(found.diagnostics)
    assert problems == []
    assert graph.sources == ("records",)
    assert graph.subscribers("/chatter") == ("/listener", "/logger")
    assert graph.servers("/stop") == ("/ctrl",)


def test_a_bad_record_is_reported_and_the_others_used(tmp_path: Path) -> None:
    messages = [
        arch_message(1.0, FIRST),
        Message(ARCH_TOPIC, 2 * SECOND + 5, "{not json", "/imrosc_record"),
        Message(
            ARCH_TOPIC, 3 * SECOND, '{"version":2,"topics":{},"services":{}}', "/imrosc_record"
        ),
    ]
    bag = write_ros1_bag(tmp_path / "a.bag", messages)
    found = read_bag_graphs([bag])
    graph, problems = found.graph, list(found.diagnostics)
    assert graph.publishers("/cmd") == ("/ctrl",)
    assert [(d.path, d.line, d.column, d.code) for d in problems] == [
        (str(bag), 1, 1, "bag-error")
    ] * 2
    assert problems[0].message.startswith(f"{ARCH_TOPIC} message at 2.000000005 s: ")
    assert "not JSON" in problems[0].message
    assert problems[1].message.startswith(f"{ARCH_TOPIC} message at 3.000000000 s: ")
    assert "version 2" in problems[1].message


def test_a_record_topic_of_another_type_is_reported_once(tmp_path: Path) -> None:
    messages = [
        Message(ARCH_TOPIC, i * SECOND, "x" * i, "/odd", "std_msgs/msg/UInt8") for i in (1, 2)
    ]
    bag = write_ros1_bag(tmp_path / "a.bag", [*messages, *TALK[:1]])
    found = read_bag_graphs([bag])
    graph, problems = found.graph, list(found.diagnostics)
    assert [d.code for d in problems] == ["bag-error"]
    assert "std_msgs/msg/UInt8, not std_msgs/msg/String" in problems[0].message
    assert "/odd" not in graph.nodes
    assert graph.publishers("/chatter") == ("/talker",)


def test_a_bag_cut_before_its_first_message_is_reported_and_the_others_used(
    tmp_path: Path,
) -> None:
    good = write_ros1_bag(tmp_path / "good.bag", TALK)
    bad = write_ros1_bag(tmp_path / "bad.bag", [arch_message(1.0, FIRST)])
    bad.write_bytes(bad.read_bytes()[:4200])
    result = read_bag_graphs([tmp_path])
    assert result.read == (good,)
    assert [(d.path, d.code) for d in result.diagnostics] == [(str(bad), "bag-error")]
    assert result.diagnostics[0].message.startswith("cannot open bag: truncated at byte 4,200")
    assert result.graph.publishers("/chatter") == ("/talker", "/talker2")
    assert not result.graph.knows_subscriptions


def test_a_bag_cut_in_its_index_is_read_with_a_warning(tmp_path: Path) -> None:
    cut = write_ros1_bag(tmp_path / "cut.bag", [arch_message(1.0, FIRST)])
    cut.write_bytes(cut.read_bytes()[:-40])
    result = read_bag_graphs([tmp_path])
    assert result.read == (cut,)
    (warning,) = result.diagnostics
    assert (warning.code, warning.severity.value) == ("bag-recovered", "warning")
    assert warning.message.startswith("truncated at byte ")
    assert "recovered 1 message of the first 0.000 s" in warning.message
    assert result.graph.publishers("/chatter") == ("/talker",)


def test_a_non_bag_file_and_a_missing_path_are_reported(tmp_path: Path) -> None:
    good = write_ros1_bag(tmp_path / "good.bag", TALK)
    (tmp_path / "README.txt").write_text("notes")
    missing = tmp_path / "gone.bag"
    result = read_bag_graphs([tmp_path, missing])
    assert result.read == (good,)
    assert sorted((Path(d.path).name, d.code) for d in result.diagnostics) == [
        ("README.txt", "bag-error"),
        ("gone.bag", "bag-error"),
    ]
    assert result.graph.publishers("/cmd") == ("/ctrl",)


@needs_fixtures
@pytest.mark.parametrize("storage", ["sqlite3", "mcap"])
def test_an_unsupported_serialization_is_reported_and_the_others_used(
    tmp_path: Path, storage: str
) -> None:
    wrong = FIXTURES / storage / "wrong_rmw_test"
    good = write_ros1_bag(tmp_path / "good.bag", TALK)
    result = read_bag_graphs([wrong, good])
    assert result.read == (good,)
    assert [(d.path, d.code) for d in result.diagnostics] == [(str(wrong), "bag-error")]
    assert "serialization format" in result.diagnostics[0].message
    assert result.graph.publishers("/cmd") == ("/ctrl",)


def test_the_same_bag_twice_is_read_once(tmp_path: Path) -> None:
    bag = write_ros1_bag(tmp_path / "a.bag", TALK)
    assert read_bag_graphs([bag, tmp_path]).read == (bag,)


def test_no_bags_gives_the_empty_graph(tmp_path: Path) -> None:
    result = read_bag_graphs([tmp_path])
    assert result.read == ()
    assert result.graph == Graph({}, (), False)
    assert [d.code for d in result.diagnostics] == ["bag-error"]
