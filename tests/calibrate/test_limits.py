"""Each family's limits: which, their supports in a unit, how they widen."""

from __future__ import annotations

import math
from typing import Any

import pytest

from imrosc.calibrate.envelope import vertices
from imrosc.calibrate.limits import (
    Slot,
    members,
    merge_sets,
    raw,
    set_broken,
    slots,
    support,
    to_scale,
    widened,
    with_value,
)


def inv(family: str, kind: str = "range", **params: Any) -> dict[str, Any]:
    return {"family": family, "kind": kind, "params": params, "variables": ["x"]}


def test_slots_per_family() -> None:
    assert [(s.param, s.upper) for s in slots(inv("bounds", min=0.0, max=1.0))] == [
        ("min", False),
        ("max", True),
    ]
    assert [s.param for s in slots(inv("bounds", "upper", max=1.0))] == ["max"]
    assert {s.scale for s in slots(inv("variance", min=0.1, max=2.0))} == {"log"}
    low, _ = slots(inv("frequency", min=19.0, max=21.0, window=0.5))
    assert low.scale == "count" and low.quantum == 2.0
    interval = inv(
        "interval", "interval", min_time=0.1, max_time=1.0, min_events={}, max_events={"b": 2}
    )
    assert [(s.param, s.index) for s in slots(interval)] == [
        ("min_time", None),
        ("max_time", None),
        ("max_events", "b"),
    ]
    assert len(slots(inv("polygon", "hull", A=[[1, 0]] * 5, b=[1.0] * 5))) == 5
    assert slots(inv("linear", a=1.0, b=2.0)) == []


def test_lower_limits_and_logs_read_outward() -> None:
    low = Slot("min", None, False, "add")
    assert to_scale(-3.0, low) == 3.0
    log_low = Slot("min", None, False, "log")
    assert to_scale(math.e, log_low) == pytest.approx(-1.0)
    assert to_scale(0.0, log_low) == math.inf  # a zero variance: nothing lies below


def test_a_widened_variance_floor_stays_above_zero() -> None:
    slot = Slot("min", None, False, "log")
    base = to_scale(0.01, slot)
    assert base is not None
    floor = widened(base, 2.0, slot)  # a factor e^2 below
    assert floor == pytest.approx(0.01 / math.e**2)
    assert floor > 0  # a frozen sensor (variance 0) still breaks it


def test_counts_move_by_whole_quanta_at_least_one() -> None:
    slot = Slot("max", None, True, "count", 0.5)
    assert widened(20.0, 0.0, slot) == 20.5
    assert widened(20.0, 0.6, slot) == 21.5
    low = Slot("min", None, False, "count", 1.0)
    assert widened(-0.5, 0.0, low) == 0.0  # never below zero


def test_polygon_support_is_the_units_reach_along_each_normal() -> None:
    merged = {"A": [[1.0, 0.0], [0.0, 1.0], [-1.0, -1.0]], "b": [1.0, 1.0, 0.0]}
    unit = {"vertices": [[0.0, 0.0], [0.5, 0.0], [0.0, 0.25]]}
    reach = [support(merged, unit, Slot("b", k, True, "add")) for k in range(3)]
    assert reach == [0.5, 0.25, 0.0]
    assert support(merged, None, Slot("b", 0, True, "add")) is None


def test_values_written_back_where_they_were_read() -> None:
    params: dict[str, Any] = {"b": [1.0, 2.0], "max_events": {"b": 2}, "max": 3.0}
    for slot, value in [
        (Slot("b", 1, True, "add"), 2.5),
        (Slot("max_events", "b", True, "count"), 3.0),
        (Slot("max", None, True, "add"), 4.0),
    ]:
        with_value(params, slot, value)
        assert raw(params, slot) == value
    assert raw({"min_events": {}}, Slot("min_events", "a", False, "count")) == 0.0


def test_sets_break_on_new_values_or_missing_nodes() -> None:
    one_of = inv("one-of", values=[1.0, 2.0])
    assert members(one_of) == frozenset({1.0, 2.0})
    assert set_broken(one_of, frozenset({3.0}), frozenset({1.0, 2.0}))
    assert not set_broken(one_of, frozenset({1.0}), frozenset({1.0, 2.0}))
    required = inv("architecture", "min_pubs", nodes=["/a", "/b"])
    assert set_broken(required, frozenset({"/a"}), frozenset({"/a", "/b"}))
    assert merge_sets(required, [frozenset({"/a", "/b"}), frozenset({"/a"})]) == {"/a"}


def test_offset_half_planes_give_a_larger_polygon() -> None:
    square = [[-1.0, -1.0], [1.0, -1.0], [1.0, 1.0], [-1.0, 1.0]]
    normals = [[0.0, -1.0], [1.0, 0.0], [0.0, 1.0], [-1.0, 0.0]]
    grown = vertices(normals, [2.0, 1.0, 1.0, 1.0], square)
    assert sorted(map(tuple, grown)) == [(-1.0, -2.0), (-1.0, 1.0), (1.0, -2.0), (1.0, 1.0)]
    assert grown[0] == [-1.0, -2.0]  # from the lexicographic minimum, counter-clockwise
