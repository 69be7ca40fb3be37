"""Ternary relations over a variable with few values (``levels``): found when two of its
levels each show more than 3 distinct points of the two other variables, not otherwise;
the same whatever the chunking and merging."""

from __future__ import annotations

import numpy as np

from imrosc.infer.core import Variable
from imrosc.infer.daikon.levels import LevelSupport
from tests.infer.daikon.support import finalize, fold, infer, merged, texts

A, M, T = Variable("a", "float"), Variable("m", "float"), Variable("t", "float")
VARIABLES = (A, M, T)


def _rows(
    n: int = 600, seed: int = 1, levels: tuple[float, ...] = (-1, 0, 2)
) -> dict[str, list[float]]:
    rng = np.random.default_rng(seed)
    a = rng.uniform(-10, 10, n)
    m = rng.choice(np.array(levels, dtype=float), n)
    return {"a": a.tolist(), "m": m.tolist(), "t": (a - 2 * m + 1).tolist()}


def test_a_three_valued_variable_joins_a_ternary_relation() -> None:
    found = infer(VARIABLES, _rows(), ["ternary"])
    assert texts(found) == ["t = a - 2*m + 1"]


def test_two_levels_are_enough_and_one_is_not() -> None:
    assert texts(infer(VARIABLES, _rows(levels=(0, 1)), ["ternary"])) == ["t = a - 2*m + 1"]
    rows = _rows(levels=(0, 1))
    # on level 1, a takes 3 values only: one full level, no relation
    a, m = np.array(rows["a"]), np.array(rows["m"])
    a[m == 1] = np.resize([1.0, 2.0, 3.0], int((m == 1).sum()))
    rows = {"a": a.tolist(), "m": m.tolist(), "t": (a - 2 * m + 1).tolist()}
    assert texts(infer(VARIABLES, rows, ["ternary"])) == []


def test_two_few_valued_variables_are_still_dropped() -> None:
    """Daikon's rule stands among discrete variables: 3 x 3 combinations always fit planes."""
    rng = np.random.default_rng(2)
    x = rng.choice([0.0, 1.0, 2.0], 500)
    y = rng.choice([0.0, 1.0, 5.0], 500)
    rows = {"x": x.tolist(), "y": y.tolist(), "z": (3 * x - y + 0.5).tolist()}  # z: 9 values
    variables = tuple(Variable(n, "float") for n in ("x", "y", "z"))
    assert texts(infer(variables, rows, ["ternary"])) == []


def test_folding_merging_and_chunking_agree() -> None:
    rows = _rows(n=900, seed=4)
    cuts = [0, 3, 10, 250, 251, 600, 900]
    whole = texts(infer(VARIABLES, rows, ["ternary"]))
    folded = texts(finalize(fold(VARIABLES, rows, cuts, ["ternary"]), VARIABLES))
    parts = texts(finalize(merged(VARIABLES, rows, cuts, ["ternary"], [1, 3, 4]), VARIABLES))
    assert whole == folded == parts == ["t = a - 2*m + 1"]


def test_level_support_merges_by_union() -> None:
    one, two = LevelSupport(), LevelSupport()
    key = (0, 1, 2)
    x = np.array([1.0, 2.0, 1.0, 2.0])
    live = np.array([key], dtype=np.int64)
    one.update([x, np.zeros(4), x], live, [False, True, False])
    two.update([x + 2, np.zeros(4), x + 2], live, [False, True, False])
    assert not one.supported(key, 1) and not two.supported(key, 1)
    one.merge(two)
    assert one.levels[(key, 1)] == {0.0: None}  # four distinct points on level 0: full
    assert not one.supported(key, 1)  # one level only
