"""Replay of ROS 1 bags without architecture records: publishers from their first message,
anonymous node names across runs, and bags that lack the invariants' topics."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import pytest
from click.testing import CliRunner

from imrosc.cli import main
from imrosc.detect import run_detect
from imrosc.replay import replay
from tests.translate import Msg, msg, write_bag

CONFIG = """<imROS project="a">
  <scope>
    <publish id="t">/t</publish>
    <arch id="g">pub</arch>
  </scope>
  <detect inv="a.inv" budget="0"><bag>train.bag</bag></detect>
</imROS>
"""

FLOAT = "std_msgs/msg/Float64"


def run(record: str, rviz: str, intruder: float | None = None) -> list[Msg]:
    """30 s of /t from /a at 10 Hz and /rosout from /a, ``record`` and ``rviz`` (anonymous
    names); with ``intruder``, /b publishes /t too from that time on."""
    found: list[Msg] = []
    for k in range(301):
        time = k / 10
        found.append(msg("/t", time, FLOAT, "/a", data=1.0))
        if intruder is not None and time >= intruder:
            found.append(msg("/t", time + 0.05, FLOAT, "/b", data=1.0))
        if k % 10 == 0:
            for node in ("/a", record, rviz):
                found.append(msg("/rosout", time, FLOAT, node, data=0.0))
    return found


@pytest.fixture(scope="module")
def document(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Any]:
    folder = tmp_path_factory.mktemp("callerid")
    write_bag(folder / "train.bag", run("/record_1553088502272947227", "/rviz_12345_1553074025852"))
    config = folder / "a.xml"
    config.write_text(CONFIG)
    result = run_detect(config, workers=1)
    assert result.document is not None
    return result.document


def texts(document: dict[str, Any]) -> set[str]:
    return {i["text"] for i in document["invariants"] if i["family"] == "architecture"}


def test_anonymous_names_are_learnt_in_their_stable_form(document: dict[str, Any]) -> None:
    found = texts(document)
    assert "max_pubs(/rosout) = {/a, /record_*, /rviz_*}" in found
    assert "min_pubs(/rosout) = {/a, /record_*, /rviz_*}" in found
    assert "max_pubs(/t) = {/a}" in found and "min_pubs(/t) = {/a}" in found


def test_a_training_run_and_a_restart_break_nothing(
    document: dict[str, Any], tmp_path: Path
) -> None:
    again = write_bag(
        tmp_path / "again.bag", run("/record_1553099999999999999", "/rviz_9_1553099999999")
    )
    train = tmp_path / "train.bag"
    write_bag(train, run("/record_1553088502272947227", "/rviz_12345_1553074025852"))
    for result in replay(document, [train, again]):
        assert (result.error, result.warnings, result.violations) == (None, [], [])


def test_an_intruder_is_reported_when_it_first_publishes(
    document: dict[str, Any], tmp_path: Path
) -> None:
    bag = write_bag(tmp_path / "intruder.bag", run("/record_1", "/rviz_2", intruder=16.0))
    (result,) = replay(document, [bag])
    start = result.start
    broken = [
        (round(v.time - start, 6), v.kind, v.text)
        for v in result.violations
        if v.family == "architecture"
    ]
    # /record_1 and /rviz_2 are ordinary names, not the training run's anonymous nodes
    assert sorted(set(broken), key=broken.index) == [
        (0.0, "max_pubs", "max_pubs(/rosout) = {/a, /record_*, /rviz_*}"),
        (0.0, "min_pubs", "min_pubs(/rosout) = {/a, /record_*, /rviz_*}"),
        (16.05, "max_pubs", "max_pubs(/t) = {/a}"),  # when /b first published, not at 0 s
    ] + [(round(16.15 + k / 10, 6), "max_pubs", "max_pubs(/t) = {/a}") for k in range(140)]
    # the graph the callerids give at /b's first message, and each of its 141 messages
    # (Engine.intruder): none of them is a sample of point t
    intruding = [v for v in result.violations if v.text == "max_pubs(/t) = {/a}"]
    assert len(intruding) == 1 + 141
    assert all(v.observed == ["/b"] for v in intruding)
    assert result.checked == {"t": 301}
    found = {v.text: v for v in result.violations if v.family == "architecture"}
    missing = found["min_pubs(/rosout) = {/a, /record_*, /rviz_*}"]
    assert missing.observed == ["/a", "/record_1", "/rviz_2"]
    assert missing.expected == "at least {/a, /record_*, /rviz_*} (missing /record_*, /rviz_*)"


def test_a_bag_without_the_topics_is_a_warning_and_is_not_read(
    document: dict[str, Any], tmp_path: Path
) -> None:
    messages = [msg("/u", k / 10, FLOAT, "/u", data=1.0) for k in range(50)]
    (result,) = replay(document, [write_bag(tmp_path / "other.bag", messages)])
    assert result.messages == 0 and result.violations == []
    assert result.warnings == ["none of the invariants' topics is in this bag (/t): not read"]


def test_a_bag_missing_some_topics_names_them(tmp_path: Path) -> None:
    document = {
        "format": "imrosc-invariants",
        "version": 1,
        "topics": {
            name: {"type": FLOAT, "variables": [{"name": "x", "type": "float", "path": "data"}]}
            for name in ("/t", "/v", "/w")
        },
        "points": {},
        "invariants": [],
    }
    bag = write_bag(tmp_path / "t.bag", [msg("/t", 0.0, FLOAT, "/a", data=1.0)])
    (result,) = replay(document, [bag])
    assert result.messages == 1
    assert result.warnings == ["no messages on /v, /w: their invariants are not checked"]


def test_warnings_reach_every_report(document: dict[str, Any], tmp_path: Path) -> None:
    inv = tmp_path / "a.inv"
    inv.write_text(json.dumps(document))
    other = write_bag(tmp_path / "other.bag", [msg("/u", 0.0, FLOAT, "/u", data=1.0)])
    runner = CliRunner()
    text = runner.invoke(main, ["replay", str(inv), str(other)])
    assert text.exit_code == 5, text.output  # its points checked no sample (README)
    assert "warning: none of the invariants' topics is in this bag (/t): not read" in text.stdout
    as_json = runner.invoke(main, ["replay", "--format", "json", str(inv), str(other)])
    (run_,) = json.loads(as_json.stdout)["runs"]
    assert run_["warnings"] == ["none of the invariants' topics is in this bag (/t): not read"]
    assert run_["messages"] == 0 and run_["unchecked"] == ["t"]
    html = runner.invoke(main, ["replay", "--format", "html", str(inv), str(other)])
    assert "none of the invariants&#39; topics is in this bag (/t): not read" in html.stdout


def test_a_topic_of_another_type_is_a_warning_and_is_not_checked(
    document: dict[str, Any], tmp_path: Path
) -> None:
    """The same values in another type may mean other things (MagneticField in tesla, then
    Vector3Stamped in gauss): replay says so rather than checking or passing them."""
    drifted = [msg("/t", k / 10, "std_msgs/msg/Float32", "/a", data=1e4) for k in range(50)]
    (result,) = replay(document, [write_bag(tmp_path / "drift.bag", drifted)])
    assert result.messages == 0 and result.violations == [] and result.alarms == []
    assert result.warnings[0] == (
        "topic /t has type std_msgs/msg/Float32 in this bag but std_msgs/msg/Float64 in the "
        "invariants: its points are not checked"
    )
    same = [msg("/t", k / 10, FLOAT, "/a", data=1e4) for k in range(50)]
    (checked,) = replay(document, [write_bag(tmp_path / "same.bag", same)])
    assert checked.violations and not checked.warnings  # the same values, learnt type: broken


PAIRED = """<imROS project="p">
  <scope>
    <publish id="t"><topic>/t</topic><topic>/u</topic></publish>
  </scope>
  <detect inv="p.inv" budget="0"><bag>train.bag</bag></detect>
</imROS>
"""


def test_replay_says_how_many_samples_each_point_checked(tmp_path: Path) -> None:
    """A point that pairs /t with /u checks nothing when /u never comes: replay says so
    (and counts what every point checked) rather than passing the run silently."""
    both = [msg("/t", 1 + k / 10, FLOAT, "/a", data=1.0) for k in range(50)]
    both += [msg("/u", 1 + k / 10 - 0.05, FLOAT, "/b", data=2.0) for k in range(50)]
    write_bag(tmp_path / "train.bag", both)
    (tmp_path / "p.xml").write_text(PAIRED)
    learnt = run_detect(tmp_path / "p.xml", workers=1).document
    assert learnt is not None
    (whole,) = replay(learnt, [tmp_path / "train.bag"])
    assert whole.checked == {"t": 50} and whole.warnings == []
    alone = write_bag(tmp_path / "alone.bag", [m for m in both if m.topic == "/t"])
    (result,) = replay(learnt, [alone])
    assert result.checked == {"t": 0} and result.violations == []
    assert "point t checked no sample: a topic or parameter it pairs /t with never came" in (
        result.warnings
    )


def test_a_point_that_checked_no_sample_has_its_own_exit_status(tmp_path: Path) -> None:
    """replay and classify exit 5 when a point checked no sample and nothing worse happened;
    violations (3) and alarms (1) come first (README, "Exit status")."""
    both = [msg("/t", 1 + k / 10, FLOAT, "/a", data=1.0) for k in range(50)]
    both += [msg("/u", 1 + k / 10 - 0.05, FLOAT, "/b", data=2.0) for k in range(50)]
    write_bag(tmp_path / "train.bag", both)
    (tmp_path / "p.xml").write_text(PAIRED)
    runner = CliRunner()
    learnt = runner.invoke(main, ["infer", str(tmp_path / "p.xml"), "-j", "1", "-q"])
    assert learnt.exit_code == 0, learnt.output
    inv = str(tmp_path / "p.inv")
    alone = write_bag(tmp_path / "alone.bag", [m for m in both if m.topic == "/t"])
    broken = [msg("/t", 1 + k / 10, FLOAT, "/a", data=9.0) for k in range(50)]
    bad = write_bag(tmp_path / "bad.bag", broken + [m for m in both if m.topic == "/u"])
    statuses = {
        name: runner.invoke(main, ["replay", inv, *map(str, bags)]).exit_code
        for name, bags in {
            "clean": [tmp_path / "train.bag"],
            "unchecked": [alone],
            "unchecked and violated": [alone, bad],
        }.items()
    }
    assert statuses["clean"] == 0 and statuses["unchecked"] == 5
    assert statuses["unchecked and violated"] in (1, 3)
    (tmp_path / "c.xml").write_text(
        PAIRED.replace(
            "</detect>",
            '</detect>\n  <check inv="p.inv"><success>alone.bag</success>'
            "<fail>bad.bag</fail></check>",
        )
    )
    scored = runner.invoke(main, ["classify", str(tmp_path / "c.xml"), "-j", "1"])
    assert scored.exit_code == 5, scored.output
    assert "point t checked no sample" in scored.stderr
    (tmp_path / "d.xml").write_text(
        PAIRED.replace("</detect>", '</detect>\n  <check inv="p.inv"><bag>alone.bag</bag></check>')
    )
    compared = runner.invoke(main, ["classify", str(tmp_path / "d.xml"), "--format", "json"])
    assert compared.exit_code == 5, compared.output
    assert json.loads(compared.stdout)["unchecked"] == {str(alone): ["t"]}
    # which point went unchecked, and why, is said on stderr as when scoring runs
    warnings = [
        "no messages on /u: their invariants are not checked",
        "point t checked no sample: a topic or parameter it pairs /t with never came",
    ]
    for warning in warnings:
        assert f"imrosc classify: {alone}: warning: {warning}" in compared.stderr
    assert json.loads(compared.stdout)["warnings"] == {str(alone): warnings}
