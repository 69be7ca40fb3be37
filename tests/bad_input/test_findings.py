"""The catalogue of bad inputs, continued (issue 18): data and configurations that used to
pass silently or crash later, one row per case of the issue.

Each row runs one command in a fresh copy of the catalogue's project and asserts the exit
status of its class (README, "Exit status"), the one line, on stdout or stderr, that says
what is wrong, no traceback, and that no file that was there before changed.
"""

from __future__ import annotations

import json
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import pytest
from click.testing import CliRunner

from imrosc.cli import main
from tests.bad_input.support import CONFIG, project, snapshot, template
from tests.graph import Message, write_ros2_bag
from tests.translate import Msg, msg, write_bag

__all__ = ["project", "template"]

INV, BAG = "{d}/p.inv", "{d}/bags/train/r1.bag"


def pairs(offset: float, out_type: str = "std_msgs/msg/Float64", **values: float) -> list[Msg]:
    """40 pairs as tests.translate.good_run writes them; ``/out`` of ``out_type``, its
    value ``values["out"]`` when given."""
    found = []
    for i in range(40):
        t = offset + i * 0.1
        out = values.get("out", float(i % 5))
        found.append(msg("/in", t, "std_msgs/msg/Int32", "/src", data=i % 3))
        if out_type.endswith("Int32"):
            out = int(i % 5)
        found.append(msg("/out", t + 0.01, out_type, "/ctl", data=out))
    return found


def bag(name: str, messages: Callable[[], list[Msg]]) -> Callable[[Path], None]:
    def setup(folder: Path) -> None:
        (folder / name).parent.mkdir(parents=True, exist_ok=True)
        write_bag(folder / name, messages())

    return setup


def config(name: str, text: str) -> Callable[[Path], None]:
    def setup(folder: Path) -> None:
        (folder / name).write_text(text)

    return setup


def condition(value: str) -> str:
    return CONFIG.replace(
        '<publish id="a">',
        f'<condition id="1"><topic>/in</topic><value>{value}</value></condition>\n'
        '    <publish id="a" conds="1">',
    )


def other_project(folder: Path) -> None:
    document = json.loads((folder / "p.inv").read_text())
    document["project"] = "other_robot"
    (folder / "other.inv").write_text(json.dumps(document))
    (folder / "m.xml").write_text(
        CONFIG.replace("</imROS>", '  <monitor inv="other.inv"/>\n</imROS>')
    )


def topic_operand(folder: Path) -> None:
    """The issue's first case: a condition whose operand is a topic (``/in == 2``)."""
    (folder / "t.xml").write_text(
        condition("/in == 2")
        .replace('inv="p.inv"', 'inv="t.inv"')
        .replace('<check inv="p.inv">', '<check inv="t.inv">')
    )
    done = CliRunner().invoke(main, ["infer", str(folder / "t.xml"), "-j", "1", "-q"])
    assert done.exit_code == 0, done.output


def ros2_bag(folder: Path) -> None:
    write_ros2_bag(folder / "ros2", [Message("/t", 1, "x", "/talker")])


@dataclass(frozen=True)
class Row:
    """A command line (``{d}``: the project), its status, a fragment of the one line that
    says what is wrong, and what is set up first."""

    args: tuple[str, ...]
    status: int
    says: str
    setup: Callable[[Path], None] | None = None


ROWS: dict[str, Row] = {
    # check rejects what would crash later
    "check: a constant condition (1 == 1)": Row(
        ("check", "{d}/c.xml"),
        1,
        "error: the condition reads no field of its topic: it holds always or never",
        config("c.xml", condition("1 == 1")),
    ),
    "check: a constant condition (true)": Row(
        ("check", "{d}/c.xml"), 1, "[constant-condition]", config("c.xml", condition("true"))
    ),
    "check: a window below the timestamps' resolution": Row(
        ("check", "{d}/w.xml"),
        1,
        "[window-below-resolution]",
        config("w.xml", CONFIG.replace('budget="0"', 'budget="0" window="0.0000001"')),
    ),
    # a topic operand: checked in replay as in infer (it raised KeyError: 'op')
    "replay: a condition with a topic operand": Row(
        ("replay", "{d}/t.inv", BAG),
        0,
        "r1.bag: 80 messages over 3.910 s, no violations, no alarm",
        topic_operand,
    ),
    # bad data is never a pass
    "replay: NaN in every message": Row(
        ("replay", INV, "{d}/nan.bag"),
        1,
        "observed nan, expected a finite value (never NaN nor infinite in training) (40x until",
        bag("nan.bag", lambda: pairs(50.0, out=float("nan"))),
    ),
    "infer: NaN and inf in training": Row(
        ("infer", "{d}/p.xml", "-j", "1", "-q", "--bags", "{d}/odd", "-o", "{d}/odd.inv"),
        0,
        "non-finite values left out of point a (of 40 samples): out.data: 40 NaN",
        bag("odd/n.bag", lambda: pairs(50.0, out=float("nan"))),
    ),
    "replay: a topic of another type": Row(
        ("replay", INV, "{d}/drift.bag"),
        5,
        "warning: topic /out has type std_msgs/msg/Int32 in this bag but std_msgs/msg/Float64 "
        "in the invariants: its points are not checked",
        bag("drift.bag", lambda: pairs(50.0, "std_msgs/msg/Int32")),
    ),
    "classify: a topic of another type": Row(
        ("classify", "{d}/p.xml", "-j", "1", "-q", "--refined", "{d}/r.inv"),
        5,
        "drift.bag: warning: topic /out has type std_msgs/msg/Int32 in this bag",
        bag("bags/bad/drift.bag", lambda: pairs(50.0, "std_msgs/msg/Int32")),
    ),
    "replay: a bag without the invariants' topics": Row(
        ("replay", INV, "{d}/other.bag"),
        5,
        "warning: none of the invariants' topics is in this bag (/in, /out): not read",
        bag(
            "other.bag",
            lambda: [msg("/z", 1 + i * 0.1, "std_msgs/msg/Int32", data=1) for i in range(9)],
        ),
    ),
    "replay: a bag with some of the invariants' topics": Row(
        ("replay", INV, "{d}/half.bag"),
        5,
        "warning: no messages on /out: their invariants are not checked",
        bag("half.bag", lambda: [m for m in pairs(50.0) if m.topic == "/in"]),
    ),
    "replay: a bag that is not one among good ones": Row(
        ("replay", INV, BAG, "{d}/junk.bag"),
        1,
        "imrosc replay: {d}/junk.bag: cannot open bag: not a ROS 1 bag",
        config("junk.bag", "junk\n"),
    ),
    # no bag read: an input error, and nothing written over what was there
    "infer: no bag could be read": Row(
        ("infer", "{d}/p.xml", "-j", "1", "-q", "--bags", "{d}/junk.bag"),
        2,
        "imrosc infer: no bag could be read: {d}/p.inv not written",
        config("junk.bag", "junk\n"),
    ),
    "replay: no bag could be read": Row(
        ("replay", INV, "{d}/junk.bag"),
        2,
        "imrosc replay: {d}/junk.bag: cannot open bag: not a ROS 1 bag",
        config("junk.bag", "junk\n"),
    ),
    "classify: no bag could be read": Row(
        ("classify", "{d}/c.xml", "-j", "1", "-q"),
        2,
        "imrosc classify: no bag could be read: nothing written",
        config(
            "c.xml",
            CONFIG.replace("<success>bags/ok</success>", "<success>gone.bag</success>").replace(
                "<fail>bags/bad</fail>", "<fail>bags/none</fail>"
            ),
        ),
    ),
    "export-daikon: no bag could be read": Row(
        ("export-daikon", "{d}/p.xml", "-q", "--bags", "{d}/gone.bag", "-o", "{d}/daikon"),
        2,
        "imrosc export-daikon: no bag could be read: nothing written to {d}/daikon",
    ),
    "build: no bag could be read": Row(
        ("build", "{d}/p.xml", "-q", "--bags", "{d}/gone.bag", "-o", "{d}/build"),
        2,
        "gone.bag:1:1: error: no such file or directory [bag-error]",
    ),
    # graph of bags without callerids: said, not an empty listing alone
    "graph: a ROS 2 bag (no callerids)": Row(
        ("graph", "{d}/ros2", "-q"),
        0,
        "imrosc graph: no node found: the inputs record no publisher",
        ros2_bag,
    ),
    # invariants of another project
    "classify: invariants of another project": Row(
        (
            "classify",
            "{d}/p.xml",
            "-j",
            "1",
            "-q",
            "--inv",
            "{d}/other.inv",
            "--refined",
            "{d}/r.inv",
        ),
        0,
        "other.inv was inferred for project 'other_robot', not 'p' [project-mismatch]",
        other_project,
    ),
    "build: a monitor of another project's invariants": Row(
        ("build", "{d}/m.xml", "--backend", "ros1", "-o", "{d}/build", "-q"),
        0,
        "other.inv was inferred for project 'other_robot', not 'p' [project-mismatch]",
        other_project,
    ),
}


@pytest.mark.parametrize("name", list(ROWS))
def test_finding(name: str, project: Path) -> None:
    row = ROWS[name]
    if row.setup is not None:
        row.setup(project)
    before = snapshot(project)
    args = [arg.replace("{d}", str(project)) for arg in row.args]
    result = CliRunner().invoke(main, args)
    assert result.exit_code == row.status, (result.exit_code, result.output)
    assert result.exception is None or isinstance(result.exception, SystemExit), result.exception
    assert "Traceback" not in result.output
    says = row.says.replace("{d}", str(project))
    lines = [line for line in (result.stdout + result.stderr).splitlines() if says in line]
    assert len(lines) == 1, result.output
    after = snapshot(project)
    assert {k: v for k, v in after.items() if k in before} == before  # nothing changed
    if row.status == 2:  # stopped: nothing written either
        assert set(after) == set(before), set(after) - set(before)
