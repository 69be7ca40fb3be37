"""Architecture checks: maximum and minimum node sets, edge-triggered reports."""

from __future__ import annotations

from collections.abc import Iterable, Mapping, Sequence
from typing import Any

from imrosc.runtime.arch import ArchChecks, node_name
from imrosc.runtime.violation import Violation

POINT = "arch"


def invariant(ident: str, kind: str, resource: str, nodes: Iterable[str]) -> dict[str, Any]:
    noun = kind.partition("_")[2]
    listed = sorted(nodes)
    return {
        "id": ident,
        "family": "architecture",
        "kind": kind,
        "point": POINT,
        "variables": [f"{noun}({resource})"],
        "text": f"{kind}({resource}) = {{{', '.join(listed)}}}",
        "params": {"resource": resource, "nodes": listed},
    }


INVARIANTS = [
    invariant("max_pub", "max_pubs", "/t", ["/a"]),
    invariant("min_pub", "min_pubs", "/t", ["/a"]),
    invariant("max_sub", "max_subs", "/t", ["/x", "/y"]),
    invariant("min_sub", "min_subs", "/t", ["/x", "/y"]),
    invariant("max_srv", "max_srvs", "/s", ["/server"]),
    invariant("min_srv", "min_srvs", "/s", ["/server"]),
    invariant("nobody", "max_pubs", "/quiet", []),
    {"id": "other", "family": "bounds", "kind": "upper", "variables": ["x"], "params": {}},
]


def snapshot(
    pubs: Sequence[str] = ("/a",),
    subs: Sequence[str] = ("/x", "/y"),
    srvs: Sequence[str] = ("/server",),
    quiet: Sequence[str] = (),
) -> dict[str, dict[str, frozenset[str]]]:
    return {
        "pub": {"/t": frozenset(pubs), "/quiet": frozenset(quiet)},
        "sub": {"/t": frozenset(subs)},
        "srv": {"/s": frozenset(srvs)},
    }


def seen(found: Sequence[Violation]) -> list[tuple[float, str, Any, str]]:
    return [(v.time, v.invariant, v.observed, v.expected) for v in found]


def test_a_healthy_graph_breaks_nothing() -> None:
    checks = ArchChecks(INVARIANTS, POINT)
    assert len(checks.items) == 7  # the bounds invariant is not architecture
    assert checks.check(0.0, snapshot()) == []
    # a missing resource is the empty set: nobody may publish on /quiet
    assert checks.check(1.0, {"pub": {"/t": frozenset({"/a"})}}, ("pub",)) == []


def test_unexpected_and_missing_nodes() -> None:
    checks = ArchChecks(INVARIANTS, POINT)
    found = checks.check(1.0, snapshot(pubs=("/a", "/b"), subs=("/x",), srvs=(), quiet=("/q",)))
    assert seen(found) == [
        (1.0, "max_pub", ["/b"], "only {/a}"),
        (1.0, "min_sub", ["/x"], "at least {/x, /y} (missing /y)"),
        (1.0, "min_srv", [], "at least {/server} (missing /server)"),
        (1.0, "nobody", ["/q"], "only {}"),
    ]
    first = found[0]
    assert (first.point, first.family, first.kind) == (POINT, "architecture", "max_pubs")
    assert first.text == "max_pubs(/t) = {/a}"
    assert seen(checks.check(2.0, snapshot(pubs=()))) == [
        (2.0, "min_pub", [], "at least {/a} (missing /a)")
    ]


def test_reports_are_edge_triggered() -> None:
    checks = ArchChecks(INVARIANTS, POINT)
    broken = snapshot(pubs=("/a", "/b"))
    assert seen(checks.check(0.0, broken)) == [(0.0, "max_pub", ["/b"], "only {/a}")]
    assert checks.check(1.0, broken) == []  # the same break: not again
    # what breaks it changed: reported again
    wider = snapshot(pubs=("/a", "/b", "/c"))
    assert seen(checks.check(2.0, wider)) == [(2.0, "max_pub", ["/b", "/c"], "only {/a}")]
    assert checks.check(3.0, wider) == []
    assert checks.check(4.0, snapshot()) == []  # healed
    assert seen(checks.check(5.0, broken)) == [(5.0, "max_pub", ["/b"], "only {/a}")]
    checks.reset()  # a new run reports a standing break again
    assert seen(checks.check(0.0, broken)) == [(0.0, "max_pub", ["/b"], "only {/a}")]


def test_a_source_that_tells_publishers_only() -> None:
    checks = ArchChecks(INVARIANTS, POINT)
    publishers_only: Mapping[str, Mapping[str, frozenset[str]]] = {
        "pub": {"/t": frozenset({"/a", "/b"})}
    }
    found = checks.check(0.0, publishers_only, kinds=("pub",))
    # no subscribers or servers known: their minimum sets are not checked
    assert seen(found) == [(0.0, "max_pub", ["/b"], "only {/a}")]
    everything = checks.check(1.0, publishers_only)
    assert [v.invariant for v in everything] == ["min_sub", "min_srv"]


def test_a_source_that_tells_publishers_only_does_not_know_unlisted_topics() -> None:
    checks = ArchChecks(INVARIANTS, POINT)
    # /t has published nothing yet: neither its minimum nor its maximum is checked
    assert checks.check(0.0, {"pub": {"/other": frozenset({"/z"})}}, kinds=("pub",)) == []
    found = checks.check(1.0, {"pub": {"/t": frozenset({"/b"})}}, kinds=("pub",))
    assert seen(found) == [
        (1.0, "max_pub", ["/b"], "only {/a}"),
        (1.0, "min_pub", ["/b"], "at least {/a} (missing /a)"),
    ]


def test_anonymous_names_have_one_stable_form() -> None:
    assert node_name("/record_1553088502272947227") == "/record_*"
    assert node_name("/rviz_1553074025852102923") == "/rviz_*"
    assert node_name("/listener_12345_1553088502272") == "/listener_*"
    assert node_name("/ns/talker_1234567890") == "/ns/talker_*"
    for name in ("/camera_2", "/robot_1/driver", "/id_123456789", "/scan_2019_06", "/_1234567890"):
        assert node_name(name) == name


def test_anonymous_publishers_of_another_run_break_nothing() -> None:
    # an invariants file holding the names of one run (or their stable form) and a run with
    # new numbers: the same nodes
    for required in ("/rviz_1553074025852102923", "/rviz_*"):
        invariants = [
            invariant("max", "max_pubs", "/rosout", ["/a", required]),
            invariant("min", "min_pubs", "/rosout", ["/a", required]),
        ]
        checks = ArchChecks(invariants, POINT)
        later = frozenset({"/a", "/rviz_1553099999999999999"})
        assert checks.check(0.0, {"pub": {"/rosout": later}}) == []
        missing = checks.check(1.0, {"pub": {"/rosout": frozenset({"/a"})}})
        assert seen(missing) == [(1.0, "min", ["/a"], "at least {/a, /rviz_*} (missing /rviz_*)")]
