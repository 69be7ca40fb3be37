"""Bad bags in the catalogue of bad inputs (issue 18, item 5): ROS 1 bags cut short at
several byte offsets or never indexed, read by every command that reads bags.

A bag cut after some whole messages is read up to its last whole record, with one warning
naming the bag, where it ends and how much was recovered; a bag cut before its first whole
message, or a file that is not a bag, is one error line naming it (ROS 2 bags cut short:
tests/bad_input/test_bags_ros2.py). No traceback, and no file that was there before changes
(the bag itself included).
"""

from __future__ import annotations

import json
import re
import struct
from pathlib import Path

import pytest

from imrosc.report import render
from tests.bad_input.support import (
    COMMANDS,
    CONFIG,
    RECOVERED,
    project,
    run,
    snapshot,
    template,
)

__all__ = ["project", "template"]


def cut(bag: Path, fraction: float) -> int:
    """Cut ``bag`` to ``fraction`` of its bytes (past its 4 KiB header); the new size."""
    data = bag.read_bytes()
    size = 4200 + int((len(data) - 4200) * fraction)
    bag.write_bytes(data[:size])
    return size


def unindex(bag: Path) -> None:
    """Drop the index, as a recording killed before ``rosbag record`` closed it leaves it:
    ``index_pos`` 0 and nothing after the last chunk."""
    data = bytearray(bag.read_bytes())
    field = data.index(b"index_pos=") + len(b"index_pos=")
    (index_pos,) = struct.unpack_from("<Q", data, field)
    data[field : field + 8] = bytes(8)
    bag.write_bytes(bytes(data[:index_pos]))


@pytest.mark.parametrize("fraction", [0.3, 0.6, 0.95, 1.0])
@pytest.mark.parametrize("command", list(COMMANDS))
def test_a_bag_cut_short_is_read_up_to_its_last_whole_record(
    command: str, fraction: float, project: Path
) -> None:
    args, damaged, statuses = COMMANDS[command]
    bag = project / damaged
    size = cut(bag, fraction) if fraction < 1 else len(bag.read_bytes()) - 40  # in the index
    if fraction == 1:
        bag.write_bytes(bag.read_bytes()[:size])
    before = snapshot(project)
    status, _, stderr = run(project, args)
    assert status in statuses, (status, stderr)
    lines = [line for line in stderr.splitlines() if RECOVERED in line]
    assert len(lines) == 1, stderr
    (line,) = lines
    assert str(bag) in line and f"truncated at byte {size:,}; recovered " in line, line
    assert re.search(r"messages? of the first \d+\.\d{3} s( \[bag-recovered\])?$", line), line
    after = snapshot(project)
    written = {"p.inv"} if command == "infer" else set()  # its own output, rewritten
    assert {k: v for k, v in after.items() if k in before and k not in written} == {
        k: v for k, v in before.items() if k not in written
    }


@pytest.mark.parametrize("command", ["infer", "replay", "info"])
def test_a_bag_never_indexed_is_read_whole(command: str, project: Path) -> None:
    args, damaged, statuses = COMMANDS[command]
    unindex(project / damaged)
    status, _, stderr = run(project, args)
    assert status in statuses, (status, stderr)
    (line,) = [line for line in stderr.splitlines() if RECOVERED in line]
    assert "not indexed (the recording was interrupted); recovered 80 messages of the first " in (
        line
    )


@pytest.mark.parametrize(
    ("content", "message"),
    [
        (b"", "the file is empty"),
        (b"#ROSB", "truncated at byte 5, in its header"),
        (bytes(range(256)) * 40, "not a ROS 1 bag: the file does not begin with #ROSBAG V2.0"),
        (b"#ROSBAG V1.2\n" + bytes(300), "format 1.2 of ROS 1 bags is not supported (only 2.0)"),
    ],
    ids=["empty", "cut in its magic", "binary junk", "format 1.2"],
)
def test_a_file_that_is_not_a_bag_says_so_in_one_line(
    content: bytes, message: str, project: Path
) -> None:
    bag = project / "bags" / "ok" / "s1.bag"
    bag.write_bytes(content)
    status, stdout, stderr = run(project, ("info", str(bag)))
    assert status == 2 and stdout == ""
    (line,) = stderr.splitlines()
    assert line == f"imrosc info: {bag}:1:1: error: cannot open bag: {message} [bag-error]"
    assert "\\x" not in line  # no bytes quoted


def test_a_bag_cut_before_its_first_message_is_an_error(project: Path) -> None:
    bag = project / "bags" / "train" / "r2.bag"
    bag.write_bytes(bag.read_bytes()[:4200])
    status, stdout, stderr = run(project, ("infer", str(project / "p.xml"), "-j", "1", "-q"))
    assert status == 1  # a bag that cannot be read among good ones
    assert f"{bag}:1:1: error: cannot open bag: truncated at byte 4,200, before its first " in (
        stderr
    )
    assert "skipped 1 bag" in stdout


RELATIVE = CONFIG.replace('<publish id="a">', '<publish id="a" relative="1">')


@pytest.mark.parametrize(
    "args",
    [
        ("infer", "{d}/r.xml", "-j", "1", "-q"),
        ("export-daikon", "{d}/r.xml", "-o", "{d}/daikon", "-q"),
        ("build", "{d}/r.xml", "--bags", "{d}/bags/train"),
    ],
    ids=lambda args: args[0],
)
def test_no_bag_read_is_an_input_error_where_the_bags_were_the_graph(
    args: tuple[str, ...], project: Path
) -> None:
    """A relative point learns its inputs from the bags' graph: when none of the bags can be
    read, the command says so (exit 2), not that the configuration lacks a graph source."""
    (project / "r.xml").write_text(RELATIVE)
    for bag in (project / "bags" / "train").iterdir():
        bag.write_bytes(b"not a bag\n")
    before = snapshot(project)
    status, _, stderr = run(project, args)
    assert status == 2, stderr
    assert "r1.bag:1:1: error: cannot open bag: not a ROS 1 bag" in stderr
    assert "relative-without-graph" not in stderr
    assert snapshot(project) == before


def test_stability_names_a_bag_it_cannot_read_once(project: Path) -> None:
    """A round that trains on the bag only stops the command; the bag's error is one line,
    not one per round that met it."""
    bag = project / "bags" / "train" / "r1.bag"
    bag.write_bytes(b"not a bag\n")
    status, _, stderr = run(project, ("stability", "{d}/p.xml", "-j", "1", "-q"))
    assert status == 1, stderr
    lines = [line for line in stderr.splitlines() if line.startswith(str(bag))]
    assert len(lines) == 1 and "[bag-error]" in lines[0], stderr
    # one bag left of two: no round trains on it and checks another
    assert "no round both trained on a bag it could read and checked one" in stderr


def test_stability_with_no_bag_it_can_read_is_an_input_error(project: Path) -> None:
    """Every <detect> bag unreadable: exit 2 (README), each bag named once, no report."""
    train = sorted((project / "bags" / "train").glob("*.bag"))
    for bag in train:
        bag.write_bytes(b"not a bag\n")
    out = project / "s.json"
    args = ("stability", "{d}/p.xml", "-j", "1", "-q", "--format", "json", "-o", str(out))
    status, _, stderr = run(project, args)
    assert status == 2, stderr
    assert "imrosc stability: no bag could be read: nothing cross-validated" in stderr
    for bag in train:
        assert sum(line.startswith(str(bag)) for line in stderr.splitlines()) == 1, stderr
    assert not out.exists()


@pytest.mark.parametrize("names", [["bad/f1.bag"], ["ok/s1.bag", "bad/f1.bag"]])
def test_classify_names_the_runs_it_cannot_read_on_stderr(names: list[str], project: Path) -> None:
    """Some runs unreadable: exit 1; none: exit 2 and no report. Either way stderr names
    each bag and its problem (the report is not always there to say it)."""
    for name in names:
        (project / "bags" / name).write_bytes(b"not a bag\n")
    out = project / "r.json"
    args = ("classify", "{d}/p.xml", "-j", "1", "-q", "--format", "json", "-o", str(out))
    status, _, stderr = run(project, args)
    assert status == (1 if len(names) == 1 else 2), stderr
    for name in names:
        line = f"imrosc classify: {project / 'bags' / name}: cannot open bag: not a ROS 1 bag"
        assert line in stderr, stderr
    assert out.exists() == (len(names) == 1)


def test_stability_leaves_a_bag_it_cannot_read_out_of_its_rounds(project: Path) -> None:
    """As infer skips a bag it cannot read, stability trains without it and reports the
    round that held it out as checking nothing (its errors, no violations, out of the
    means); exit 1 (README: a bag that could not be read among good ones)."""
    train = project / "bags" / "train"
    (train / "r3.bag").write_bytes((train / "r2.bag").read_bytes())
    (train / "r1.bag").write_bytes(b"not a bag\n")
    out = project / "s.json"
    args = ("stability", "{d}/p.xml", "-j", "1", "-q", "--format", "json", "-o", str(out))
    status, _, stderr = run(project, args)
    assert status == 1, stderr
    report = json.loads(out.read_text())
    (unread,) = [r for r in report["rounds"] if r["errors"]]
    assert unread["held_out"] == [str(train / "r1.bag")] and unread["violated"] == {}
    scored = [r for r in report["rounds"] if not r["errors"]]
    assert len(scored) == 2 and report["held_out_runs"] == 2
    assert "of 2 held-out runs raised an alarm" in render(report, "text")  # not of 3
    for family, summary in report["families"].items():
        mean = sum(r["total"].get(family, 0) for r in scored) / 2
        assert summary["total_mean"] == round(mean, 3), family


def make_active(project: Path, *names: str) -> list[Path]:
    """The bags ``names`` as an interrupted ``rosbag record`` leaves them: unindexed and
    named ``NAME.bag.active``."""
    found = []
    for name in names:
        bag = project / name
        unindex(bag)
        active = bag.with_name(bag.name + ".active")
        bag.rename(active)
        found.append(active)
    return found


NOT_INDEXED = "not indexed (the recording was interrupted); recovered 80 messages of the first "


def test_an_unfinished_recording_is_read_wherever_a_bag_is_named(project: Path) -> None:
    """``NAME.bag.active`` files read as they are, not renamed: by name in <bag>, <success>
    and <fail>, in their folders, on the command line and by glob."""
    r2, s1, f1 = make_active(project, "bags/train/r2.bag", "bags/ok/s1.bag", "bags/bad/f1.bag")
    config = (project / "p.xml").read_text()
    named = config.replace("<bag>bags/train</bag>", "<bag>bags/train/r2.bag.active</bag>")
    named = named.replace("<success>bags/ok</success>", "<success>bags/ok/s1.bag.active</success>")
    named = named.replace("<fail>bags/bad</fail>", "<fail>bags/bad/f1.bag.active</fail>")
    (project / "named.xml").write_text(named)
    for xml, trained in (("p.xml", "2 bags"), ("named.xml", "1 bag,")):
        status, stdout, stderr = run(project, ("infer", f"{{d}}/{xml}", "-j", "1", "-q"))
        assert status == 0 and f"from {trained}" in stdout, (stdout, stderr)
        (line,) = [line for line in stderr.splitlines() if RECOVERED in line]
        assert line.startswith(f"{r2}:1:1: warning: {NOT_INDEXED}"), line
        status, stdout, stderr = run(project, ("classify", f"{{d}}/{xml}", "-j", "1", "-q"))
        assert status == 0, (stdout, stderr)
        assert f"success  {s1}" in stdout and f"fail     {f1}" in stdout, stdout
        assert {bag for bag in (s1, f1) if f"{bag}: warning: {NOT_INDEXED}" in stderr} == {s1, f1}
    status, stdout, stderr = run(project, ("replay", "{d}/p.inv", str(s1)))
    assert status in (0, 1, 3) and f"{s1}: warning: {NOT_INDEXED}" in stderr, stderr
    status, stdout, stderr = run(project, ("info", "{d}/bags/*/*.active", "-q"))
    assert status == 0 and all(f"bag:       {bag}" in stdout for bag in (r2, s1, f1)), stdout
    assert len([line for line in stderr.splitlines() if NOT_INDEXED in line]) == 3


def test_an_unfinished_recording_is_read_by_url(project: Path) -> None:
    from tests.served import serve

    (active,) = make_active(project, "bags/ok/s1.bag")
    with serve(project) as url:
        named = f"{url}/bags/ok/{active.name}"
        status, stdout, stderr = run(project, ("info", named, "-q"))
        assert status == 0 and f"bag:       {named}" in stdout, (stdout, stderr)
        (line,) = stderr.splitlines()
        assert line.startswith(f"imrosc info: {named}:1:1: warning: {NOT_INDEXED}"), line
