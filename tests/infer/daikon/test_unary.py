"""One-of, string one-of, non-zero and array families."""

from __future__ import annotations

import math

import numpy as np

from imrosc.infer.core import Variable

from .support import infer, texts

NAN = math.nan


def test_one_of_up_to_three_values() -> None:
    x, y, z = Variable("x", "int"), Variable("y", "float"), Variable("z", "int")
    rows = {
        "x": [1.0, 2.0, 3.0] * 5,
        "y": [0.5, -0.25] * 7 + [NAN],
        "z": [1.0, 2.0, 3.0, 4.0] * 4 + [1.0] * 4,
    }
    found = infer((x, y, z), {k: v[:15] for k, v in rows.items()}, ["one-of"])
    assert texts(found) == ["x one of {1, 2, 3}", "y one of {-0.25, 0.5}"]
    assert found[0].params == {"values": [1.0, 2.0, 3.0]}
    assert found[0].kind == "one-of"
    assert found[1].samples == 14


def test_one_of_justification_counts_since_the_last_new_value() -> None:
    x = Variable("x", "int")
    values = [1.0] * 10 + [2.0] + [1.0] * 5
    assert texts(infer((x,), {"x": values}, ["one-of"])) == []
    found = infer((x,), {"x": [*values, 1.0]}, ["one-of"])
    assert texts(found) == ["x one of {1, 2}"]
    assert found[0].confidence == 1 - 2**-7


def test_one_of_single_value_and_bools() -> None:
    flag, on, k = Variable("flag", "bool"), Variable("on", "bool"), Variable("k", "float")
    rows = {"flag": [0.0, 1.0] * 5, "on": [1.0] * 10, "k": [2.5] * 10}
    assert texts(infer((flag, on, k), rows, ["one-of"])) == ["on == true", "k == 2.5"]


def test_string_one_of() -> None:
    mode, name = Variable("mode", "string"), Variable("name", "string")
    rows = {
        "mode": ["idle", "run", "idle", None, "run"] * 3,
        "name": ["a", "b", "c", "d", "a"] * 3,
    }
    found = infer((mode, name), rows, ["string-one-of"])
    assert texts(found) == ['mode one of {"idle", "run"}']
    assert found[0].params == {"values": ["idle", "run"]}
    assert found[0].samples == 12
    single = infer((mode,), {"mode": ['say "hi"'] * 8}, ["string-one-of"])
    assert texts(single) == ['mode == "say \\"hi\\""']


def test_non_zero_follows_daikons_rule() -> None:
    n, f, far, seen = (
        Variable("n", "int"),
        Variable("f", "float"),
        Variable("far", "int"),
        Variable("seen", "int"),
    )
    values = np.array([v for v in range(-10, 11) if v != 0] * 6, dtype=float)
    rows = {"n": values, "f": values, "far": values + 20, "seen": np.append(values[1:], 0.0)}
    found = infer((n, f, far, seen), rows, ["non-zero"])
    assert texts(found) == ["n != 0"]
    assert found[0].kind == "!=0"
    assert abs(found[0].confidence - (1 - (1 - 1 / 21) ** 120)) < 1e-12
    # 60 samples are too few to expect a zero among 21 possible values
    assert texts(infer((n,), {"n": values[:60]}, ["non-zero"])) == []


def test_non_zero_is_implied_by_one_of() -> None:
    n = Variable("n", "int")
    rows = {"n": [-1.0, 1.0] * 20}
    assert texts(infer((n,), rows, ["non-zero", "one-of"])) == ["n one of {-1, 1}"]
    assert texts(infer((n,), rows, ["non-zero"])) == ["n != 0"]


def test_array_statistics() -> None:
    variables = (
        Variable("len(scan.ranges)", "uint", path="ranges", derived="len"),
        Variable("avg(scan.ranges)", "float", path="ranges", derived="avg"),
        Variable("std(scan.ranges)", "float", path="ranges", derived="std"),
        Variable("min(scan.ranges)", "float", path="ranges", derived="min"),
        Variable("max(scan.ranges)", "float", path="ranges", derived="max"),
        Variable("len(cloud.data)", "uint", path="data", derived="len"),
    )
    rows = {
        "len(scan.ranges)": [3.0, 1.0, 2.0] * 4,
        "avg(scan.ranges)": [1.5, 0.5, 1.0] * 4,
        "std(scan.ranges)": [1.41, 0.12, 0.5] * 4,
        "min(scan.ranges)": [0.25, 0.5, 0.1] * 4,
        "max(scan.ranges)": [2.5, 30.0, 1.0] * 4,
        "len(cloud.data)": [720.0] * 12,
    }
    found = infer(variables, rows, ["array"])
    assert texts(found) == [
        "1 <= len(scan.ranges) <= 3",
        "0.5 <= avg(scan.ranges) <= 1.5",
        "0.12 <= std(scan.ranges) <= 1.41",
        "scan.ranges[] elements >= 0.1",
        "scan.ranges[] elements <= 30",
        "len(cloud.data) == 720",
    ]
    assert found[3].variables == ("min(scan.ranges)",)
    assert found[3].params == {"min": 0.1}
    assert found[4].params == {"max": 30.0}
    assert {f.family for f in found} == {"array"}


def test_array_trivial_lower_bounds_are_not_stated() -> None:
    variables = (
        Variable("len(a)", "uint", path="a", derived="len"),
        Variable("std(a)", "float", path="a", derived="std"),
    )
    rows = {"len(a)": [0.0, 4.0, 2.0] * 4, "std(a)": [0.0, 1.0, 0.5] * 4}
    assert texts(infer(variables, rows, ["array"])) == ["len(a) <= 4", "std(a) <= 1"]


def test_constant_arrays_state_their_elements_only() -> None:
    variables = tuple(
        Variable(
            f"{stat}(imu.covariance)",
            "uint" if stat == "len" else "float",
            path="covariance",
            derived=stat,
        )
        for stat in ("len", "avg", "std", "min", "max")
    )
    rows = {v.name: [9.0 if v.derived == "len" else 0.0] * 10 for v in variables}
    assert texts(infer(variables, rows, ["array"])) == [
        "len(imu.covariance) == 9",
        "imu.covariance[] elements >= 0",
        "imu.covariance[] elements <= 0",
    ]


def test_derived_variables_stay_out_of_the_scalar_families() -> None:
    variables = (Variable("len(a)", "uint", path="a", derived="len"), Variable("x", "int"))
    rows = {"len(a)": [5.0] * 10, "x": [5.0] * 10}
    assert texts(infer(variables, rows, ["bounds", "one-of", "equality"])) == ["x == 5"]
