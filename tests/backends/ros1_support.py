"""What the ROS 1 backend's tests share with the ROS 2 backend's: hostile names, value and
quoting checks, the Python 3.8 compile check."""

from __future__ import annotations

import io
import json
import math
import shutil
import subprocess
import sys
import tokenize
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from tests.backends.monitor_support import config_text, invariants_document, write_case
from tests.backends.support import (
    HOSTILE,
)


def python38() -> str | None:
    """A Python 3.8 interpreter that runs (a pyenv shim may name one that is not enabled)."""
    candidates = [
        shutil.which("python3.8"),
        *map(str, Path.home().glob(".pyenv/versions/3.8*/bin/python3.8")),
    ]
    for candidate in candidates:
        if candidate is None:
            continue
        probe = subprocess.run([candidate, "-c", "pass"], capture_output=True, check=False)
        if probe.returncode == 0:
            return candidate
    return None


def assert_same_values(got: Sequence[Any], expected: Sequence[Any]) -> None:
    assert len(got) == len(expected)
    for mine, theirs in zip(got, expected, strict=True):
        assert type(mine) is type(theirs), (mine, theirs)
        if isinstance(mine, float) and math.isnan(mine):
            assert math.isnan(theirs)
        else:
            assert mine == theirs


MARKERS = ("zqsrc", "zqproj", "zqtopic", "zqvalue", "zqtext", "zqvar", "zqpoint", "zqframe")


def _offsets(text: str) -> list[int]:
    starts = [0]
    for line in text.splitlines(keepends=True):
        starts.append(starts[-1] + len(line))
    return starts


def _quoted_spans(text: str) -> list[tuple[int, int]]:
    """Character spans of the string literals and comments of Python source."""
    starts = _offsets(text)
    spans = []
    for token in tokenize.generate_tokens(io.StringIO(text).readline):
        if token.type in (tokenize.STRING, tokenize.COMMENT) or (
            sys.version_info >= (3, 12) and token.type == tokenize.FSTRING_MIDDLE
        ):
            (row, col), (end_row, end_col) = token.start, token.end
            spans.append((starts[row - 1] + col, starts[end_row - 1] + end_col))
    return spans


def assert_markers_only_quoted(name: str, text: str) -> None:
    spans = _quoted_spans(text)
    for marker in MARKERS:
        at = text.find(marker)
        while at >= 0:
            inside = any(start <= at and at + len(marker) <= end for start, end in spans)
            assert inside, f"{marker} reaches code unquoted in {name}: {text[at - 60 : at + 40]!r}"
            at = text.find(marker, at + 1)


def hostile_case(folder: Path) -> Path:
    document = invariants_document({"/zqtopic/cmd": "std_msgs/msg/UInt8"})
    document["source"] = HOSTILE
    variable = document["topics"]["/zqtopic/cmd"]["variables"][0]
    variable["name"] = "zqvar" + HOSTILE
    point = document["points"].pop("a")
    point["variables"][0]["name"] = "zqvar" + HOSTILE
    document["points"]["a?zqpoint" + HOSTILE] = {**point, "condition": "zqpoint" + HOSTILE}
    document["points"]["a"] = point
    document["invariants"] = [
        {
            "id": "zqtext" + HOSTILE,
            "family": "one-of",
            "kind": "one-of",
            "point": "a",
            "condition": None,
            "variables": ["zqvar" + HOSTILE],
            "params": {"values": [1], "zqframe": HOSTILE},
            "text": "zqtext" + HOSTILE,
            "support": {"samples": 1, "runs": 1},
            "confidence": 1.0,
        }
    ]
    value = json.dumps(HOSTILE)  # a double-quoted YAML scalar, escaped as JSON escapes it
    monitor = (
        '<monitor inv="demo.inv" launch="system.launch"><block>/zqtopic/cmd</block>'
        f'<action id="f"><topic>/zqtopic/cmd</topic><value>{{data: {_xml(value)}, '
        f"frame: zqframe}}</value></action><violation>a -> f</violation></monitor>"
    )
    config = write_case(
        folder,
        config_text(
            project="zqproj", scope='<publish id="a">/zqtopic/cmd</publish>', monitor=monitor
        ),
        document,
        name="zqsrc'\"--> x.xml",
    )
    (folder / "graph.yaml").write_text(
        "version: 1\nnodes:\n  /zqtopic/driver:\n    publishes: [/zqtopic/cmd]\n"
        "  /zqtopic/motor:\n    subscribes: [/zqtopic/cmd]\n"
    )
    (folder / "system.launch").write_text(
        '<launch>\n  <node pkg="zqproj" type="motor" name="motor" ns="zqtopic"/>\n</launch>\n'
    )
    return config


def _xml(text: str) -> str:
    return text.replace("&", "&amp;").replace("<", "&lt;").replace(">", "&gt;")
