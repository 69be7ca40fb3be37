"""Reading ROS 2 bags cut short or without metadata.yaml (imrosc.bagrecover_ros2): whatever
the cut, the messages read are exactly the first ones written, as many as the warning says."""

from __future__ import annotations

import random
import shutil
import tempfile
from pathlib import Path

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from rosbags.rosbag2 import CompressionFormat, CompressionMode, StoragePlugin, Writer
from rosbags.rosbag2.storage_mcap import McapReader
from rosbags.rosbag2.storage_sqlite3 import Sqlite3Reader

from imrosc.bagrecover_ros2 import RecoveringSqlite3Reader
from imrosc.bagrecover_sqlite import last_rowid, read_data, scan_messages
from imrosc.bags import BagError, discover_bags, open_bag, recovered
from tests.damage_support import reads_or_refuses_in_one_line
from tests.graph import ros2_typestore

TYPE = "std_msgs/msg/String"
COUNT = 1500
KINDS = {
    # storage, compression: rosbags' MCAP writer closes a chunk past 1 MiB, so 1,500
    # messages of ~2 KiB make two chunks
    "mcap": (StoragePlugin.MCAP, None),
    "mcap-zstd": (StoragePlugin.MCAP, CompressionMode.STORAGE),
    "sqlite3": (StoragePlugin.SQLITE3, None),
    "sqlite3-zstd-messages": (StoragePlugin.SQLITE3, CompressionMode.MESSAGE),
}


def write(path: Path, kind: str, count: int = COUNT, first: int = 0) -> Path:
    """A bag of ``count`` strings (``i`` zero-padded, then 2,000 bytes) at i * 10 ms."""
    plugin, compression = KINDS[kind]
    writer = Writer(path, version=9, storage_plugin=plugin)
    if compression is not None:
        writer.set_compression(compression, CompressionFormat.ZSTD)
    store = ros2_typestore()
    with writer:
        connection = writer.add_connection("/s", TYPE, typestore=store)
        for i in range(first, first + count):
            value = store.types[TYPE](data=f"{i:06d}" + "x" * 2000)
            writer.write(connection, i * 10_000_000, bytes(store.serialize_cdr(value, TYPE)))
    return path


def storage(bag: Path) -> Path:
    (found,) = [p for p in bag.iterdir() if p.suffix in (".db3", ".mcap")]
    return found


def values(bag: Path) -> tuple[list[int], str | None]:
    with open_bag(bag) as reader:
        found = [
            int(reader.deserialize(raw, c.msgtype).data[:6])  # type: ignore[attr-defined]
            for c, _, raw in reader.messages()
        ]
        assert reader.message_count == len(found)
        assert sum(c.msgcount for c in reader.connections) == len(found)
        return found, recovered(reader)


@pytest.fixture(scope="module", params=list(KINDS))
def whole(request: pytest.FixtureRequest, tmp_path_factory: pytest.TempPathFactory) -> Path:
    return write(tmp_path_factory.mktemp("bags") / "whole", request.param)


def copy(whole: Path, folder: Path, size: int | None = None, metadata: bool = True) -> Path:
    bag = folder / f"cut{size}{'' if metadata else '-bare'}"
    shutil.copytree(whole, bag)
    stored = storage(bag)
    if size is not None:
        stored.write_bytes(stored.read_bytes()[:size])
    if not metadata:
        (bag / "metadata.yaml").unlink()
    return bag


def test_a_whole_bag_is_read_through_its_index(whole: Path) -> None:
    found, note = values(whole)
    assert found == list(range(COUNT)) and note is None


@pytest.mark.parametrize("metadata", [True, False], ids=["metadata", "no metadata"])
def test_a_bag_cut_anywhere_gives_a_prefix_of_its_messages(
    whole: Path, metadata: bool, tmp_path: Path
) -> None:
    length = len(storage(whole).read_bytes())
    rng = random.Random(18)
    cuts = [*sorted(rng.randrange(length // 5, length) for _ in range(8)), length - 1]
    counts = []
    for size in cuts:
        bag = copy(whole, tmp_path, size, metadata)
        try:
            found, note = values(bag)
        except BagError as error:  # cut before the pages or records of the first message
            assert error.message.endswith(
                f"truncated at byte {size:,}, before its first whole message"
            )
            counts.append(0)
            continue
        assert found == list(range(len(found)))
        missing = "" if metadata else "metadata.yaml missing, "
        seconds = (len(found) - 1) * 0.01
        assert note == (
            f"{missing}truncated at byte {size:,}; recovered {len(found):,} messages of the "
            f"first {seconds:.3f} s"
        )
        counts.append(len(found))
    assert counts == sorted(counts) and counts[-1] > COUNT * 0.9
    assert len(set(counts)) > 3


def test_a_bag_without_metadata_is_read_from_its_storage(whole: Path, tmp_path: Path) -> None:
    """A recorder killed before it closed the bag leaves no metadata.yaml."""
    bag = copy(whole, tmp_path, metadata=False)
    assert discover_bags(bag) == ([bag], [])
    assert discover_bags(storage(bag)) == ([bag], [])
    assert discover_bags(tmp_path) == ([bag], [])
    found, note = values(bag)
    assert found == list(range(COUNT))
    assert note == f"metadata.yaml missing; recovered {COUNT:,} messages of the first 14.990 s"


@pytest.mark.parametrize("text", ["rosbag2_bagfile_information: {version: 9}\n", ": [\n"])
def test_a_bag_whose_metadata_is_unreadable_is_read_from_its_storage(
    text: str, tmp_path: Path
) -> None:
    bag = write(tmp_path / "bag", "mcap", 200)
    (bag / "metadata.yaml").write_text(text)
    found, note = values(bag)
    assert found == list(range(200))
    assert note == "metadata.yaml unreadable; recovered 200 messages of the first 1.990 s"


def test_a_split_bag_without_metadata_reads_its_files_in_order(tmp_path: Path) -> None:
    parts = [write(tmp_path / f"p{i}", "mcap", 100, first=100 * i) for i in range(3)]
    bag = tmp_path / "run"
    bag.mkdir()
    for i in (2, 0, 1):  # the split index orders them, not the order they were made
        shutil.copy(storage(parts[i]), bag / f"run_{i}.mcap")
    found, note = values(bag)
    assert found == list(range(300))
    assert note == "metadata.yaml missing; recovered 300 messages of the first 2.990 s"
    last = bag / "run_2.mcap"
    last.write_bytes(last.read_bytes()[:-30_000])
    found, note = values(bag)
    assert found == list(range(len(found))) and 200 < len(found) < 300
    assert note is not None
    assert note.startswith("metadata.yaml missing, run_2.mcap truncated at byte")


def test_a_folder_with_more_than_storage_files_is_searched(tmp_path: Path) -> None:
    bag = write(tmp_path / "bag", "sqlite3", 10)
    (bag / "metadata.yaml").unlink()
    (bag / "notes.txt").write_text("x")
    bags, problems = discover_bags(bag)
    assert bags == [] and len(problems) == 2
    assert "without metadata.yaml beside it" in problems[0].message


def test_a_damaged_mcap_record_stops_the_scan(tmp_path: Path) -> None:
    bag = write(tmp_path / "bag", "mcap")
    stored = storage(bag)
    reader = McapReader(stored)
    reader.open()
    second = reader.chunks[1].chunk_start_offset
    reader.close()
    data = bytearray(stored.read_bytes())
    data[second] = 0  # not a record: the scan stops before the second chunk
    data[-37:] = bytes(37)  # the footer: the file must be scanned
    stored.write_bytes(bytes(data))
    found, note = values(bag)
    assert found == list(range(len(found))) and 0 < len(found) < COUNT
    assert note == (
        f"damaged at byte {second:,}; recovered {len(found)} messages of the first "
        f"{(len(found) - 1) * 0.01:.3f} s"
    )


def test_an_empty_or_foreign_storage_file_is_one_error(tmp_path: Path) -> None:
    bag = write(tmp_path / "bag", "mcap", 10)
    stored = storage(bag)
    for content in (b"", b"\x89MC", bytes(range(256)) * 10):
        stored.write_bytes(content)
        with pytest.raises(BagError) as raised:
            values(bag)
        assert "\n" not in raised.value.message and "\\x" not in raised.value.message


@settings(
    max_examples=200,
    deadline=None,
    derandomize=True,
    database=None,
    suppress_health_check=[HealthCheck.function_scoped_fixture],
)
@given(
    kind=st.sampled_from(list(KINDS)),
    metadata=st.booleans(),
    edits=st.lists(
        st.tuples(
            st.sampled_from(["cut", "overwrite", "flip"]),
            st.floats(0, 1),
            st.binary(min_size=1, max_size=64),
        ),
        min_size=1,
        max_size=3,
    ),
)
def test_a_damaged_bag_is_read_or_refused_never_crashes(
    damaged_sources: dict[str, Path],
    kind: str,
    metadata: bool,
    edits: list[tuple[str, float, bytes]],
) -> None:
    """Whatever the damage, opening and reading a bag gives messages or a BagError."""
    with tempfile.TemporaryDirectory() as folder:
        bag = copy(damaged_sources[kind], Path(folder), metadata=metadata)
        stored = storage(bag)
        data = bytearray(stored.read_bytes())
        for edit, fraction, payload in edits:
            where = int(fraction * max(len(data) - 1, 0))
            if edit == "cut":
                del data[where:]
            elif edit == "overwrite":
                data[where : where + len(payload)] = payload
            elif data:
                data[where] ^= payload[0] | 1
        stored.write_bytes(bytes(data))
        reads_or_refuses_in_one_line(bag)


@pytest.fixture(scope="module")
def damaged_sources(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    folder = tmp_path_factory.mktemp("sources")
    return {kind: write(folder / kind, kind, 120) for kind in KINDS}


def test_the_leaves_of_a_database_are_read_when_its_tree_leads_to_none(tmp_path: Path) -> None:
    """Cut at a quarter, a database of 150,000 small messages keeps the leaves of the first
    ones but not the interior page leading to them: sqlite reads none, the page scan
    (imrosc.bagrecover_sqlite) reads the leaves."""
    plugin, _ = KINDS["sqlite3"]
    bag = tmp_path / "many"
    store = ros2_typestore()
    with Writer(bag, version=9, storage_plugin=plugin) as writer:
        connection = writer.add_connection("/x", "std_msgs/msg/Float64", typestore=store)
        for i in range(150_000):
            value = store.types["std_msgs/msg/Float64"](data=float(i))
            data = store.serialize_cdr(value, "std_msgs/msg/Float64")
            writer.write(connection, i * 1_000_000, bytes(data))
    stored = storage(bag)
    stored.write_bytes(stored.read_bytes()[: len(stored.read_bytes()) // 4])
    reader = RecoveringSqlite3Reader(stored)
    reader.open()
    try:
        assert reader._rows == 0 and reader._pages is not None  # the tree: none; the leaves
    finally:
        reader.close()
    with open_bag(bag) as opened:
        found = [
            opened.deserialize(raw, c.msgtype).data  # type: ignore[attr-defined]
            for c, _, raw in opened.messages()
        ]
        note = recovered(opened)
    assert found == [float(i) for i in range(len(found))] and len(found) > 30_000
    assert note is not None and f"recovered {len(found):,} messages" in note


@pytest.mark.parametrize("whole", [k for k in KINDS if k.startswith("sqlite3")], indirect=True)
def test_the_page_scan_reads_every_message_of_a_whole_database(whole: Path) -> None:
    """Overflow pages included (2 KiB messages do not fit a leaf's cell)."""
    stored = storage(whole)
    with stored.open("rb") as stream:
        size = stored.stat().st_size
        messages = scan_messages(stream, size)
        assert last_rowid(stream, size) == COUNT
        found = [read_data(stream, m) for m in messages]
    reader = Sqlite3Reader(stored)  # the stored bytes (compressed or not), in row order
    reader.open()
    expected = [bytes(raw) for _, _, raw in reader.messages(reader.connections)]
    reader.close()
    assert [m.rowid for m in messages] == list(range(1, COUNT + 1))
    assert found == expected
