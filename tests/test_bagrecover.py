"""Reading ROS 1 bags cut short or never indexed (imrosc.bagrecover): whatever the cut, the
messages read are exactly the first ones written, as many as the warning says."""

from __future__ import annotations

import random
import struct
import tempfile
from pathlib import Path

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from rosbags.rosbag1 import Reader, Writer

from imrosc.bags import BagError, open_bag, recovered
from tests.damage_support import reads_or_refuses_in_one_line
from tests.translate import build, store

TYPE = "std_msgs/msg/Float64"
COUNT = 3000
COMPRESSIONS = {
    "none": None,
    "bz2": Writer.CompressionFormat.BZ2,
    "lz4": Writer.CompressionFormat.LZ4,
}


def write(path: Path, compression: str, count: int = COUNT) -> Path:
    """A bag of ``count`` Float64 messages (value i at i * 10 ms) in chunks of ~16 KiB."""
    writer = Writer(path)
    if COMPRESSIONS[compression] is not None:
        writer.set_compression(COMPRESSIONS[compression])  # type: ignore[arg-type]
    writer.chunk_threshold = 16 * 1024
    writer.open()
    connection = writer.add_connection("/x", TYPE, typestore=store(), callerid="/n")
    for i in range(count):
        data = store().serialize_ros1(build(TYPE, {"data": float(i)}), TYPE)
        writer.write(connection, i * 10_000_000, bytes(data))
    writer.close()
    return path


def values(bag: Path) -> tuple[list[float], str | None]:
    with open_bag(bag) as reader:
        found = [
            float(reader.deserialize(raw, c.msgtype).data)  # type: ignore[attr-defined]
            for c, _, raw in reader.messages()
        ]
        assert reader.message_count == len(found)
        return found, recovered(reader)


@pytest.fixture(scope="module", params=list(COMPRESSIONS))
def whole(request: pytest.FixtureRequest, tmp_path_factory: pytest.TempPathFactory) -> Path:
    return write(tmp_path_factory.mktemp("bags") / "whole.bag", request.param)


def test_a_whole_bag_is_read_through_its_index(whole: Path) -> None:
    found, note = values(whole)
    assert found == [float(i) for i in range(COUNT)] and note is None


def test_a_bag_cut_anywhere_gives_a_prefix_of_its_messages(whole: Path, tmp_path: Path) -> None:
    data = whole.read_bytes()
    rng = random.Random(18)
    cuts = [*sorted(rng.randrange(4200, len(data)) for _ in range(12)), len(data) - 1]
    counts = []
    for size in cuts:
        bag = tmp_path / f"cut{size}.bag"
        bag.write_bytes(data[:size])
        try:
            found, note = values(bag)
        except BagError as error:  # cut in the first chunk of a compressed bag
            assert "before its first whole message" in error.message
            counts.append(0)
            continue
        assert found == [float(i) for i in range(len(found))]
        assert note is not None and note.startswith(f"truncated at byte {size:,}; ")
        seconds = (len(found) - 1) * 0.01
        assert f"recovered {len(found):,} messages of the first {seconds:.3f} s" in note
        counts.append(len(found))
    assert counts == sorted(counts) and counts[-1] == COUNT  # the index alone was lost
    assert len(set(counts)) > 4


def test_a_bag_never_indexed_is_read_whole(whole: Path, tmp_path: Path) -> None:
    data = bytearray(whole.read_bytes())
    field = data.index(b"index_pos=") + len(b"index_pos=")
    (index_pos,) = struct.unpack_from("<Q", data, field)
    data[field : field + 8] = bytes(8)
    for name, content in (("kept", data), ("dropped", data[:index_pos])):
        bag = tmp_path / f"{name}.bag"
        bag.write_bytes(bytes(content))
        found, note = values(bag)
        assert found == [float(i) for i in range(COUNT)]
        assert note == (
            f"not indexed (the recording was interrupted); recovered {COUNT:,} messages of "
            f"the first {(COUNT - 1) * 0.01:.3f} s"
        )


def test_the_open_chunk_of_an_interrupted_recording_is_read(tmp_path: Path) -> None:
    """rosbag record writes a chunk's sizes when it closes it: a killed recording leaves
    its last chunk with sizes 0 and its records after them."""
    bag = write(tmp_path / "a.bag", "none")
    with Reader(bag) as reader:
        last = reader.chunk_infos[-1].pos
    data = bytearray(bag.read_bytes())
    (header_length,) = struct.unpack_from("<I", data, last)
    size_field = data.index(b"size=", last) + len(b"size=")
    data[size_field : size_field + 4] = bytes(4)
    data[last + 4 + header_length : last + 8 + header_length] = bytes(4)
    field = data.index(b"index_pos=") + len(b"index_pos=")
    data[field : field + 8] = bytes(8)
    cut = bag.with_name("active.bag")
    cut.write_bytes(bytes(data[: len(data) - 5000]))  # in the index records after the chunk
    found, note = values(cut)
    assert found == [float(i) for i in range(len(found))]
    assert COUNT - 400 < len(found) < COUNT and note is not None and "truncated" in note


def test_a_damaged_record_stops_the_scan(tmp_path: Path) -> None:
    bag = write(tmp_path / "a.bag", "lz4", 500)
    data = bytearray(bag.read_bytes())
    field = data.index(b"index_pos=") + len(b"index_pos=")
    (index_pos,) = struct.unpack_from("<Q", data, field)
    data[index_pos + 4 : index_pos + 20] = b"\xff" * 16  # the fields of the index's first record
    bag.write_bytes(bytes(data))
    found, note = values(bag)
    assert found == [float(i) for i in range(500)]
    assert note is not None and note.startswith(f"damaged at byte {index_pos:,}; recovered 500 ")


def test_a_damaged_bag_header_is_said_so(tmp_path: Path) -> None:
    bag = write(tmp_path / "a.bag", "none", 50)
    data = bytearray(bag.read_bytes())
    data[17:30] = b"\xff" * 13  # the fields of the bag header record
    bag.write_bytes(bytes(data))
    with pytest.raises(BagError, match=r"cannot open bag: its header record is damaged$"):
        values(bag)


def test_an_index_pointing_nowhere_is_scanned_past(tmp_path: Path) -> None:
    bag = write(tmp_path / "a.bag", "bz2", 500)
    data = bytearray(bag.read_bytes())
    field = data.index(b"index_pos=") + len(b"index_pos=")
    data[field : field + 8] = struct.pack("<Q", 20)
    bag.write_bytes(bytes(data))
    found, note = values(bag)
    assert found == [float(i) for i in range(500)]
    assert note is not None and note.startswith("index damaged; recovered 500 messages")


@settings(
    max_examples=150,
    deadline=None,
    derandomize=True,
    database=None,
    suppress_health_check=[HealthCheck.function_scoped_fixture],
)
@given(
    compression=st.sampled_from(list(COMPRESSIONS)),
    edits=st.lists(
        st.tuples(
            st.sampled_from(["cut", "overwrite", "flip", "unindex"]),
            st.floats(0, 1),
            st.binary(min_size=1, max_size=64),
        ),
        min_size=1,
        max_size=3,
    ),
)
def test_a_damaged_bag_is_read_or_refused_never_crashes(
    damaged_sources: dict[str, bytes],
    compression: str,
    edits: list[tuple[str, float, bytes]],
) -> None:
    """Whatever the damage, opening and reading a bag gives messages or a BagError."""
    data = bytearray(damaged_sources[compression])
    for kind, fraction, payload in edits:
        where = int(fraction * max(len(data) - 1, 0))
        if kind == "cut":
            del data[where:]
        elif kind == "overwrite":
            data[where : where + len(payload)] = payload
        elif kind == "flip" and data:
            data[where] ^= payload[0] | 1
        elif b"index_pos=" in data:
            field = data.index(b"index_pos=") + len(b"index_pos=")
            data[field : field + 8] = bytes(8)
    with tempfile.TemporaryDirectory() as folder:
        bag = Path(folder) / "x.bag"
        bag.write_bytes(bytes(data))
        reads_or_refuses_in_one_line(bag)


@pytest.fixture(scope="module")
def damaged_sources(tmp_path_factory: pytest.TempPathFactory) -> dict[str, bytes]:
    folder = tmp_path_factory.mktemp("sources")
    return {name: write(folder / f"{name}.bag", name, 600).read_bytes() for name in COMPRESSIONS}
