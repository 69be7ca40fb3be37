"""A real ``rosbag record`` killed (SIGKILL) mid-recording leaves ``NAME.bag.active``: no
index, its last chunk open (its sizes are written when it closes). imrosc reads it, as it is
or renamed ``.bag``, up to its last whole record, with one warning, and keeps at least what
``rosbag reindex`` keeps (issue 18, item 5)."""

from __future__ import annotations

import os
import shutil
import signal
import subprocess
import time
from pathlib import Path

import pytest
from click.testing import CliRunner

from imrosc.bags import open_bag, recovered
from imrosc.cli import main
from tests.live.harness import ROSBAG, Ros, wait_until

pytestmark = pytest.mark.live

ROSTOPIC = Path("/usr/bin/rostopic")


def count(bag: Path) -> tuple[int, str | None]:
    with open_bag(bag) as reader:
        return sum(1 for _ in reader.messages()), recovered(reader)


def test_a_killed_recording_is_read_up_to_its_last_whole_record(ros: Ros, tmp_path: Path) -> None:
    publisher = ros.spawn(
        "pub-x", [str(ROSTOPIC), "pub", "-r", "200", "/x", "std_msgs/Float64", "data: 1.5"]
    )
    ros.wait_publisher("/x", None, 20, (publisher,))
    bag = tmp_path / "run.bag"
    active = tmp_path / "run.bag.active"
    recorder = ros.spawn(
        "record-x", [str(ROSBAG), "record", "--chunksize=16", "-O", str(bag), "/x"]
    )
    wait_until(active.exists, f"rosbag record to open {active}", 30, (recorder,))
    wait_until(lambda: active.stat().st_size > 60_000, "a few chunks recorded", 30, (recorder,))
    os.killpg(recorder.popen.pid, signal.SIGKILL)  # as a crash or a power cut would
    recorder.popen.wait(10)
    ros.stop(publisher)
    time.sleep(0.2)
    assert active.exists() and not bag.exists()  # never closed, never indexed
    shutil.copyfile(active, bag)
    messages, note = count(bag)
    assert messages > 100 and note is not None
    assert count(active) == (messages, note)  # as it is, not renamed
    assert note.startswith(f"truncated at byte {bag.stat().st_size:,}; recovered {messages:,} ")
    for named in (bag, active, tmp_path):  # renamed, as rosbag record left it, its folder
        result = CliRunner().invoke(main, ["info", str(named), "-q"])
        assert result.exit_code == 0, result.output
        lines = result.stderr.splitlines()
        assert len(lines) == (2 if named == tmp_path else 1), lines
        assert all("[bag-recovered]" in line for line in lines)
        assert all(f"recovered {messages:,} messages" in line for line in lines)
    reindexed = tmp_path / "reindexed.bag"
    shutil.copyfile(active, reindexed)
    done = subprocess.run(
        [str(ROSBAG), "reindex", str(reindexed)],
        check=False,
        env=ros.env,
        capture_output=True,
        timeout=60,
    )
    assert done.returncode == 0, done.stderr
    kept, none = count(reindexed)
    assert none is None and kept <= messages  # rosbag reindex drops the open chunk
