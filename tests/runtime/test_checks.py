"""Value checks: each family by hand, and every inferred invariant against its training rows."""

from __future__ import annotations

import json
import math
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np
import numpy.typing as npt
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from imrosc.infer.core import FinalizeContext, Samples, Variable
from imrosc.infer.polygon.state import PolygonState, half_planes
from imrosc.invariants import document, dumps
from imrosc.ir import Tunables
from imrosc.runtime.checks import Checks, WindowChecks
from imrosc.runtime.violation import Violation
from tests.runtime.support import NUMERIC, POINT, infer, inv, on_the_tolerance, planted

NAN = math.nan
NAMES = ["x", "y", "z", "w", "k", "avg(a)", "std(a)"]
INDEX = {name: k for k, name in enumerate(NAMES)}
STRINGS = {"mode": 0}


def row(**values: float) -> npt.NDArray[np.float64]:
    """A sample: the given values, 0.5 elsewhere."""
    out = np.full(len(NAMES), 0.5)
    for name, value in values.items():
        out[INDEX[name]] = value
    return out


def check(
    invariants: Sequence[Mapping[str, Any]],
    sample: npt.NDArray[np.float64],
    strings: Sequence[str] = ("idle",),
    cleared: Sequence[str] = (),
) -> list[tuple[str, Any, str]]:
    checks = Checks(invariants, INDEX, STRINGS, stats=("avg(a)", "std(a)"))
    checks.cleared.update(cleared)
    with np.errstate(all="ignore"):  # as the engine's callers run it: NaN and inf are input
        found = checks.check(3.0, POINT, sample, strings)
    for violation in found:
        assert (violation.time, violation.point) == (3.0, POINT)
        assert violation.family == next(
            i["family"] for i in invariants if i["id"] == violation.invariant
        )
    return [(v.invariant, v.observed, v.expected) for v in found]


BOUNDS = [
    inv("lower", "bounds", "lower", ["x"], min=-1.0),
    inv("upper", "bounds", "upper", ["x"], max=9.5),
    inv("range", "bounds", "range", ["y"], min=0.0, max=1.0),
]


def test_bounds() -> None:
    assert check(BOUNDS, row(x=-1.0, y=0.0)) == []
    assert check(BOUNDS, row(x=9.5, y=1.0)) == []
    assert check(BOUNDS, row(x=-1.5, y=1.25)) == [
        ("lower", -1.5, "[-1, inf]"),
        ("range", 1.25, "[0, 1]"),
    ]
    assert check(BOUNDS, row(x=9.75, y=-0.0)) == [("upper", 9.75, "[-inf, 9.5]")]
    assert check(BOUNDS, row(x=math.inf)) == [("upper", math.inf, "[-inf, 9.5]")]
    assert check(BOUNDS, row(x=NAN, y=NAN)) == []


def test_bounds_read_infinite_bounds_as_the_file_writes_them() -> None:
    stated = [inv("s", "bounds", "range", ["x"], min="-inf", max=2.0)]
    assert check(stated, row(x=-1e308)) == []
    assert check(stated, row(x=3.0)) == [("s", 3.0, "[-inf, 2]")]


def test_array_statistics_get_a_few_ulps_of_slack() -> None:
    stats = [
        inv("avg", "array", "range", ["avg(a)"], min=1.0, max=2.0),
        inv("std", "array", "upper", ["std(a)"], max=0.25),
        inv("plain", "array", "range", ["w"], min=1.0, max=2.0),  # e.g. len or min: exact
    ]
    near = row(w=1.5, **{"avg(a)": 2.0 * (1 + 1e-13), "std(a)": 0.25 * (1 + 1e-13)})
    assert check(stats, near) == []
    assert check(stats, row(w=2.0 * (1 + 1e-13), **{"avg(a)": 1.5, "std(a)": 0.1})) == [
        ("plain", 2.0 * (1 + 1e-13), "[1, 2]")
    ]
    far = row(w=1.5, **{"avg(a)": 1.0 - 1e-10, "std(a)": 0.25 * (1 + 1e-10)})
    assert [found[0] for found in check(stats, far)] == ["avg", "std"]


def test_one_of() -> None:
    invariants = [
        inv("set", "one-of", "one-of", ["k"], values=[1.0, 2.0, 3.0]),
        inv("big", "one-of", "one-of", ["w"], values=["-inf", 4.5]),
    ]
    assert check(invariants, row(k=2.0, w=4.5)) == []
    assert check(invariants, row(k=3.0, w=-math.inf)) == []
    assert check(invariants, row(k=4.0, w=4.0)) == [
        ("set", 4.0, "one of {1.0, 2.0, 3.0}"),
        ("big", 4.0, "one of {-inf, 4.5}"),
    ]
    assert check(invariants, row(k=NAN, w=NAN)) == []


def test_non_zero() -> None:
    invariants = [inv("nz", "non-zero", "!=0", ["k"])]
    assert check(invariants, row(k=-3.0)) == []
    assert check(invariants, row(k=0.0)) == [("nz", 0.0, "!= 0")]
    assert check(invariants, row(k=-0.0)) == [("nz", 0.0, "!= 0")]
    assert check(invariants, row(k=NAN)) == []


def test_an_equality_class_of_three() -> None:
    invariants = [inv("eq", "equality", "==", ["x", "y", "z"])]
    assert check(invariants, row(x=2.0, y=2.0, z=2.0)) == []
    assert check(invariants, row(x=0.0, y=-0.0, z=0.0)) == []
    assert check(invariants, row(x=2.0, y=2.0, z=3.0)) == [("eq", (2.0, 3.0), "==")]
    # two pairs of the class broken: the invariant is reported (once, naming one of them)
    found = check(invariants, row(x=2.0, y=1.0, z=3.0))
    assert [ident for ident, _, _ in found] == ["eq"]
    assert found[0][1] in ((2.0, 1.0), (2.0, 3.0))
    assert check(invariants, row(x=2.0, y=NAN, z=2.0)) == []
    assert check(invariants, row(x=NAN, y=1.0, z=2.0)) == []
    checks = Checks(invariants, INDEX, STRINGS)
    assert checks.size == 1


def test_order() -> None:
    invariants = [
        inv("lt", "order", "<", ["x", "y"]),
        inv("le", "order", "<=", ["z", "w"]),
    ]
    assert check(invariants, row(x=1.0, y=2.0, z=1.0, w=1.0)) == []
    assert check(invariants, row(x=2.0, y=2.0, z=1.5, w=1.0)) == [
        ("lt", (2.0, 2.0), "<"),
        ("le", (1.5, 1.0), "<="),
    ]
    assert check(invariants, row(x=NAN, y=2.0, z=1.0, w=NAN)) == []


def test_linear_within_its_tolerance() -> None:
    invariants = [inv("lin", "linear", "linear", ["y", "x"], a=2.0, b=3.0, tolerance=1e-9)]
    assert check(invariants, row(x=0.1, y=3.2)) == []
    assert check(invariants, row(x=0.1, y=3.2 + 9e-10)) == []
    found = check(invariants, row(x=0.1, y=3.2 + 2e-9))
    assert found == [("lin", (3.2 + 2e-9, 0.1), "within 1e-09 of the relation")]
    assert check(invariants, row(x=NAN, y=1.0)) == []
    assert check(invariants, row(x=1.0, y=NAN)) == []


def test_linear_allows_the_rounding_of_large_terms() -> None:
    for x in (1e15 / 3, 123456.789, -7.1e8, 0.3, 1e-300):
        y = 3.0 * x + 0.1
        # the least tolerance inference states: its rounding term alone
        tolerance = 1e-14 * (abs(y) + 3.0 * abs(x) + 0.1)
        invariants = [inv("lin", "linear", "linear", ["y", "x"], a=3.0, b=0.1, tolerance=tolerance)]
        assert check(invariants, row(x=x, y=y)) == []
        assert check(invariants, row(x=x, y=y + 3 * tolerance + abs(y) * 1e-12)) != []


def test_ternary() -> None:
    invariants = [
        inv("ter", "ternary", "ternary", ["z", "x", "y"], a=1.0, b=-2.0, c=1.0, tolerance=1e-9)
    ]
    assert check(invariants, row(x=0.7, y=0.3, z=0.7 - 2 * 0.3 + 1)) == []
    assert check(invariants, row(x=0.7, y=0.3, z=1.2)) == [
        ("ter", (1.2, 0.7, 0.3), "within 1e-09 of the relation")
    ]
    assert check(invariants, row(x=0.7, y=NAN, z=5.0)) == []


def polygon(ident: str, variables: Sequence[str], vertices: Sequence[Sequence[float]]) -> Any:
    """A polygon invariant as inference writes it (counter-clockwise ``vertices``)."""
    normals, offsets, _ = half_planes(np.asarray(vertices, dtype=np.float64))
    return inv(
        ident,
        "polygon",
        "hull",
        variables,
        x=variables[0],
        y=variables[1],
        vertices=[list(map(float, v)) for v in vertices],
        A=normals.tolist(),
        b=offsets.tolist(),
    )


SQUARE = polygon("square", ["x", "y"], [(0, 0), (1, 0), (1, 1), (0, 1)])
TRIANGLE = polygon("triangle", ["z", "w"], [(0, 0), (1, 0), (0, 1)])


def test_polygons_are_half_planes() -> None:
    polygons = [SQUARE, TRIANGLE]
    assert check(polygons, row(x=0.5, y=1.0, z=0.25, w=0.75)) == []
    # two edges broken: one violation
    assert check(polygons, row(x=1.5, y=1.5, z=0.5, w=0.5)) == [
        ("square", (1.5, 1.5), "inside the 4-vertex polygon of (x, y)")
    ]
    assert check(polygons, row(x=0.5, y=0.5, z=0.75, w=0.5)) == [
        ("triangle", (0.75, 0.5), "inside the 3-vertex polygon of (z, w)")
    ]
    assert check(polygons, row(x=NAN, y=5.0, z=0.5, w=NAN)) == []


def test_a_broken_polygon_reads_as_its_text() -> None:
    checks = Checks([SQUARE], INDEX, STRINGS)
    (broken,) = checks.check(3.0, POINT, row(x=2.0, y=0.5), ("idle",))
    assert (broken.family, broken.kind, broken.text) == ("polygon", "hull", "square text")


@st.composite
def hulls(draw: st.DrawFn) -> tuple[list[dict[str, Any]], npt.NDArray[np.float64]]:
    """Polygons inference finds for random point clouds, and the clouds."""
    rng = np.random.default_rng(draw(st.integers(0, 2**32 - 1)))
    n = draw(st.integers(3, 120))
    scale = np.asarray(draw(st.sampled_from([(1.0, 1.0), (1e-3, 1e4), (1e8, 1.0)])))
    offset = np.asarray(draw(st.sampled_from([(0.0, 0.0), (1e6, -3.0), (-0.5, 0.25)])))
    shape = draw(st.sampled_from(["disk", "triangle", "grid"]))
    if shape == "disk":
        angle, radius = rng.uniform(0, 2 * np.pi, n), np.sqrt(rng.uniform(0, 1, n))
        unit = np.stack([radius * np.cos(angle), radius * np.sin(angle)], axis=1)
    elif shape == "triangle":
        unit = rng.uniform(0, 1, (n, 2))
        unit[:, 1] *= 1 - unit[:, 0]
    else:
        unit = rng.integers(0, 4, (n, 2)).astype(np.float64)
    points = unit * scale + offset
    variables = (Variable("x", "float"), Variable("y", "float"))
    state = PolygonState(variables)
    state.update(
        Samples(
            POINT,
            0,
            np.arange(n, dtype=np.float64) * 0.01,
            {"x": points[:, 0], "y": points[:, 1]},
            variables,
        )
    )
    context = FinalizeContext(Tunables(confidence=0.0, drop_ratio=1.0), variables, POINT)
    doc = document(
        project="t", source="t", bags=[], tunables={}, topics={}, points=[],
        invariants=state.finalize(context),
    )  # fmt: skip
    found: list[dict[str, Any]] = json.loads(dumps(doc))["invariants"]
    return found, points


@settings(max_examples=40, deadline=None)
@given(hulls(), st.integers(0, 2**32 - 1))
def test_polygon_checks_are_the_half_planes_evaluated_in_float64(
    drawn: tuple[list[dict[str, Any]], npt.NDArray[np.float64]], seed: int
) -> None:
    """Whatever shortcut the checks take, a sample breaks a polygon exactly when
    ``a*x + b*y > c`` for one of its edges (finite samples only); training samples never."""
    invariants, points = drawn
    if not invariants:
        return
    (polygon_inv,) = invariants
    rng = np.random.default_rng(seed)
    vertices = np.asarray(polygon_inv["params"]["vertices"])
    low, high = points.min(axis=0), points.max(axis=0)
    span = high - low
    near = vertices[rng.integers(0, len(vertices), 60)]
    queries = np.concatenate(
        [
            points,
            vertices,
            near * (1 + rng.normal(0, 1e-15, near.shape)),  # at the corners, a few ulps off
            near + rng.normal(0, 1e-9, near.shape) * span,
            # on the edges, and just across them
            (vertices + np.roll(vertices, -1, axis=0)) / 2,
            low + rng.uniform(-0.2, 1.2, (150, 2)) * span,
            [[np.nan, low[1]], [low[0], np.inf], [-np.inf, np.nan]],
        ]
    )
    a, b = np.asarray(polygon_inv["params"]["A"]).T
    c = np.asarray(polygon_inv["params"]["b"])
    checks = Checks(invariants, {"x": 0, "y": 1}, {})
    with np.errstate(all="ignore"):
        for k, (x, y) in enumerate(queries.tolist()):
            outside = bool(np.any(a * x + b * y > c)) and math.isfinite(x) and math.isfinite(y)
            found = checks.check(0.0, POINT, np.asarray([x, y]), [])
            assert [v.observed for v in found] == ([(x, y)] if outside else []), (k, x, y)
            assert not (outside and k < len(points)), "a training sample is outside"


def test_string_one_of() -> None:
    invariants = [inv("str", "string-one-of", "string-one-of", ["mode"], values=["idle", "run"])]
    assert check(invariants, row(), ["run"]) == []
    assert check(invariants, row(), ["fly"]) == [("str", "fly", 'one of "idle", "run"')]
    assert check(invariants, row(), [""]) == [("str", "", 'one of "idle", "run"')]


EVERYTHING = [
    *BOUNDS,
    inv("set", "one-of", "one-of", ["k"], values=[1.0, 2.0]),
    inv("nz", "non-zero", "!=0", ["k"]),
    inv("eq", "equality", "==", ["x", "y", "z"]),
    inv("lt", "order", "<", ["x", "w"]),
    inv("lin", "linear", "linear", ["y", "x"], a=2.0, b=3.0, tolerance=1e-9),
    inv("ter", "ternary", "ternary", ["z", "x", "y"], a=1.0, b=-2.0, c=1.0, tolerance=1e-9),
    inv("avg", "array", "range", ["avg(a)"], min=1.0, max=2.0),
    SQUARE,
    TRIANGLE,
    inv("str", "string-one-of", "string-one-of", ["mode"], values=["idle"]),
    inv("freq", "frequency", "range", [], min=1.0, max=2.0, window=1.0),
    inv("gone", "bounds", "upper", ["not-here"], max=0.0),
]


def test_nan_breaks_nothing() -> None:
    assert check(EVERYTHING, np.full(len(NAMES), NAN)) == []


def test_cleared_invariants_are_not_reported() -> None:
    broken = row(x=20.0, y=-5.0, z=0.0, w=-3.0, k=0.0, **{"avg(a)": 7.0})
    found = {ident for ident, _, _ in check(EVERYTHING, broken, ["run"])}
    assert found == {
        "upper", "range", "set", "nz", "eq", "lt", "lin", "ter", "avg", "square",
        "triangle", "str",
    }  # fmt: skip
    assert check(EVERYTHING, broken, ["run"], cleared=sorted(found)) == []
    left = check(EVERYTHING, broken, ["run"], cleared=sorted(found - {"square", "nz"}))
    assert sorted(ident for ident, _, _ in left) == ["nz", "square"]


def test_only_known_variables_are_compiled() -> None:
    checks = Checks(EVERYTHING, INDEX, STRINGS)
    assert checks.size == len(EVERYTHING) - 2  # not the frequency, not the unknown variable
    assert Checks([], INDEX, STRINGS).check(0.0, POINT, row()) == []


# -- window bounds ---------------------------------------------------------------------------

WINDOWED = [
    inv("freq", "frequency", "range", [], min=8.0, max=12.0, window=1.0, topic="/t"),
    inv("var", "variance", "range", ["x"], min=0.0, max=1.0, window=1.0),
    inv("rate", "rate", "range", ["y"], min=-1.0, max="inf", window=1.0),
    inv("other", "variance", "range", ["untracked"], min=0.0, max=1.0, window=1.0),
]


def window_check(
    frequency: float, variance: Sequence[float], rate: Sequence[float], cleared: Sequence[str] = ()
) -> list[tuple[str, float, str]]:
    checks = WindowChecks(WINDOWED, ["x", "y"])
    assert checks.active and checks.window == 1.0

    def derived(family: str) -> npt.NDArray[np.float64]:
        return np.asarray(variance if family == "variance" else rate, dtype=np.float64)

    found = checks.check(2.0, POINT, frequency, derived, set(cleared))
    return [(v.invariant, v.observed, v.expected) for v in found]


def test_window_bounds() -> None:
    assert window_check(10.0, [0.5, 7.0], [3.0, 0.0]) == []
    assert window_check(13.0, [1.5, 0.0], [0.0, -2.0]) == [
        ("freq", 13.0, "[8, 12] Hz"),
        ("var", 1.5, "[0, 1]"),
        ("rate", -2.0, "[-1, inf]"),
    ]
    assert window_check(7.0, [1.5, 0.0], [0.0, -2.0], cleared=["var", "rate", "freq"]) == []
    assert window_check(10.0, [NAN, NAN], [NAN, NAN]) == []
    assert not WindowChecks(BOUNDS, ["x"]).active


def test_window_values_that_are_not_finite_are_skipped_as_inference_skips_them() -> None:
    # an infinite sample (or a squared difference that overflows) gives an infinite
    # variance or rate: inference leaves such windows out, so they break nothing
    assert window_check(10.0, [math.inf, 0.0], [0.0, -math.inf]) == []


def test_an_infinite_sample_is_outside_no_polygon() -> None:
    # inference leaves samples with an infinite coordinate out of every hull
    assert check([SQUARE], row(x=math.inf, y=0.5)) == []
    assert check([SQUARE], row(x=0.5, y=-math.inf)) == []


# -- every inferred invariant holds on the rows it was inferred from --------------------------


@st.composite
def training(draw: st.DrawFn) -> dict[str, npt.NDArray[Any]]:
    """Random rows with planted structure: relations, sets, order, a hull, NaN and inf."""
    rng = np.random.default_rng(draw(st.integers(0, 2**32 - 1)))
    n = draw(st.integers(8, 50))
    scale = draw(st.sampled_from([1.0, 1e-6, 1e6, 3.7]))
    offset = draw(st.sampled_from([0.0, 1e3, -2.5]))
    x = rng.uniform(-5, 5, n) * scale + offset
    if draw(st.booleans()):
        x = np.round(x, draw(st.integers(0, 3)))
    a, b = draw(st.sampled_from([(2.5, 3.0), (-1.0, 0.0), (0.1, -7.0), (1e-3, 1e3)]))
    m = rng.uniform(0, 1, n) * scale
    columns: dict[str, npt.NDArray[Any]] = {
        "x": x,
        "y": a * x + b,
        "z": x - 2 * m + 1,
        "m": m,
        "k": rng.choice([1.0, 2.0, 3.0, 4.0][: draw(st.integers(1, 4))], n),
        "nz": rng.choice([-3.0, -1.0, 2.0, 5.0], n),
        "flag": rng.choice([0.0, 1.0], n),
        "u": x + rng.uniform(0, 1, n),  # x < u
        "v": rng.uniform(0, 1, n) * (x - x.min() + 1),  # a hull with x
        "avg(a)": rng.uniform(1, 2, n),
        "mode": rng.choice(
            np.array(["idle", "run", "land"], dtype=object)[: draw(st.integers(1, 3))], n
        ),
    }
    holes = draw(st.sampled_from([0.0, 0.05, 0.3]))
    for name in NUMERIC:
        column = columns[name]
        column[rng.random(n) < holes] = math.nan
        if draw(st.integers(0, 9)) == 0:
            column[rng.integers(0, n)] = draw(st.sampled_from([math.inf, -math.inf]))
    return columns


@settings(max_examples=30, deadline=None)
@given(training(), st.sampled_from([1000, 13]))
def test_training_rows_never_violate_inferred_invariants(
    columns: dict[str, npt.NDArray[Any]], chunk: int
) -> None:
    invariants = infer(columns, chunk)
    numeric = list(NUMERIC)
    checks = Checks(invariants, {n: k for k, n in enumerate(numeric)}, {"mode": 0}, ["avg(a)"])
    assert checks.size == len(invariants)  # every inferred invariant is checked
    rows = np.stack([columns[name] for name in numeric], axis=1)
    found: list[Violation] = []
    with np.errstate(all="ignore"):
        for k in range(len(rows)):
            found += checks.check(float(k), POINT, rows[k], [str(columns["mode"][k])])
    assert found == []


@pytest.mark.parametrize("seed", range(3))
def test_the_planted_families_are_inferred_and_checked(seed: int) -> None:
    """The property above is not vacuous: its data gives every family."""
    invariants = infer(planted(np.random.default_rng(seed), 80), 1000)
    families = {i["family"] for i in invariants}
    assert families >= {
        "bounds", "one-of", "non-zero", "order", "linear", "ternary", "polygon", "array",
        "string-one-of",
    }  # fmt: skip
    checks = Checks(invariants, {n: k for k, n in enumerate(NUMERIC)}, {"mode": 0}, ["avg(a)"])
    assert checks.size == len(invariants)


@settings(max_examples=30, deadline=None)
@given(training(), st.integers(0, 2**32 - 1))
def test_the_dense_product_and_the_gathered_forms_find_the_same_violations(
    columns: dict[str, npt.NDArray[Any]], seed: int
) -> None:
    """A finite sample takes one matrix-vector product; NaN and inf the gathered terms;
    a large point always the gathered terms. Both read each invariant the same way: the
    same violations, except a linear or ternary relation whose residual is within the
    rounding of its evaluation (a few ulps of its terms) of the tolerance, where the two
    summation orders may differ."""
    invariants = infer(columns, 1000)
    index = {n: k for k, n in enumerate(NUMERIC)}
    dense = Checks(invariants, index, {"mode": 0}, ["avg(a)"])
    gathered = Checks(invariants, index, {"mode": 0}, ["avg(a)"])
    gathered.forms.dense = None
    if dense.forms.dense is None:  # nothing inferred for the forms to check
        assert not dense.forms.size
        return
    rng = np.random.default_rng(seed)
    rows = np.stack([columns[name] for name in NUMERIC], axis=1)
    rows = rows[np.isfinite(rows).all(axis=1)]
    spread = np.nan_to_num(np.nanstd(rows, axis=0) if len(rows) else np.ones(len(NUMERIC)))
    if not len(rows):
        return
    queries = [
        *rows,
        *(rows[rng.integers(0, len(rows), 40)] + rng.normal(0, 1, (40, len(NUMERIC))) * spread),
        *(rows[rng.integers(0, len(rows), 20)] * (1 + rng.normal(0, 1e-13, (20, len(NUMERIC))))),
    ]
    by_id = {i["id"]: i for i in invariants}
    with np.errstate(all="ignore"):
        for query in queries:
            got = {(v.invariant, v.observed) for v in dense.check(0.0, POINT, query, ["idle"])}
            want = {(v.invariant, v.observed) for v in gathered.check(0.0, POINT, query, ["idle"])}
            for ident, _ in got ^ want:
                assert on_the_tolerance(by_id[ident], query), (ident, got ^ want)
