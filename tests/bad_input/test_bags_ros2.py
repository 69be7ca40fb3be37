"""Bad ROS 2 bags in the catalogue of bad inputs (issue 18, item 5): bags whose storage file
(sqlite3 or MCAP) was cut short, or whose metadata.yaml is missing (a recorder killed before
it closed the bag) or unreadable, read by every command that reads bags.

As for ROS 1 bags (tests/bad_input/test_bags.py): a bag cut after some whole messages is read
up to its last whole record, with one warning naming the bag, where it ends and how much was
recovered; a bag cut before its first whole message is one error line naming it. No
traceback, and no file that was there before changes (the bag itself included).
"""

from __future__ import annotations

import re
import shutil
from collections.abc import Iterator
from pathlib import Path

import pytest
from click.testing import CliRunner
from rosbags.rosbag2 import StoragePlugin, Writer

from imrosc.cli import main
from tests.bad_input.support import COMMANDS, CONFIG, RECOVERED, run, snapshot
from tests.graph import ros2_typestore

PAIRS = 400


def good_run_ros2(path: Path, offset: float, storage: str, odd: bool = False) -> Path:
    """The ROS 2 bag of tests.translate.good_run, ten times as long: ``/in`` (Int32) then
    ``/out`` (Float64 0..4) 10 ms later, every 0.1 s from ``offset``."""
    plugin = StoragePlugin.MCAP if storage == "mcap" else StoragePlugin.SQLITE3
    store = ros2_typestore()
    with Writer(path, version=9, storage_plugin=plugin) as writer:
        inputs = writer.add_connection("/in", "std_msgs/msg/Int32", typestore=store)
        outputs = writer.add_connection("/out", "std_msgs/msg/Float64", typestore=store)
        for i in range(PAIRS):
            at = int((offset + i * 0.1) * 1e9)
            value = float(i % 5)
            if odd and i in (3, 4):
                value = [float("nan"), float("inf")][i - 3]
            for connection, fields, time in ((inputs, i % 3, at), (outputs, value, at + 10**7)):
                message = store.types[connection.msgtype](data=fields)
                writer.write(
                    connection, time, bytes(store.serialize_cdr(message, connection.msgtype))
                )
    return path


@pytest.fixture(scope="module", params=["sqlite3", "mcap"])
def template2(request: pytest.FixtureRequest, tmp_path_factory: pytest.TempPathFactory) -> Path:
    folder = tmp_path_factory.mktemp("project2")
    (folder / "p.xml").write_text(CONFIG)
    for name in ("train", "ok", "bad"):
        (folder / "bags" / name).mkdir(parents=True)
    storage = str(request.param)
    good_run_ros2(folder / "bags" / "train" / "r1", 0.0, storage)
    good_run_ros2(folder / "bags" / "train" / "r2", 100.0, storage)
    good_run_ros2(folder / "bags" / "ok" / "s1", 200.0, storage)
    good_run_ros2(folder / "bags" / "bad" / "f1", 300.0, storage, odd=True)
    done = CliRunner().invoke(main, ["infer", str(folder / "p.xml"), "-j", "1", "-q"])
    assert done.exit_code == 0, done.output
    return folder


@pytest.fixture
def project2(template2: Path, tmp_path: Path) -> Iterator[Path]:
    folder = tmp_path / "project"
    shutil.copytree(template2, folder, symlinks=True)
    yield folder


def commands() -> dict[str, tuple[tuple[str, ...], str, set[int]]]:
    """The commands of the ROS 1 catalogue, each reading the same bag as a ROS 2 folder."""
    return {
        name: (tuple(a.replace(".bag", "") for a in args), bag.replace(".bag", ""), statuses)
        for name, (args, bag, statuses) in COMMANDS.items()
    }


def storage_of(bag: Path) -> Path:
    (found,) = [p for p in bag.iterdir() if p.suffix in (".db3", ".mcap")]
    return found


def unchanged_but_written(before: dict[str, str], after: dict[str, str], command: str) -> bool:
    written = {"p.inv"} if command == "infer" else set()  # its own output, rewritten
    kept = {k: v for k, v in after.items() if k in before and k not in written}
    return kept == {k: v for k, v in before.items() if k not in written}


@pytest.mark.parametrize("fraction", [0.8, 0.97])
@pytest.mark.parametrize("command", list(COMMANDS))
def test_a_ros2_bag_cut_short_is_read_up_to_its_last_whole_record(
    command: str, fraction: float, project2: Path
) -> None:
    args, damaged, statuses = commands()[command]
    stored = storage_of(project2 / damaged)
    data = stored.read_bytes()
    size = int(len(data) * fraction)
    stored.write_bytes(data[:size])
    before = snapshot(project2)
    status, _, stderr = run(project2, args)
    assert status in statuses, (status, stderr)
    lines = [line for line in stderr.splitlines() if RECOVERED in line]
    assert len(lines) == 1, stderr
    (line,) = lines
    assert str(project2 / damaged) in line, line
    assert f"truncated at byte {size:,}; recovered " in line, line
    assert re.search(r"messages? of the first \d+\.\d{3} s( \[bag-recovered\])?$", line), line
    assert unchanged_but_written(before, snapshot(project2), command)


@pytest.mark.parametrize("command", list(COMMANDS))
def test_a_ros2_bag_without_metadata_is_read_from_its_storage(command: str, project2: Path) -> None:
    """``ros2 bag record`` killed: the storage file and no metadata.yaml."""
    args, damaged, statuses = commands()[command]
    (project2 / damaged / "metadata.yaml").unlink()
    before = snapshot(project2)
    status, _, stderr = run(project2, args)
    assert status in statuses - {1, 3}, (status, stderr)  # every message is there
    (line,) = [line for line in stderr.splitlines() if RECOVERED in line]
    assert str(project2 / damaged) in line
    assert f"metadata.yaml missing; recovered {2 * PAIRS} messages of the first 39.910 s" in line
    assert unchanged_but_written(before, snapshot(project2), command)


def test_a_ros2_bag_whose_metadata_is_unreadable_is_read(project2: Path) -> None:
    bag = project2 / "bags" / "ok" / "s1"
    (bag / "metadata.yaml").write_text("rosbag2_bagfile_information: [\n")
    status, stdout, stderr = run(project2, ("info", str(bag)))
    assert status == 0 and stdout.count(f" {PAIRS} msgs ") == 2
    (line,) = stderr.splitlines()
    assert line == (
        f"imrosc info: {bag}:1:1: warning: metadata.yaml unreadable; recovered {2 * PAIRS} "
        "messages of the first 39.910 s [bag-recovered]"
    )


def test_a_ros2_bag_cut_before_its_first_message_is_an_error(project2: Path) -> None:
    bag = project2 / "bags" / "train" / "r2"
    stored = storage_of(bag)
    stored.write_bytes(stored.read_bytes()[:300])
    before = snapshot(project2)
    status, stdout, stderr = run(project2, ("infer", str(project2 / "p.xml"), "-j", "1", "-q"))
    assert status == 1  # a bag that cannot be read among good ones
    assert f"{bag}:1:1: error: cannot open bag: truncated at byte 300, before its first " in (
        stderr
    )
    assert "skipped 1 bag" in stdout
    assert unchanged_but_written(before, snapshot(project2), "infer")
