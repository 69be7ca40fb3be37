"""The catalogue read bag by bag on its own (``note_bag``, on any process: a pool, a cluster's
worker) and merged in bag order is the catalogue of reading the bags in turn, whatever the bags
and their order: types decided by the first bag of a topic, drift, unknown types, publishers,
record topics, bad records and bad bags."""

from __future__ import annotations

import shutil
from collections.abc import Iterator, Sequence
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from imrosc import records
from imrosc.bags import BagError, discover_bags, open_bag, recovered_diagnostic
from imrosc.diagnostics import make
from imrosc.graph.bags import read_bag_graphs
from imrosc.graph.model import SOURCE_CALLERID, SOURCE_RECORDS
from imrosc.msgtypes import flatten
from imrosc.translate.catalog import (
    BagNote,
    Catalog,
    _note_records,
    _observed_lengths,
    build_catalog,
    note_bag,
    note_in_pool,
)
from tests.translate import Msg, msg, unknown_type_bag, write_bag

FIXTURES = Path(__file__).parent.parent / "fixtures"
STRING, FLOATS = "std_msgs/msg/String", "std_msgs/msg/Float32MultiArray"


def _in_turn(catalog: Catalog, bag: Path) -> None:
    """The catalogue's reading of one bag as it was before bags were noted on their own
    (the reference)."""
    with open_bag(bag) as reader:
        warning = recovered_diagnostic(bag, reader)
        if warning is not None:
            catalog.diagnostics.append(warning)
        count = 0
        for connection in reader.connections:
            count += connection.msgcount
            if connection.topic in records.RECORD_TOPICS:
                continue
            known = catalog.types.get(connection.topic)
            if known is not None and connection.msgtype not in reader.typestore.fielddefs:
                message = (
                    f"topic {connection.topic}: unknown message type {connection.msgtype} in "
                    f"this bag (it stores no definition of it); its messages are skipped"
                )
                catalog.diagnostics.append(make(str(bag), 1, 1, "bag-error", message))
                continue
            if known is None:
                try:
                    fields = flatten(reader.typestore, connection.msgtype)
                except KeyError as missing:
                    message = (
                        f"topic {connection.topic}: unknown message type {missing.args[0]} (the "
                        f"bag stores no definition of it); the topic is skipped"
                    )
                    catalog.unusable.setdefault(connection.topic, (bag, message))
                    continue
                fields = _observed_lengths(reader, connection, fields)
                catalog.types[connection.topic] = (connection.msgtype, fields)
            elif known[0] != connection.msgtype:
                message = (
                    f"topic {connection.topic} has type {connection.msgtype} here but "
                    f"{known[0]} in an earlier bag; fields are matched by name"
                )
                catalog.drift.setdefault(connection.topic, []).append((bag, message))
            callerid = getattr(connection.ext, "callerid", None)
            if callerid:
                catalog.callerids.setdefault(connection.topic, set()).add(callerid)
        catalog.messages[bag] = count
        _note_records(catalog, reader, bag)


def reference(paths: Sequence[Path]) -> Catalog:
    catalog = Catalog()
    for path in paths:
        found, problems = discover_bags(path)
        catalog.diagnostics += problems
        for bag in found:
            try:
                _in_turn(catalog, bag)
            except BagError as error:
                catalog.diagnostics.append(error.diagnostic())
                catalog.has_records.discard(bag)
                catalog.messages.pop(bag, None)
                continue
            catalog.bags.append(bag)
    catalog.bags = sorted(dict.fromkeys(catalog.bags))
    return catalog


def assert_same(got: Catalog, expected: Catalog) -> None:
    """``got`` is the reference catalogue, and its bags' graphs are those the graph's own
    reading of the catalogued bags gives (the bags are opened once for both)."""
    assert replace(got, graphs={}, graph_problems=[]) == expected
    assert got.bag_graphs() == read_bag_graphs(got.bags)


def _record(topic: str, time: float, value: object) -> Msg:
    text = value if isinstance(value, str) else records.encode(value)  # type: ignore[arg-type]
    return msg(topic, time, STRING, "/imrosc_record", data=text)


def _run(offset: float, variant: int) -> list[Msg]:
    """Two seconds of a small system; each ``variant`` differs in types, publishers, the
    length of ``/scan``'s array and its records."""
    found = []
    for i in range(20):
        t = offset + i * 0.1
        found.append(msg("/in", t, "std_msgs/msg/Int32", f"/src{variant % 2}", data=i % 3))
        out = "std_msgs/msg/Float32" if variant == 1 else "std_msgs/msg/Float64"
        found.append(msg("/out", t + 0.01, out, "/ctl", data=float(i)))
        if variant == 2 and i == 5:  # a second publisher of another type in the same bag
            found.append(msg("/out", t + 0.02, "std_msgs/msg/Float32", "/other", data=1.0))
        values = np.zeros(3 + variant, dtype=np.float32)
        found.append(msg("/scan", t + 0.03, FLOATS, "/scanner", data=values))
    params = {"/gain": 2.5} if variant != 1 else {"/gain": "high", f"/v{variant}": 1}
    found.append(_record(records.PARAMS_TOPIC, offset + 0.05, records.ParamSnapshot(params)))
    call = records.ServiceCall(
        "/srv", "/ctl", "/server", {f"id{variant}": 1}, {"ok": True}, True, offset, 0.01
    )
    found.append(_record(records.SRVS_TOPIC, offset + 0.06, call))
    ends = records.TopicEnds(frozenset({f"/ctl{variant}"}), frozenset({"/loc"}))
    snapshot = records.ArchSnapshot({"/out": ends}, {"/srv": frozenset({"/server"})})
    found.append(_record(records.ARCH_TOPIC, offset + 0.07, snapshot))
    if variant == 2:
        found.append(_record(records.PARAMS_TOPIC, offset + 0.08, "{not json"))
    return found


@pytest.fixture(scope="module")
def entries(tmp_path_factory: pytest.TempPathFactory) -> list[Path]:
    """Paths a user may give: bags, a folder of bags, and bad ones."""
    folder = tmp_path_factory.mktemp("notes")
    paths = [write_bag(folder / f"v{v}.bag", _run(10.0 * v, v)) for v in range(4)]
    group = folder / "group"
    group.mkdir()
    write_bag(group / "a.bag", _run(100.0, 1))
    write_bag(group / "b.bag", _run(110.0, 3))
    (group / "notes.txt").write_text("not a bag\n")
    whole = (folder / "v0.bag").read_bytes()
    (folder / "truncated.bag").write_bytes(whole[:4200])
    shutil.copyfile(FIXTURES / "bags" / "bag-empty.bag", folder / "empty.bag")
    unknown = unknown_type_bag(folder / "unknown_types")
    return [*paths, group, folder / "truncated.bag", folder / "empty.bag", unknown]


def _backwards(bags: Sequence[Path]) -> Iterator[BagNote]:
    """Notes read last bag first, given in bag order (as a cluster's may complete)."""
    notes = [note_bag(bag) for bag in reversed(bags)]
    yield from reversed(notes)


@settings(
    max_examples=15, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture]
)
@given(data=st.data())
def test_bags_noted_on_their_own_merge_into_the_catalogue_of_reading_them_in_turn(
    entries: list[Path], data: st.DataObject
) -> None:
    order = data.draw(st.permutations(entries), "order")
    chosen = order[: data.draw(st.integers(1, len(order)), "how many")]
    expected = reference(chosen)
    assert_same(build_catalog(chosen), expected)
    assert_same(build_catalog(chosen, _backwards), expected)


def test_the_cases_are_all_met_and_a_pool_gives_the_same(entries: list[Path]) -> None:
    """The bags above hold every case the merge tells apart, and forked processes give the
    catalogue of one."""
    expected = reference(entries)
    assert set(expected.drift) == {"/out"}
    assert "/out" in expected.callerids and len(expected.callerids["/in"]) == 2
    assert expected.types["/scan"][1][-1].length == 3
    assert expected.params == {"/gain": "numeric", "/v1": "numeric"}
    assert [(Path(d.path).name, d.message.split(":")[0]) for d in expected.diagnostics] == [
        ("v2.bag", "bad /imrosc/params record at 20.080000000"),
        ("notes.txt", "not a bag"),
        ("truncated.bag", "cannot open bag"),
        ("unknown_types", "topic /out"),
    ]
    graph = build_catalog(entries).bag_graphs().graph
    assert graph.sources == (SOURCE_RECORDS, SOURCE_CALLERID) and "/ctl1" in graph.nodes
    unknown_first = reference([entries[-1], *entries[:-1]])
    assert "/out" in unknown_first.unusable
    assert_same(build_catalog(entries, note_in_pool(2)), expected)
    assert_same(build_catalog([entries[-1], *entries[:-1]], note_in_pool(2)), unknown_first)
