"""Bounds (Daikon's LowerBound/UpperBound), the thesis' chapter 1 example, justification."""

from __future__ import annotations

import math

import numpy as np

from imrosc.infer.core import Variable
from imrosc.infer.daikon.bounds import BoundsState

from .support import chunk, feed, finalize, infer, states, texts

NAN = math.nan
A, B = Variable("a", "float"), Variable("b", "float")
AB = (A, B)


def thesis_trace(extra_ones: int = 0) -> dict[str, list[float]]:
    """Chapter 1: t1 a=1, t2 b=3, t3 a=1, t4 a=2, t5 a=1, t6 a=-1 (then more a=1)."""
    a = [1.0, NAN, 1.0, 2.0, 1.0, -1.0] + [1.0] * extra_ones
    b = [NAN, 3.0, NAN, NAN, NAN, NAN] + [NAN] * extra_ones
    return {"a": a, "b": b}


def test_thesis_example_refines_the_lower_bound() -> None:
    trace = thesis_trace()
    built = states(AB, ["bounds"])
    feed(built, chunk(AB, trace, 0, 5))
    # a = 1, 1, 2, 1 so far: with a permissive limit the lower bound reads a >= 1
    assert "1 <= a <= 2" in texts(finalize(built, AB, confidence=0.5))
    feed(built, chunk(AB, trace, 5, 6))
    found = finalize(built, AB, confidence=0.0)
    assert texts(found) == ["-1 <= a <= 2", "b == 3"]
    bound = found[0]
    assert bound.params == {"min": -1.0, "max": 2.0}
    assert bound.samples == 5
    # a >= -1 has one supporting sample (a <= 2 has three), b a single one
    assert bound.confidence == 0.5
    assert found[1].confidence == 0.5
    assert texts(finalize(built, AB)) == []


def test_seven_samples_justify_a_bound_at_099() -> None:
    # a <= 2 has held for 3 + 5 samples, a >= -1 for 1 + 5: 1 - 2**-6 < 0.99
    assert texts(infer(AB, thesis_trace(5), ["bounds"])) == ["a <= 2"]
    assert texts(infer(AB, thesis_trace(5), ["bounds"], confidence=0.98)) == ["-1 <= a <= 2"]
    found = infer(AB, thesis_trace(6), ["bounds"])
    assert texts(found) == ["-1 <= a <= 2"]
    assert found[0].kind == "range"
    assert found[0].confidence == 1 - 2**-7


def test_one_of_implies_the_bounds() -> None:
    # a takes 3 values: one-of reports them and the bounds say nothing more
    found = infer(AB, thesis_trace(6), ["bounds", "one-of"])
    assert texts(found) == ["a one of {-1, 1, 2}"]
    assert [f.family for f in found] == ["one-of"]


def test_constant_prints_once() -> None:
    x = Variable("x", "float")
    rows = {"x": [4.0] * 10}
    assert texts(infer((x,), rows, ["bounds", "one-of"])) == ["x == 4"]
    assert texts(infer((x,), rows, ["bounds"])) == ["x == 4"]


def test_integer_and_float_printing() -> None:
    i, f = Variable("i", "int"), Variable("f", "float")
    rows = {
        "i": np.roll(np.arange(-3, 17, dtype=float), 10),
        "f": np.roll(np.linspace(-0.45, 1.25, 20), 10),
    }
    assert texts(infer((i, f), rows, ["bounds"])) == ["-3 <= i <= 16", "-0.45 <= f <= 1.25"]


def test_unsigned_zero_lower_bound_and_bools_say_nothing() -> None:
    u, b = Variable("u", "uint"), Variable("flag", "bool")
    rows = {"u": np.roll(np.arange(20, dtype=float), 10), "flag": np.arange(20) % 2.0}
    assert texts(infer((u, b), rows, ["bounds"])) == ["u <= 19"]


def test_nan_is_skipped_and_inf_takes_part() -> None:
    x, y = Variable("x", "float"), Variable("y", "float")
    rows = {
        "x": [NAN, 1.0, 8.0, NAN, 3.0, 4.0, 5.0, 6.0, 7.0, 2.0, NAN],
        "y": [1.0, 9.0, -math.inf, 3.0, 4.0, 5.0, 6.0, 7.0, 8.0, 9.0, 9.0],
    }
    built = states((x, y), ["bounds"])
    feed(built, chunk((x, y), rows))
    assert texts(finalize(built, (x, y))) == ["1 <= x <= 8", "y <= 9"]
    bounds = built[0]
    assert isinstance(bounds, BoundsState)
    assert bounds.nan_counts() == {"x": 3, "y": 0}


def test_all_nan_variable_gives_nothing() -> None:
    x = Variable("x", "float")
    assert texts(infer((x,), {"x": [NAN] * 20}, ["bounds", "one-of"])) == []


def test_negative_zero_is_zero() -> None:
    x = Variable("x", "float")
    first = infer((x,), {"x": [-0.0] + [1.0] * 10}, ["bounds"])
    second = infer((x,), {"x": [0.0] + [1.0] * 10}, ["bounds"])
    assert first == second
    assert first[0].text == "0 <= x <= 1"


def test_followers_of_an_equality_class_have_no_bounds() -> None:
    x, copy = Variable("x", "float"), Variable("x_copy", "float")
    values = np.roll(np.linspace(0, 1, 30), 15)
    rows = {"x": values, "x_copy": values.copy()}
    assert texts(infer((x, copy), rows, ["bounds", "equality"])) == [
        "0 <= x <= 1",
        "x == x_copy",
    ]
    assert len(infer((x, copy), rows, ["bounds"])) == 2


def test_chunking_does_not_change_the_first_occurrence() -> None:
    x = Variable("x", "float")
    values = [5.0, 3.0, 3.0, 9.0, 2.0, 2.0, 9.0] + [4.0] * 6
    whole = infer((x,), {"x": values}, ["bounds"])
    for size in (1, 2, 3, 5):
        assert infer((x,), {"x": values}, ["bounds"], chunk_rows=size) == whole
    assert whole[0].kind == "range"
    assert whole[0].confidence == 1 - 2**-9
