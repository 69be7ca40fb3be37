"""Folding chunks in order equals merging states built from parts (property tests).

For every family: one state updated with chunks c1..cn gives exactly the invariants of
states built from contiguous groups of the same chunks (pickled, as workers return them)
and merged in order. For every family but linear and ternary (whose float screen depends
on chunk boundaries in documented corner cases) any other chunking gives them too.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from imrosc.infer.core import Variable
from imrosc.infer.daikon import FAMILIES

from .support import finalize, fold, merged

VARIABLES = (
    Variable("i", "int"),
    Variable("j", "int"),
    Variable("u", "uint"),
    Variable("flag", "bool"),
    Variable("f", "float"),
    Variable("g", "float"),
    Variable("h", "float"),
    Variable("t", "float"),
    Variable("s", "string"),
    Variable("len(a)", "uint", path="a", derived="len"),
    Variable("std(a)", "float", path="a", derived="std"),
    Variable("min(a)", "float", path="a", derived="min"),
)
EXACT = tuple(f for f in FAMILIES if f not in ("linear", "ternary"))
SPECIAL = [
    0.0,
    -0.0,
    1.0,
    -1.0,
    0.5,
    2.0,
    3.0,
    math.nan,
    math.inf,
    -math.inf,
    5e-324,
    1e-300,
    1e300,
]

floats = st.one_of(
    st.sampled_from(SPECIAL),
    st.floats(allow_nan=True, allow_infinity=True),
    st.integers(-4, 4).map(float),
)


@st.composite
def streams(draw: st.DrawFn) -> dict[str, list[Any]]:
    """A point's rows: related columns often enough to exercise every family."""
    n = draw(st.integers(1, 40))
    small = st.integers(-3, 3).map(float)
    i = draw(st.lists(small, min_size=n, max_size=n))
    f = draw(st.lists(floats, min_size=n, max_size=n))
    h = draw(st.lists(floats, min_size=n, max_size=n))
    how = draw(st.sampled_from(["copy", "linear", "free"]))
    j = {
        "copy": list(i),
        "linear": [2 * v + 1 for v in i],
        "free": draw(st.lists(small, min_size=n, max_size=n)),
    }[how]
    g = (
        [2.5 * v - 1 for v in f]
        if draw(st.booleans())
        else draw(st.lists(floats, min_size=n, max_size=n))
    )
    t = [a - 2 * b + 1 for a, b in zip(f, h, strict=True)]
    if draw(st.booleans()):
        t = draw(st.lists(floats, min_size=n, max_size=n))
    return {
        "i": i,
        "j": j,
        "u": draw(st.lists(st.integers(0, 3).map(float), min_size=n, max_size=n)),
        "flag": draw(st.lists(st.sampled_from([0.0, 1.0]), min_size=n, max_size=n)),
        "f": f,
        "g": g,
        "h": h,
        "t": t,
        "s": draw(st.lists(st.sampled_from(["a", "b", "c", "d", None]), min_size=n, max_size=n)),
        "len(a)": draw(st.lists(st.integers(0, 3).map(float), min_size=n, max_size=n)),
        "std(a)": draw(st.lists(floats, min_size=n, max_size=n)),
        "min(a)": draw(st.lists(floats, min_size=n, max_size=n)),
    }


@st.composite
def cuts(draw: st.DrawFn, rows: int) -> list[int]:
    inner = draw(st.sets(st.integers(1, max(1, rows - 1)), max_size=6))
    return sorted({0, rows, *(c for c in inner if 0 < c < rows)})


@st.composite
def cases(draw: st.DrawFn) -> tuple[dict[str, list[Any]], list[int], list[int], list[int]]:
    rows = draw(streams())
    n = len(rows["i"])
    chunking = draw(cuts(n))
    parts = sorted(draw(st.sets(st.integers(1, max(1, len(chunking) - 2)), max_size=3)))
    parts = [p for p in parts if 0 < p < len(chunking) - 1]
    other = draw(cuts(n))
    return rows, chunking, parts, other


SETTINGS = settings(max_examples=30, deadline=None, suppress_health_check=[HealthCheck.too_slow])


@SETTINGS
@given(st.sampled_from(FAMILIES), cases())
def test_fold_equals_merge_of_parts(
    family: str, case: tuple[dict[str, list[Any]], list[int], list[int], list[int]]
) -> None:
    rows, chunking, parts, _ = case
    families = [family]
    folded = finalize(fold(VARIABLES, rows, chunking, families), VARIABLES)
    joined = finalize(merged(VARIABLES, rows, chunking, families, parts), VARIABLES)
    assert folded == joined


@SETTINGS
@given(st.sampled_from(EXACT), cases())
def test_exact_families_ignore_chunking(
    family: str, case: tuple[dict[str, list[Any]], list[int], list[int], list[int]]
) -> None:
    rows, chunking, parts, other = case
    families = [family]
    folded = finalize(fold(VARIABLES, rows, chunking, families), VARIABLES, confidence=0.5)
    again = finalize(fold(VARIABLES, rows, other, families), VARIABLES, confidence=0.5)
    joined = finalize(merged(VARIABLES, rows, other, families, parts), VARIABLES, confidence=0.5)
    assert folded == again == joined


@settings(SETTINGS, max_examples=40)
@given(cases())
def test_all_families_together_fold_equals_merge(
    case: tuple[dict[str, list[Any]], list[int], list[int], list[int]],
) -> None:
    rows, chunking, parts, _ = case
    folded = finalize(fold(VARIABLES, rows, chunking, FAMILIES, runs=parts), VARIABLES, 0.5)
    joined = finalize(merged(VARIABLES, rows, chunking, FAMILIES, parts), VARIABLES, 0.5)
    assert folded == joined


def test_long_stream_split_into_runs() -> None:
    rng = np.random.default_rng(5)
    n = 3000
    x = rng.integers(-5, 6, n).astype(float)
    m = rng.uniform(-1, 1, n)
    f = np.where(rng.random(n) < 0.05, np.nan, rng.uniform(-2, 2, n))
    rows: dict[str, Any] = {
        "i": x,
        "j": 2 * x + 1,
        "u": rng.integers(0, 4, n).astype(float),
        "flag": rng.integers(0, 2, n).astype(float),
        "f": f,
        "g": 2.5 * f - 1,
        "h": m,
        "t": f - 2 * m + 1,
        "s": list(rng.choice(["a", "b"], n)),
        "len(a)": rng.integers(1, 4, n).astype(float),
        "std(a)": rng.uniform(0, 1, n),
        "min(a)": rng.uniform(0, 1, n),
    }
    chunking = [0, 100, 700, 1500, 1501, 2200, 3000]
    folded = finalize(fold(VARIABLES, rows, chunking, FAMILIES), VARIABLES)
    for parts in ([1], [2, 4], [1, 2, 3, 4, 5]):
        assert finalize(merged(VARIABLES, rows, chunking, FAMILIES, parts), VARIABLES) == folded
    shown = {invariant.text for invariant in folded}
    assert {"j = 2*i + 1", "g = 2.5*f - 1", "t = f - 2*h + 1", "j != 0"} <= shown
