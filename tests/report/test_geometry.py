"""Values and chart geometry: number spelling, ticks, downsampling, timeline marks."""

from __future__ import annotations

import itertools
import math

import pytest
from hypothesis import given
from hypothesis import strategies as st

from imrosc.report import svg, views
from imrosc.report.values import number, seconds, value


@pytest.mark.parametrize(
    ("item", "text"),
    [
        (4.1, "4.1"),
        (19.0, "19"),
        ("inf", "inf"),
        ([4.2, 3.9], "[4.2, 3.9]"),
        ([[1, 2], [3.5, "nan"]], "[[1, 2], [3.5, nan]]"),
        ({"lo": -2.1}, "{lo: -2.1}"),
        (None, "-"),
        (1e-9, "1e-09"),
        (123456789.123, "123456789.123"),
    ],
)
def test_values(item: object, text: str) -> None:
    assert value(item) == text


def test_seconds() -> None:
    assert seconds(1700000012.3 - 1700000000.0) == "12.300 s"
    assert seconds(math.nan) == "nan s"
    assert number(-1e-300) == "-1e-300"


@given(
    st.floats(min_value=-1e9, max_value=1e9),
    st.floats(min_value=1e-6, max_value=1e9),
    st.integers(min_value=2, max_value=10),
)
def test_ticks_cover_the_domain(lo: float, width: float, count: int) -> None:
    hi = lo + width
    if hi - lo <= 1e-9 * max(abs(lo), 1.0):  # not a width floats can tell apart
        return
    start, stop, values, step = svg.ticks(lo, hi, count)
    slack = 1e-6 * step  # ticks snap values a hair from a step onto it
    assert start <= lo + slack and stop >= hi - slack
    assert 1 <= len(values) - 1 <= 3 * count
    assert all(b > a for a, b in itertools.pairwise(values))
    labels = [svg.tick_label(v, step) for v in values]
    assert len(set(labels)) == len(labels)


def test_ticks_inside_a_fixed_domain() -> None:
    start, stop, values, step = svg.ticks(0.0, 42.5, 8, extend=False)
    assert (start, stop, step) == (0.0, 42.5, 5.0)
    assert values == [0.0, 5.0, 10.0, 15.0, 20.0, 25.0, 30.0, 35.0, 40.0]


def test_thin_and_envelope_keep_the_limit() -> None:
    points = [(float(i), math.sin(i / 10.0)) for i in range(10001)]
    thinned = svg.thin(points, 100)
    assert len(thinned) == 100 and thinned[0] == points[0] and thinned[-1] == points[-1]
    kept = svg.envelope(points, 100)
    assert len(kept) <= 100
    assert kept == sorted(kept)
    assert max(y for _, y in kept) == max(y for _, y in points)
    assert min(y for _, y in kept) == min(y for _, y in points)
    assert svg.envelope(points[:50], 100) == points[:50]


def test_domain_of_one_value_is_widened() -> None:
    assert svg.domain([0.0, 0.0]) == (-0.5, 0.5)
    assert svg.domain([float("nan")]) == (0.0, 1.0)


def test_timeline_merges_episodes_closer_than_a_pixel() -> None:
    episodes = [
        {
            "invariant": "i1",
            "point": "a",
            "family": "bounds",
            "kind": "range",
            "text": "x < 1",
            "first": 100.0 + i * 0.001,
            "last": 100.0 + i * 0.001,
            "count": 1,
            "observed": 2,
            "expected": "< 1",
        }
        for i in range(500)
    ]
    run = views.run(
        {
            "bag": "b.bag",
            "start": 0.0,
            "end": 3600.0,
            "messages": 1,
            "error": None,
            "violations": 500,
            "episodes": episodes,
        }
    )
    chart = svg.timeline_chart(run)
    (row,) = chart.rows
    (mark,) = row.marks
    assert mark.title == "500 episodes from 100.000 s to 100.499 s"


def test_timeline_rows_are_capped() -> None:
    episodes = [
        {"invariant": f"i{i:04d}", "first": float(i), "last": float(i), "count": 1}
        for i in range(svg.MAX_ROWS + 5)
    ]
    run = views.run(
        {
            "bag": "b.bag",
            "start": 0.0,
            "end": 300.0,
            "episodes": episodes,
            "violations": len(episodes),
        }
    )
    chart = svg.timeline_chart(run)
    assert len(chart.rows) == svg.MAX_ROWS
    assert chart.notes == [
        f"the first {svg.MAX_ROWS} of {svg.MAX_ROWS + 5} violated invariants shown"
    ]
