"""Configurations fuzzed through ``check -> infer -> replay`` on short bags (issue 18).

Shared by ``tests/test_pipeline_fuzz.py`` (a short, fixed run in CI) and ``bench/fuzz.py``
(a longer one that counts cases and crashes). A configuration is drawn over the topics of
a short ROS 1 bag (numbers, a discrete integer, a point, NaN and infinities, two callers):
publish, call, parameter, architecture and temporal points, conditions, every tunable of
``<detect>`` at ordinary and extreme values, and sometimes edited at random as the check
fuzzer edits its examples; replay reads the training bag, another run, a run with other
values, the training bag cut short, or a bag without the topics. A crash is an exception
that escaped a command, a traceback in its output, or an exit status outside the README's
table for that command.
"""

from __future__ import annotations

import math
import shutil
import tempfile
import traceback
from dataclasses import dataclass, field
from pathlib import Path
from xml.sax.saxutils import escape, quoteattr

import numpy as np
from click.testing import CliRunner
from hypothesis import strategies as st

from imrosc.cli import main
from tests.fuzz_support import mutate, text_values
from tests.translate import Msg, msg, write_bag

DOCUMENTED = {"check": {0, 1, 2}, "infer": {0, 1, 2}, "replay": {0, 1, 2, 3, 5}}
"""The exit statuses each command may end with (README, "Exit status"; 4 is the system
refusing a write, which no case here provokes)."""

TOPICS = ["/in", "/out", "/pos", "/label", "/name", "/scan", "/missing"]
INT, FLOAT, POINT = "std_msgs/msg/Int32", "std_msgs/msg/Float64", "geometry_msgs/msg/Point"
STRING, FLOATS = "std_msgs/msg/String", "std_msgs/msg/Float32MultiArray"
BAGS = ("train", "other", "odd", "cut", "unrelated")
EXPRESSIONS = [
    "data == 1",
    "data > 0",
    "data >= 0 and data < 2",
    "data / 0 > 1",
    "not data",
    "x > 0.5",
    "data == ",
    "label.data != 0",
    "data == 'go'",
    "len(data) > 1",
]
PATTERNS = ["(AB)*", "A+B", "(A|B)+", "AB?", "((AB)*C)*", "(", "A"]
TUNABLES: dict[str, list[str]] = {
    "window": ["0.1", "1.0", "5", "0.000001", "0.0000001"],
    "confidence": ["0", "0.5", "0.99", "0.999999"],
    "drop_ratio": ["0.1", "0.9", "1"],
    "hull_chunk": ["1", "3", "20"],
    "discrete": ["0", "1", "2", "10"],
    "budget": ["0", "0.05", "0.5"],
}


GRAPH = """version: 1
nodes:
  /src:
    publishes: [/in]
  /ctl:
    publishes: [/out]
    subscribes: [/in, /pos]
  /loc:
    publishes: [/pos]
    subscribes: [/out]
  /lab:
    publishes: [/label, /name]
    subscribes: [/out, /scan]
  /scanner:
    publishes: [/scan]
"""
"""Who subscribes to what (``--graph``, one case in two): relative points need it."""


def run_messages(offset: float, scale: float = 1.0, odd: bool = False) -> list[Msg]:
    """Four seconds of a small system at 10 Hz: /in (0, 1, 2), /out, /pos, /label, /name
    (two strings) and /scan (an array whose length changes)."""
    found = []
    for i in range(40):
        t = offset + i * 0.1
        value = scale * math.sin(i / 4)
        if odd and i % 7 == 3:
            value = [math.nan, math.inf, -math.inf][i % 3]
        found.append(msg("/in", t, INT, "/src", data=i % 3))
        found.append(msg("/out", t + 0.01, FLOAT, "/ctl", data=value))
        found.append(msg("/pos", t + 0.02, POINT, "/loc", x=math.cos(i / 5), y=scale * i / 40))
        found.append(msg("/label", t + 0.03, FLOAT, "/lab", data=float(odd and i > 20)))
        if i % 2:
            found.append(msg("/name", t + 0.04, STRING, "/lab", data=["go", "stop"][i % 4 // 2]))
        if i % 4 == 0:
            values = np.array([value] * (1 + i % 3 if odd else 3), dtype=np.float32)
            found.append(msg("/scan", t + 0.05, FLOATS, "/scanner", data=values))
    return found


def write_bags(folder: Path) -> dict[str, Path]:
    """The bags a case reads, under ``folder``."""
    folder.mkdir(parents=True, exist_ok=True)
    bags = {
        "train": write_bag(folder / "train.bag", run_messages(0.0)),
        "other": write_bag(folder / "other.bag", run_messages(10.0)),
        "odd": write_bag(folder / "odd.bag", run_messages(20.0, 3.0, odd=True)),
        "unrelated": write_bag(folder / "unrelated.bag", [msg("/zz", 1.0, FLOAT, data=1.0)]),
    }
    whole = write_bag(folder / "whole.bag", run_messages(30.0)).read_bytes()
    bags["cut"] = folder / "cut.bag"
    bags["cut"].write_bytes(whole[: len(whole) * 2 // 3])
    return bags


@st.composite
def points(draw: st.DrawFn, ids: list[str], events: list[str], conditions: list[str]) -> str:
    """One scope element; its id is appended to ``ids`` (and to ``events`` when a temporal
    point may name it)."""
    kind = draw(st.sampled_from(["publish", "publish", "publish", "call", "param", "arch"]))
    ident = "abcdefgh"[len(ids)]
    ids.append(ident)
    if kind in ("publish", "call"):
        events.append(ident)
    conds = (
        draw(st.lists(st.sampled_from(conditions), max_size=2, unique=True)) if conditions else []
    )
    extra = f' conds="{",".join(conds)}"' if conds and kind != "param" else ""
    if kind == "publish":
        topics = draw(st.lists(st.sampled_from(TOPICS), min_size=1, max_size=3, unique=True))
        params = draw(st.lists(st.sampled_from(["/p", "/q"]), max_size=1))
        relative = draw(st.sampled_from(["", "", ' relative="1"']))
        body = "".join(f"<topic>{t}</topic>" for t in topics)
        body += "".join(f"<param>{p}</param>" for p in params)
        return f'<publish id="{ident}"{relative}{extra}>{body}</publish>'
    if kind == "call":
        return f'<call id="{ident}"{extra}>/srv</call>'
    if kind == "param":
        return f'<param id="{ident}">/p</param>'
    kinds = draw(st.sampled_from(["pub", "pub,sub", "pub,sub,srv", "sub"]))
    return f'<arch id="{ident}"{extra}>{kinds}</arch>'


@st.composite
def configurations(draw: st.DrawFn, train: str | list[str]) -> bytes:
    """A configuration over the short bags' topics that learns from ``train`` (one of them,
    when it is a list)."""
    if isinstance(train, list):
        train = draw(st.sampled_from(train))
    conditions: list[str] = []
    scope: list[str] = []
    for number in range(draw(st.integers(0, 2))):
        ident = str(number + 1)
        conditions.append(ident)
        topic = draw(st.sampled_from(["/in", "/in", "/pos", "/label", "/missing"]))
        value = escape(draw(st.sampled_from(EXPRESSIONS)))
        scope.append(
            f'<condition id="{ident}"><topic>{topic}</topic><value>{value}</value></condition>'
        )
    ids: list[str] = []
    named: list[str] = []
    for _ in range(draw(st.integers(1, 4))):
        scope.append(draw(points(ids, named, conditions)))
    if draw(st.booleans()) and len(named) >= 2:
        events = draw(st.lists(st.sampled_from(named), min_size=2, max_size=3, unique=True))
        pattern = escape(draw(st.sampled_from(PATTERNS)))
        interval = draw(st.sampled_from(["0.05", "2.0", "100"]))
        scope.append(
            f'<temporal id="{"abcdefgh"[len(ids)]}" events="{",".join(events)}" '
            f'max_interval="{interval}"><pattern>{pattern}</pattern></temporal>'
        )
    tunables = draw(st.lists(st.sampled_from(sorted(TUNABLES)), max_size=4, unique=True))
    rendered = ""
    for name in tunables:
        value = draw(st.sampled_from(TUNABLES[name]))
        if draw(st.integers(0, 9)) == 9:  # now and then, anything (the check fuzzer's values)
            value = draw(text_values)
        rendered += f" {name}={quoteattr(value)}"
    text = (
        '<imROS project="fuzz">\n  <scope>\n    ' + "\n    ".join(scope) + "\n  </scope>\n"
        f'  <detect inv="p.inv"{rendered}><bag>{escape(train)}</bag></detect>\n</imROS>\n'
    )
    data = text.encode()
    if draw(st.integers(0, 4)) == 4:  # one case in five, edited at random
        data = mutate(draw, data)
    return data


def damage(draw: st.DrawFn, source: bytes) -> bytes:
    """A bag with 1 to 3 kinds of damage: cut short, a span overwritten with random bytes or
    zeros, its index dropped (``index_pos`` 0)."""
    data = bytearray(source)
    for _ in range(draw(st.integers(1, 3))):
        kind = draw(st.sampled_from(["cut", "overwrite", "zeros", "unindex"]))
        where = draw(st.integers(0, max(len(data) - 1, 0)))
        if kind == "cut":
            del data[where:]
        elif kind == "overwrite":
            span = draw(st.binary(min_size=1, max_size=64))
            data[where : where + len(span)] = span
        elif kind == "zeros":
            data[where : where + draw(st.integers(1, 256))] = bytes(draw(st.integers(1, 256)))
        elif b"index_pos=" in data:
            field = data.index(b"index_pos=") + len(b"index_pos=")
            data[field : field + 8] = bytes(8)
    return bytes(data)


@st.composite
def cases(draw: st.DrawFn, bags: dict[str, Path]) -> tuple[bytes, str, dict[str, bytes]]:
    """A case: the configuration, the bag to replay (a name of ``bags`` or a file of the
    case), and the files to write in the case's folder first (a damaged bag; the graph file,
    which infer then reads)."""
    files = {}
    if draw(st.booleans()):
        files["graph.yaml"] = GRAPH.encode()
    if draw(st.integers(0, 3)) == 3:  # one case in four reads a damaged copy of a bag
        source = bags[draw(st.sampled_from(["train", "odd"]))].read_bytes()
        files["damaged.bag"] = damage(draw, source)
    trains = [str(bags["train"]), str(bags["odd"]), *(["damaged.bag"] if files else [])]
    config = draw(configurations(trains))
    replayed = draw(st.sampled_from([*BAGS, *(["damaged.bag"] if files else [])]))
    return config, replayed, files


@dataclass
class Outcome:
    """What one case did: each command's exit status, and the first crash (None: none)."""

    statuses: dict[str, int] = field(default_factory=dict)
    crash: str | None = None


def run_case(
    config: bytes,
    replay_bag: Path,
    folder: Path | None = None,
    files: dict[str, bytes] | None = None,
) -> Outcome:
    """``check``, ``infer`` and (if it wrote invariants) ``replay`` on one configuration,
    in a fresh folder (removed afterwards unless ``folder`` is given) holding ``files``
    (a relative ``replay_bag`` is one of them)."""
    work = folder or Path(tempfile.mkdtemp(prefix="imrosc-fuzz-"))
    outcome = Outcome()
    try:
        for name, content in (files or {}).items():
            (work / name).write_bytes(content)
        replay_bag = work / replay_bag
        graph = ["--graph", str(work / "graph.yaml")] if (work / "graph.yaml").exists() else []
        config_path = work / "p.xml"
        config_path.write_bytes(config)
        inv = work / "p.inv"
        steps = [
            ("check", ["check", str(config_path)]),
            ("infer", ["infer", str(config_path), "-j", "1", "-q", *graph]),
            ("replay", ["replay", str(inv), str(replay_bag), "-q", "--format", "json"]),
        ]
        runner = CliRunner()
        for name, args in steps:
            if name == "replay" and not inv.exists():
                break
            result = runner.invoke(main, args)
            outcome.statuses[name] = result.exit_code
            error = result.exception
            if error is not None and not isinstance(error, SystemExit):
                assert result.exc_info is not None
                frame = traceback.extract_tb(result.exc_info[2])[-1]
                where = f"{Path(frame.filename).name}:{frame.lineno}"
                outcome.crash = f"{name}: {type(error).__name__} at {where}: {error}"[:300]
                break
            if "Traceback" in result.output:
                outcome.crash = f"{name}: a traceback in its output"
                break
            if result.exit_code not in DOCUMENTED[name]:
                last = (result.stderr.strip().splitlines() or [""])[-1]
                outcome.crash = f"{name}: exit status {result.exit_code}: {last}"[:300]
                break
    finally:
        if folder is None:
            shutil.rmtree(work, ignore_errors=True)
    return outcome
