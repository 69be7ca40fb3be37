"""Finding and opening bags: every bag is found, every broken one is a one-line BagError."""

from __future__ import annotations

import os
from pathlib import Path

import pytest
from rosbags.rosbag1 import Writer as Ros1Writer

from imrosc import bags
from imrosc.bags import (
    BagError,
    MessageError,
    discover_bags,
    open_bag,
    recovered,
    recovered_diagnostic,
    time_text,
)
from imrosc.codes import Severity
from tests.graph import SECOND, Message, write_ros1_bag, write_ros2_bag

FIXTURES = Path("/work/shared/data/fixtures/rosbag2/rosbag2_tests/resources")
WRONG_RMW = [FIXTURES / "sqlite3" / "wrong_rmw_test", FIXTURES / "mcap" / "wrong_rmw_test"]
needs_fixtures = pytest.mark.skipif(not FIXTURES.is_dir(), reason="shared bag fixtures missing")

MESSAGES = [Message("/t", i * SECOND, f"m{i}", "/talker") for i in range(1, 6)]


def ros1(path: Path) -> Path:
    return write_ros1_bag(path, MESSAGES)


# discover_bags


def test_a_ros1_file_is_a_bag(tmp_path: Path) -> None:
    bag = ros1(tmp_path / "a.bag")
    assert discover_bags(bag) == ([bag], [])


@pytest.mark.parametrize("storage", ["sqlite3", "mcap"])
def test_a_ros2_directory_is_a_bag_and_so_are_its_parts(tmp_path: Path, storage: str) -> None:
    bag = write_ros2_bag(tmp_path / "r2", MESSAGES, storage=storage)  # type: ignore[arg-type]
    assert discover_bags(bag) == ([bag], [])
    for part in bag.iterdir():
        assert discover_bags(part) == ([bag], [])


def test_directories_are_searched_recursively_and_sorted(tmp_path: Path) -> None:
    b = ros1(tmp_path / "b.bag")
    (tmp_path / "sub" / "deeper").mkdir(parents=True)
    a = ros1(tmp_path / "sub" / "deeper" / "a.bag")
    r2 = write_ros2_bag(tmp_path / "sub" / "r2", MESSAGES)
    (tmp_path / ".hidden").mkdir()
    (tmp_path / ".hidden" / "notes.txt").write_text("skipped")
    (tmp_path / ".DS_Store").write_bytes(b"\0")
    bags, problems = discover_bags(tmp_path)
    assert bags == sorted([a, b, r2])
    assert problems == []


def test_a_file_that_is_not_a_bag_is_reported_and_the_bags_still_found(tmp_path: Path) -> None:
    bag = ros1(tmp_path / "a.bag")
    (tmp_path / "notes.txt").write_text("not a bag")
    (tmp_path / "orphan.db3").write_bytes(b"")
    bags, problems = discover_bags(tmp_path)
    assert bags == [bag]
    by_path = {Path(d.path).name: d for d in problems}
    assert sorted(by_path) == ["notes.txt", "orphan.db3"]
    assert all(d.code == "bag-error" and d.severity is Severity.ERROR for d in problems)
    assert all((d.line, d.column) == (1, 1) for d in problems)
    assert "not a bag" in by_path["notes.txt"].message
    assert "metadata.yaml" in by_path["orphan.db3"].message


def test_an_unfinished_recording_is_a_ros1_bag_read_up_to_its_last_whole_record(
    tmp_path: Path,
) -> None:
    many = [Message("/t", i * SECOND // 10, f"m{i}", "/talker") for i in range(1, 400)]
    whole = write_ros1_bag(tmp_path / "whole.bag", many)
    data = whole.read_bytes()
    (tmp_path / "rec").mkdir()
    active = tmp_path / "rec" / "run.bag.active"
    active.write_bytes(data[: len(data) * 3 // 4])  # rosbag record killed: no index
    assert discover_bags(active) == ([active], [])
    assert discover_bags(tmp_path / "rec") == ([active], [])
    with open_bag(whole) as reader:
        total = sum(1 for _ in reader.messages())
    with open_bag(active) as reader:
        kept = sum(1 for _ in reader.messages())
        note = recovered(reader)
    assert 0 < kept < total
    assert note is not None and note.startswith(f"truncated at byte {active.stat().st_size:,}")


def test_a_missing_path_is_reported(tmp_path: Path) -> None:
    missing = tmp_path / "nope.bag"
    bags, problems = discover_bags(missing)
    assert bags == []
    assert [(d.path, d.code, d.message) for d in problems] == [
        (str(missing), "bag-error", "no such file or directory")
    ]


def test_an_explicit_file_that_is_not_a_bag_is_reported(tmp_path: Path) -> None:
    path = tmp_path / "data.csv"
    path.write_text("1,2\n")
    bags, problems = discover_bags(path)
    assert bags == []
    assert [d.code for d in problems] == ["bag-error"]


def test_an_empty_directory_is_reported(tmp_path: Path) -> None:
    bags, problems = discover_bags(tmp_path)
    assert bags == []
    assert [d.message for d in problems] == ["directory holds no bag"]


def test_a_symlink_loop_ends(tmp_path: Path) -> None:
    bag = ros1(tmp_path / "a.bag")
    os.symlink(tmp_path, tmp_path / "loop")
    bags, problems = discover_bags(tmp_path)
    assert bags == [bag]
    assert problems == []


# open_bag


@pytest.mark.parametrize("kind", ["ros1", "sqlite3", "mcap"])
def test_every_bag_kind_opens_and_decodes(tmp_path: Path, kind: str) -> None:
    if kind == "ros1":
        bag = ros1(tmp_path / "a.bag")
    else:
        bag = write_ros2_bag(tmp_path / "r2", MESSAGES, storage=kind)  # type: ignore[arg-type]
    with open_bag(bag) as reader:
        data = [
            getattr(reader.deserialize(raw, c.msgtype), "data", None)
            for c, _, raw in reader.messages()
        ]
    assert data == [m.data for m in MESSAGES]


def test_a_truncated_bag_is_a_bag_error(tmp_path: Path) -> None:
    bag = ros1(tmp_path / "a.bag")
    data = bag.read_bytes()
    bag.write_bytes(data[: len(data) // 2])
    with pytest.raises(BagError) as raised, open_bag(bag):
        pass
    error = raised.value
    assert error.path == bag
    assert error.message.startswith("cannot open bag:")
    assert "\n" not in error.message
    assert str(error) == f"{bag}: {error.message}"
    diagnostic = error.diagnostic()
    assert (diagnostic.path, diagnostic.line, diagnostic.column) == (str(bag), 1, 1)
    assert diagnostic.code == "bag-error"


@pytest.mark.parametrize("cut", [0, 5, 13, 200])
def test_a_bag_cut_anywhere_is_a_bag_error(tmp_path: Path, cut: int) -> None:
    bag = ros1(tmp_path / "a.bag")
    bag.write_bytes(bag.read_bytes()[:cut])
    with pytest.raises(BagError), open_bag(bag):
        pass


@pytest.mark.parametrize("storage", ["sqlite3", "mcap"])
def test_a_truncated_ros2_storage_is_a_bag_error(tmp_path: Path, storage: str) -> None:
    bag = write_ros2_bag(tmp_path / "r2", MESSAGES, storage=storage)  # type: ignore[arg-type]
    for part in bag.iterdir():
        if part.name != "metadata.yaml":
            part.write_bytes(part.read_bytes()[:100])
    with pytest.raises(BagError, match="cannot open bag"), open_bag(bag):
        pass


def test_a_damaged_chunk_is_a_bag_error_while_reading(tmp_path: Path) -> None:
    bag = write_ros1_bag(tmp_path / "a.bag", MESSAGES, compression=Ros1Writer.CompressionFormat.BZ2)
    data = bytearray(bag.read_bytes())
    data[4200:4260] = bytes(60)  # inside the first (bz2) chunk; the index at the end is intact
    bag.write_bytes(bytes(data))
    with open_bag(bag) as reader, pytest.raises(BagError, match="cannot read messages"):
        list(reader.messages())


def test_a_missing_bag_is_a_bag_error(tmp_path: Path) -> None:
    with pytest.raises(BagError, match="no such file or directory"), open_bag(tmp_path / "x.bag"):
        pass


def test_a_directory_without_metadata_is_a_bag_error(tmp_path: Path) -> None:
    with pytest.raises(BagError, match="cannot open bag"), open_bag(tmp_path):
        pass


@needs_fixtures
@pytest.mark.parametrize("bag", WRONG_RMW, ids=["sqlite3", "mcap"])
def test_an_unsupported_serialization_is_a_bag_error(bag: Path) -> None:
    with pytest.raises(BagError, match=r"serialization format .* is not supported"), open_bag(bag):
        pass


def test_an_unknown_type_and_a_corrupt_message_are_message_errors(tmp_path: Path) -> None:
    bag = ros1(tmp_path / "a.bag")
    with open_bag(bag) as reader:
        with pytest.raises(MessageError, match="unknown message type foo_msgs/msg/Bar"):
            reader.deserialize(b"", "foo_msgs/msg/Bar")
        with pytest.raises(MessageError, match="cannot decode a std_msgs/msg/String message"):
            reader.deserialize(b"\xff\xff\xff\x7f", "std_msgs/msg/String")
        assert [c.topic for c in reader.connections] == ["/t"]


def test_a_message_error_left_uncaught_is_still_a_bag_error(tmp_path: Path) -> None:
    bag = ros1(tmp_path / "a.bag")
    with pytest.raises(BagError), open_bag(bag) as reader:
        reader.deserialize(b"", "foo_msgs/msg/Bar")


def test_time_text_keeps_nanoseconds() -> None:
    assert time_text(5) == "0.000000005"
    assert time_text(12 * SECOND + 340_000_000) == "12.340000000"


def test_bag_error_fixture_points_where_it_says() -> None:
    fixture = Path(__file__).parent / "fixtures" / "bags" / "bag-error.bag"
    expected = fixture.with_suffix(".expect").read_text().split()
    with pytest.raises(BagError) as raised, open_bag(fixture):
        pass
    diagnostic = raised.value.diagnostic()
    got = [f"{diagnostic.line}:", f"{diagnostic.severity.value}:", f"[{diagnostic.code}]"]
    assert got == expected


def test_bag_recovered_fixture_points_where_it_says() -> None:
    """A bag cut in its index (the fixture: 100 bytes short) is read with a warning."""
    fixture = Path(__file__).parent / "fixtures" / "bags" / "bag-recovered.bag"
    expected = fixture.with_suffix(".expect").read_text().split()
    with open_bag(fixture) as reader:
        diagnostic = recovered_diagnostic(fixture, reader)
        assert sum(1 for _ in reader.messages()) == 20
    assert diagnostic is not None
    got = [f"{diagnostic.line}:", f"{diagnostic.severity.value}:", f"[{diagnostic.code}]"]
    assert got == expected
    assert diagnostic.message.startswith("truncated at byte ")
    assert "recovered 20 messages of the first 1.900 s" in diagnostic.message


def test_an_error_carrying_the_damaged_bytes_is_told_without_them() -> None:
    undecodable = UnicodeDecodeError("utf-8", b"\x80\xfftopic", 0, 1, "invalid start byte")
    assert bags._one_line(undecodable) == "text that is not UTF-8 (invalid start byte)"
    assert "\\x" not in bags._one_line(ValueError("bad header", b"\x00\x80op=\x03"))
