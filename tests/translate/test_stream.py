"""The translator: Algorithm 1 pairing, chunk independence, conditions, records, events."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from imrosc import records
from imrosc.infer.core import Samples
from imrosc.translate.stream import BagTranslator
from tests.translate import Msg, msg, specs_for, write_bag

CONFIG = """<imROS project="t">
  <scope>
    <publish id="a"><topic>/out</topic><topic>/in</topic><param>/gain</param></publish>
    <publish id="b" conds="1">/out</publish>
    <call id="c">/srv</call>
    <param id="p">/gain</param>
    <arch id="d">pub,sub,srv</arch>
    <temporal id="e" events="a,c"/>
    <condition id="1"><topic>/mode</topic><value>mode == 1</value></condition>
  </scope>
</imROS>
"""


def record(topic: str, time: float, value: Any) -> Msg:
    return msg(topic, time, "std_msgs/msg/String", "/imrosc_record", data=records.encode(value))


def trace() -> list[Msg]:
    messages = [
        record(records.PARAMS_TOPIC, 0.1, records.ParamSnapshot({"/gain": 2.5})),
        record(
            records.ARCH_TOPIC,
            0.2,
            records.ArchSnapshot(
                {"/out": records.TopicEnds(frozenset({"/ctl"}), frozenset({"/motor"}))},
                {"/srv": frozenset({"/server"})},
            ),
        ),
        msg("/out", 0.5, "std_msgs/msg/Float64", "/ctl", data=-1.0),  # before any /in: unpaired
        msg("/mode", 0.6, "std_msgs/msg/UInt8", "/sm", data=0),
    ]
    for i in range(1, 6):
        messages.append(msg("/in", i, "std_msgs/msg/Int32", "/src", data=10 * i))
        messages.append(msg("/out", i + 0.5, "std_msgs/msg/Float64", "/ctl", data=float(i)))
        messages.append(msg("/mode", i + 0.7, "std_msgs/msg/UInt8", "/sm", data=i % 2))
    call = records.ServiceCall(
        "/srv", "/ctl", "/server", {"task_id": 3}, {"ok": True}, True, 2.0, 0.25
    )
    messages.append(record(records.SRVS_TOPIC, 2.1, call))
    return messages


def collect(translator: BagTranslator, bag: Path) -> dict[str, dict[str, list[Any]]]:
    out: dict[str, dict[str, list[Any]]] = {}
    for samples in translator.translate(bag, 0):
        point = out.setdefault(samples.point, {"time": []})
        point["time"] += samples.time.tolist()
        for name, column in samples.columns.items():
            point.setdefault(name, []).extend(column.tolist())
    return out


@pytest.fixture
def bag(tmp_path: Path) -> Path:
    return write_bag(tmp_path / "run.bag", trace())


def test_latest_input_pairing_drops_unpaired_and_attaches_params(bag: Path) -> None:
    specs, layouts, catalog = specs_for(CONFIG, [bag])
    got = collect(BagTranslator(specs, layouts, catalog.callerids), bag)
    a = got["a"]
    assert a["time"] == [1.5, 2.5, 3.5, 4.5, 5.5]
    assert a["out.data"] == [1.0, 2.0, 3.0, 4.0, 5.0]
    assert a["in.data"] == [10.0, 20.0, 30.0, 40.0, 50.0]
    assert a["/gain"] == [2.5] * 5


@pytest.mark.parametrize("chunk", [1, 2, 3, 7, 10_000])
def test_chunk_size_does_not_change_samples(bag: Path, chunk: int) -> None:
    specs, layouts, catalog = specs_for(CONFIG, [bag])
    whole = collect(BagTranslator(specs, layouts, catalog.callerids), bag)
    assert collect(BagTranslator(specs, layouts, catalog.callerids, chunk=chunk), bag) == whole


def test_declared_condition_keeps_only_matching_samples(bag: Path) -> None:
    specs, layouts, catalog = specs_for(CONFIG, [bag])
    got = collect(BagTranslator(specs, layouts, catalog.callerids), bag)
    # /mode before /out at i+0.5 is the one published at (i-1)+0.7 = (i-1) % 2
    assert got["b?1"]["out.data"] == [2.0, 4.0]
    assert got["b"]["out.data"] == [-1.0, 1.0, 2.0, 3.0, 4.0, 5.0]


def test_records_feed_call_param_arch_points_and_events(bag: Path) -> None:
    specs, layouts, catalog = specs_for(CONFIG, [bag])
    got = collect(BagTranslator(specs, layouts, catalog.callerids), bag)
    assert got["c"]["srv.request.task_id"] == [3.0]
    assert got["c"]["srv.response.ok"] == [1.0]
    assert got["c"]["srv.delay"] == [0.25]
    # the record at 0.1 s (the bag's start: no tick of its own), then the value in force
    # once a second: a parameter that keeps its value still gets samples to justify it
    assert got["p"]["time"] == pytest.approx([0.1, 1.1, 2.1, 3.1, 4.1, 5.1])
    assert got["p"]["/gain"] == [2.5] * 6
    # the snapshot at 0.2 s, then one sample a second from the bag start (0.1 s) to its end
    assert got["d"]["time"] == pytest.approx([0.2, 1.1, 2.1, 3.1, 4.1, 5.1])
    assert got["d"]["pubs(/out)"] == [frozenset({"/ctl"})] * 6
    assert got["d"]["subs(/out)"] == [frozenset({"/motor"})] * 6
    assert got["d"]["srvs(/srv)"] == [frozenset({"/server"})] * 6
    assert got["e"]["event"] == ["a", "a", "c", "a", "a", "a", "a"]


def test_bags_without_records_give_publishers_from_callerid(tmp_path: Path) -> None:
    bag = write_bag(
        tmp_path / "plain.bag", [m for m in trace() if not m.topic.startswith("/imrosc")]
    )
    config = CONFIG.replace('<call id="c">/srv</call>', "").replace('events="a,c"', 'events="a,b"')
    specs, layouts, catalog = specs_for(config, [bag])
    got = collect(BagTranslator(specs, layouts, catalog.callerids), bag)
    # a change at each connection's first message (/out 0.5 s, /mode 0.6 s, /in 1 s), then
    # one sample a second from the bag's start (0.5 s)
    assert got["d"]["time"] == pytest.approx([0.5, 0.6, 1.0, 1.5, 2.5, 3.5, 4.5, 5.5])
    assert got["d"]["pubs(/out)"] == [frozenset({"/ctl"})] * 8
    # /in is unknown before its first message (no sample of it), not empty
    assert got["d"]["pubs(/in)"] == [None, None] + [frozenset({"/src"})] * 6
    assert "subs(/out)" not in got["d"]  # callerids say nothing of subscribers


def test_nan_and_inf_pass_through(tmp_path: Path) -> None:
    bag = write_bag(
        tmp_path / "odd.bag",
        [
            msg("/out", 1.0, "std_msgs/msg/Float64", data=float("nan")),
            msg("/out", 2.0, "std_msgs/msg/Float64", data=float("inf")),
        ],
    )
    config = '<imROS project="t"><scope><publish id="a">/out</publish></scope></imROS>'
    specs, layouts, catalog = specs_for(config, [bag])
    (samples,) = list(BagTranslator(specs, layouts, catalog.callerids).translate(bag, 0))
    assert isinstance(samples, Samples)
    values = samples.column("out.data")
    assert np.isnan(values[0]) and np.isposinf(values[1])
    assert json.dumps(samples.time.tolist()) == "[1.0, 2.0]"


def test_parameter_points_follow_changes_and_ticks_across_chunks(tmp_path: Path) -> None:
    messages = [msg("/out", 0.0, "std_msgs/msg/Float64", "/ctl", data=0.0)]
    for k, (time, gain) in enumerate([(0.5, 1.0), (2.25, 3.0), (2.5, 4.0)]):
        snapshot = records.ParamSnapshot({"/gain": gain, "/other": k})
        messages.append(record(records.PARAMS_TOPIC, time, snapshot))
    messages += [msg("/out", t / 4, "std_msgs/msg/Float64", "/ctl", data=t) for t in range(1, 20)]
    bag = write_bag(tmp_path / "params.bag", sorted(messages, key=lambda m: m.time))
    config = '<imROS project="t"><scope><param id="p">/gain</param></scope></imROS>'
    specs, layouts, catalog = specs_for(config, [bag])
    for chunk in (1, 3, 1000):  # the clock's state carries from chunk to chunk
        got = collect(BagTranslator(specs, layouts, catalog.callerids, chunk=chunk), bag)
        assert got["p"]["time"] == pytest.approx([0.5, 1.0, 2.0, 2.25, 2.5, 3.0, 4.0])
        assert got["p"]["/gain"] == [1.0, 1.0, 1.0, 3.0, 4.0, 4.0, 4.0]
