"""Every condition form the grammar accepts goes through infer and replay: a topic operand
(docs/config.md) learns the same conditional invariants as the topic's last name segment, and
replay checks them (it used to stop with ``KeyError: 'op'``)."""

from __future__ import annotations

from pathlib import Path
from typing import Any
from xml.sax.saxutils import escape

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from imrosc.check import check_file
from imrosc.detect import run_detect
from imrosc.diagnostics import has_errors
from imrosc.replay import replay
from tests.translate import Msg, msg, write_bag

CONFIG = """<imROS project="c">
  <scope>
    <publish id="a" conds="1">/a/x</publish>
    <condition id="1"><topic>/a/state</topic><value>VALUE</value></condition>
  </scope>
  <detect inv="c.inv" budget="0" discrete="0"><bag>train.bag</bag></detect>
</imROS>
"""


def run(high: float) -> list[Msg]:
    """20 s: /a/state 4 for the first 10 s then 3; /a/x at 10 Hz, between 0 and 1 in state 4,
    ``high`` at the end of state 3."""
    found: list[Msg] = []
    for k in range(200):
        time = k / 10
        state = 4 if time < 10 else 3
        found.append(msg("/a/state", time, "std_msgs/msg/UInt8", "/s", data=state))
        value = (k % 10) / 10 if state == 4 else (high if k == 199 else 5.0)
        found.append(msg("/a/x", time + 0.01, "std_msgs/msg/Float64", "/p", data=value))
    return found


@pytest.mark.parametrize("value", ["state == 4", "/a/state == 4", "not (/a/state != 4)"])
def test_a_condition_form_is_learnt_and_replayed(tmp_path: Path, value: str) -> None:
    write_bag(tmp_path / "train.bag", run(5.0))
    config = tmp_path / "c.xml"
    config.write_text(CONFIG.replace("VALUE", value))
    result = run_detect(config, workers=1)
    document: Any = result.document
    assert document is not None
    conditional = [i for i in document["invariants"] if i["point"] != "a"]
    texts = {i["text"] for i in conditional}
    assert any("<= 0.9" in text for text in texts), texts  # learnt in state 4 only
    write_bag(tmp_path / "normal.bag", run(5.0))
    (normal,) = replay(document, [tmp_path / "normal.bag"])
    assert not normal.violations


def test_a_topic_operand_condition_catches_a_fault_while_it_holds(tmp_path: Path) -> None:
    write_bag(tmp_path / "train.bag", run(5.0))
    config = tmp_path / "c.xml"
    config.write_text(CONFIG.replace("VALUE", "/a/state == 4"))
    document: Any = run_detect(config, workers=1).document
    faulty = [
        msg(m.topic, m.time, m.msgtype, m.callerid, data=3.0)
        if m.topic == "/a/x" and m.time == 5.01
        else m
        for m in run(5.0)
    ]
    write_bag(tmp_path / "faulty.bag", faulty)
    (result,) = replay(document, [tmp_path / "faulty.bag"])
    points = {v.point for v in result.violations}
    assert "a?1" in points, points  # the conditional point, checked while state is 4


# -- every condition check accepts goes through infer and replay ------------------------------

_OPERANDS = st.sampled_from(["state", "data", "/a/state", "1", "0.5", "true", '"x"', "-2"])


def _expressions(children: st.SearchStrategy[str]) -> st.SearchStrategy[str]:
    binary = st.tuples(
        children,
        st.sampled_from(["+", "-", "*", "/", "%", "==", "!=", "<", ">=", "and", "or"]),
        children,
    ).map(lambda t: f"({t[0]} {t[1]} {t[2]})")
    unary = st.tuples(st.sampled_from(["not ", "-"]), children).map("".join)
    return st.one_of(binary, unary)


@settings(max_examples=25, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(st.recursive(_OPERANDS, _expressions, max_leaves=5))
def test_a_condition_check_accepts_never_crashes_infer_or_replay(
    tmp_path_factory: pytest.TempPathFactory, value: str
) -> None:
    folder = tmp_path_factory.mktemp("fuzz")
    write_bag(folder / "train.bag", run(5.0))
    config = folder / "c.xml"
    config.write_text(CONFIG.replace("VALUE", escape(value)))
    if has_errors(check_file(config)):
        return  # check refuses it: nothing later sees it
    result = run_detect(config, workers=1)
    assert result.document is not None, [d.as_text() for d in result.diagnostics]
    (replayed,) = replay(result.document, [folder / "train.bag"])
    assert replayed.error is None
