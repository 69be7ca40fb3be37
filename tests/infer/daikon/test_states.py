"""The public API: which states exist, protocol details, robustness."""

from __future__ import annotations

import math
import pickle

import numpy as np

from imrosc.infer.core import FinalizeContext, Samples, Variable
from imrosc.infer.daikon import FAMILIES, make_states
from imrosc.ir import Tunables

from .support import chunk, feed, finalize, infer, states

VARIABLES = (
    Variable("x", "float"),
    Variable("n", "int"),
    Variable("s", "string"),
    Variable("len(a)", "uint", path="a", derived="len"),
)


def test_one_state_per_enabled_family_in_order() -> None:
    built = make_states(VARIABLES, Tunables(), frozenset(FAMILIES))
    assert [state.family for state in built] == list(FAMILIES)
    chosen = make_states(VARIABLES, Tunables(), frozenset({"linear", "bounds", "frequency"}))
    assert [state.family for state in chosen] == ["bounds", "linear"]
    assert make_states(VARIABLES, Tunables(), frozenset()) == []


def test_every_invariant_is_well_formed() -> None:
    rng = np.random.default_rng(1)
    x = rng.uniform(-1, 1, 200)
    rows = {
        "x": x,
        "n": rng.integers(-3, 4, 200).astype(float),
        "s": ["a", "b"] * 100,
        "len(a)": np.full(200, 3.0),
    }
    found = infer(VARIABLES, rows)
    assert {f.family for f in found} == {"bounds", "string-one-of", "array"}
    for invariant in found:
        assert invariant.point == "p"
        assert invariant.condition is None
        assert invariant.runs == 1
        assert invariant.samples == 200
        assert 0.99 < invariant.confidence <= 1.0
        assert set(invariant.variables) <= {v.name for v in VARIABLES}


def test_condition_and_runs_come_from_the_context() -> None:
    built = states(VARIABLES, ["bounds"])
    feed(
        built,
        chunk(
            VARIABLES, {"x": [1.0, 2.0] * 5, "n": [1.0] * 10, "s": ["a"] * 10, "len(a)": [1.0] * 10}
        ),
    )
    context = FinalizeContext(Tunables(), VARIABLES, "p?mode==2", "mode==2", 3)
    found = built[0].finalize(context)
    assert found
    assert all(f.condition == "mode==2" and f.runs == 3 and f.point == "p?mode==2" for f in found)


def test_empty_chunks_and_points_without_variables() -> None:
    built = states(VARIABLES)
    empty = Samples(
        "p",
        0,
        np.zeros(0),
        {"x": np.zeros(0), "n": np.zeros(0), "s": np.zeros(0, dtype=object), "len(a)": np.zeros(0)},
        VARIABLES,
    )
    feed(built, empty)
    assert finalize(built, VARIABLES) == []
    nothing = make_states((), Tunables(), frozenset(FAMILIES))
    feed(nothing, Samples("p", 0, np.zeros(3), {}, ()))
    assert finalize(nothing, ()) == []


def test_states_pickle_and_merge_after_pickling() -> None:
    rows = {"x": [1.0, 2.0, 3.0, 4.0] * 5, "n": [1.0] * 20, "s": ["a"] * 20, "len(a)": [2.0] * 20}
    built = states(VARIABLES)
    feed(built, chunk(VARIABLES, rows, 0, 10))
    copies = pickle.loads(pickle.dumps(built))
    later = states(VARIABLES)
    feed(later, chunk(VARIABLES, rows, 10, 20))
    for mine, theirs in zip(copies, later, strict=True):
        mine.merge(theirs)
    feed(built, chunk(VARIABLES, rows, 10, 20))
    assert finalize(copies, VARIABLES) == finalize(built, VARIABLES)


def test_nan_and_inf_everywhere_never_crash() -> None:
    rng = np.random.default_rng(4)
    variables = tuple(Variable(f"v{i}", "float") for i in range(6))
    pool = np.array([math.nan, math.inf, -math.inf, 0.0, -0.0, 1e308, -1e308, 5e-324, 1.0])
    rows = {v.name: rng.choice(pool, 300) for v in variables}
    rows["v0"] = np.full(300, math.nan)
    for size in (1, 7, 300):
        found = infer(variables, rows, chunk_rows=size, confidence=0.5)
        assert all(math.isfinite(f.confidence) for f in found)


def test_merge_refuses_another_family() -> None:
    built = states(VARIABLES)
    try:
        built[0].merge(built[1])
    except TypeError:
        pass
    else:
        raise AssertionError("merging bounds with one-of should fail")
