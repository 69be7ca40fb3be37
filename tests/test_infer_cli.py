"""``imrosc infer`` and ``imrosc show`` as a user runs them, with good and bad bags."""

from __future__ import annotations

import json
import shutil
import sqlite3
from pathlib import Path

import pytest
from click.testing import CliRunner
from rosbags.rosbag2 import StoragePlugin
from rosbags.rosbag2 import Writer as Ros2Writer
from rosbags.typesys import Stores, get_types_from_msg, get_typestore

from imrosc.cli import main
from imrosc.detect import run_detect
from tests.translate import good_run, msg, write_bag

FIXTURES = Path(__file__).parent / "fixtures"
SHARED = Path(__file__).resolve().parent.parent.parent / "shared" / "data"
WRONG_RMW = SHARED / "fixtures/rosbag2/rosbag2_tests/resources/sqlite3/wrong_rmw_test"

CONFIG = """<imROS project="bad">
  <scope>
    <publish id="a"><topic>/out</topic><topic>/in</topic></publish>
  </scope>
  <detect inv="bad.inv">
    <bag>bags</bag>{wrong}
  </detect>
</imROS>
"""


def unknown_type_bag(path: Path) -> Path:
    """A ROS 2 bag whose message definitions were lost (as old rosbag2 versions wrote)."""
    store = get_typestore(Stores.LATEST)
    store.register(get_types_from_msg("float64 level\n", "my_pkg/msg/Thing"))
    with Ros2Writer(path, version=9, storage_plugin=StoragePlugin.SQLITE3) as writer:
        connection = writer.add_connection("/out", "my_pkg/msg/Thing", typestore=store)
        thing = store.types["my_pkg/msg/Thing"](level=1.5)
        writer.write(connection, 1, bytes(store.serialize_cdr(thing, "my_pkg/msg/Thing")))
    with sqlite3.connect(next(path.glob("*.db3"))) as database:
        database.execute("delete from message_definitions")
    return path


@pytest.fixture
def project(tmp_path: Path) -> Path:
    bags = tmp_path / "bags"
    bags.mkdir()
    good_run(bags / "run1.bag", 0.0)
    good_run(bags / "run2.bag", 100.0, odd=True)
    whole = good_run(tmp_path / "whole.bag", 200.0).read_bytes()
    (bags / "truncated.bag").write_bytes(whole[:4200])  # before its first message
    (bags / "notes.txt").write_text("not a bag\n")
    shutil.copyfile(FIXTURES / "bags" / "bag-empty.bag", bags / "empty.bag")
    unknown_type_bag(bags / "unknown_types")
    config = tmp_path / "bad.xml"
    wrong = f"\n    <bag>{WRONG_RMW}</bag>" if WRONG_RMW.exists() else ""
    config.write_text(CONFIG.format(wrong=wrong))
    return config


def test_bad_bags_are_reported_by_name_and_the_good_ones_still_used(project: Path) -> None:
    result = CliRunner().invoke(main, ["infer", str(project), "-j", "1"])
    assert result.exception is None or isinstance(result.exception, SystemExit)
    assert result.exit_code == 1  # bad bags are errors, but the file is written
    output = result.output
    bags = project.parent / "bags"
    expected = [
        (bags / "truncated.bag", "error"),
        (bags / "notes.txt", "error"),
        (bags / "unknown_types", "error"),
        (bags / "empty.bag", "warning"),
    ]
    if WRONG_RMW.exists():  # rosbag2's own bag of an unsupported serialization
        expected.append((WRONG_RMW, "error"))
        assert "serialization format" in output
    for name, problem in expected:
        assert f"{name}:1:1: {problem}:" in output, name
    assert "unknown message type my_pkg/msg/Thing" in output
    assert "skipped" in output and "truncated.bag" in output.split("skipped", 1)[1]
    document = json.loads((project.parent / "bad.inv").read_text())
    assert document["points"]["a"]["support"]["runs"] == 2  # run1 and run2
    assert document["points"]["a"]["support"]["samples"] == 80
    bounds = [i for i in document["invariants"] if i["kind"] == "upper" or i["kind"] == "range"]
    assert bounds, "NaN and inf did not stop inference"
    # ... and they are reported, not skipped silently (issue 18, item 2)
    assert "non-finite values left out of point a (of 80 samples): out.data: 1 NaN, 1 +inf\n" in (
        result.stdout
    )
    assert document["points"]["a"]["support"]["nonfinite"] == {
        "out.data": {"nan": 1, "+inf": 1, "-inf": 0}
    }
    assert all("nonfinite" not in p["support"] for k, p in document["points"].items() if k != "a")


def test_show_filters_by_family_and_point(project: Path) -> None:
    CliRunner().invoke(main, ["infer", str(project), "-j", "1", "-q"])
    inv = str(project.parent / "bad.inv")
    shown = CliRunner().invoke(main, ["show", inv, "--family", "frequency"])
    assert shown.exit_code == 0
    lines = [line for line in shown.output.splitlines() if line and not line.startswith("=")]
    assert lines[0].startswith("a:::POINT")
    listed = [line for line in lines if ":::POINT" not in line]
    assert listed and all("freq(" in line for line in listed)
    assert CliRunner().invoke(main, ["show", inv, "--point", "zz"]).output == ""


def test_infer_refuses_to_overwrite_a_file_it_did_not_write(project: Path) -> None:
    (project.parent / "bad.inv").write_text("my notes\n")
    result = CliRunner().invoke(main, ["infer", str(project), "-j", "1", "-q"])
    assert result.exit_code == 2  # an output refused: a usage error (README, "Exit status")
    assert "was not generated by imrosc; use --force" in result.output
    assert (project.parent / "bad.inv").read_text() == "my notes\n"


def test_show_reports_a_broken_file_without_traceback(tmp_path: Path) -> None:
    broken = tmp_path / "x.inv"
    broken.write_text("{not json")
    result = CliRunner().invoke(main, ["show", str(broken)])
    assert result.exit_code == 2
    assert f"{broken}:1:2: not JSON" in result.output


def test_bag_empty_fixture_points_where_it_says(tmp_path: Path) -> None:
    fixture = FIXTURES / "bags" / "bag-empty.bag"
    config = tmp_path / "c.xml"
    config.write_text(
        '<imROS project="e"><scope><publish id="a">/x</publish></scope>'
        f'<detect inv="e.inv"><bag>{fixture}</bag></detect></imROS>'
    )
    result = run_detect(config, workers=1)
    expected = fixture.with_suffix(".expect").read_text().split()
    (diagnostic,) = result.diagnostics
    got = [f"{diagnostic.line}:", f"{diagnostic.severity.value}:", f"[{diagnostic.code}]"]
    assert got == expected


TALKER = SHARED / "fixtures/rosbag2/rosbag2_py/test/resources/sqlite3/talker"


@pytest.mark.skipif(not TALKER.exists(), reason="shared data missing")
def test_a_type_referring_to_an_unknown_type_is_reported_only_when_used(tmp_path: Path) -> None:
    """/parameter_events refers to rcl_interfaces/msg/Parameter, which the bag does not define."""
    config = tmp_path / "t.xml"
    for topic, reported in (("/topic", False), ("/parameter_events", True)):
        config.write_text(
            f'<imROS project="t"><scope><publish id="a">{topic}</publish></scope>'
            f'<detect inv="t.inv"><bag>{TALKER}</bag></detect></imROS>'
        )
        result = run_detect(config, workers=1)
        messages = [d.message for d in result.diagnostics if d.code == "bag-error"]
        assert bool(messages) == reported
        if reported:
            assert "unknown message type rcl_interfaces/msg/Parameter" in messages[0]


def test_a_topic_whose_type_drifts_is_a_warning_and_still_read(tmp_path: Path) -> None:
    """Schema drift: /out is Float64 in one bag and Float32 in the next (field ``data``)."""
    bags = tmp_path / "bags"
    bags.mkdir()
    good_run(bags / "run1.bag", 0.0)
    drifted = [
        msg("/out" if i % 2 else "/in", 100 + i * 0.05, t, "/ctl", data=(i // 2) % 3)
        for i in range(80)
        for t in ["std_msgs/msg/Float32" if i % 2 else "std_msgs/msg/Int32"]
    ]
    write_bag(bags / "run2.bag", drifted)
    config = tmp_path / "drift.xml"
    config.write_text(CONFIG.format(wrong=""))
    result = run_detect(config, workers=1)
    drift = [d for d in result.diagnostics if d.code == "bag-type-drift"]
    assert [(d.path, d.severity.value) for d in drift] == [(str(bags / "run2.bag"), "warning")]
    assert "std_msgs/msg/Float32 here but std_msgs/msg/Float64" in drift[0].message
    assert result.document is not None
    assert result.document["points"]["a"]["support"]["runs"] == 2
