"""Pairs whose every block of rows is open (samples drawn independently along a band) are
filtered on their columns as they are: the same candidates as gathered row by row."""

from __future__ import annotations

import numpy as np
import pytest

from imrosc.infer.polygon import candidates
from imrosc.infer.polygon.hull import GroupSet
from tests.infer.polygon.support import state_of


def _band(rows: int, seed: int, gaps: float) -> dict[str, np.ndarray]:
    rng = np.random.default_rng(seed)
    a = rng.uniform(-10, 10, rows)
    n = rng.normal(size=rows)
    columns = {
        "a": a,
        "c": a + rng.uniform(0.5, 5, rows),  # a band along the diagonal
        "t": a - 2 * rng.choice([-1.0, 0.0, 2.0], rows) + 1,  # three parallel lines
        "n": n,
        "ab": np.abs(n),  # every sample on an edge
    }
    for name in ("c", "n"):
        columns[name][rng.random(rows) < gaps] = np.nan
    return columns


@pytest.mark.parametrize(("seed", "gaps"), [(1, 0.0), (2, 0.0), (3, 0.02)])
def test_whole_columns_give_the_same_hulls_as_rows_gathered(
    seed: int, gaps: float, monkeypatch: pytest.MonkeyPatch
) -> None:
    columns = _band(40_000, seed, gaps)
    hits: list[int] = []
    original = candidates._whole

    def counted(*args: object) -> list[GroupSet]:
        found = original(*args)  # type: ignore[arg-type]
        hits.append(len(found))
        return found

    monkeypatch.setattr(candidates, "_whole", counted)
    fast = state_of(columns, {}, 8192)
    assert hits  # some pair had every block open

    def gathered(chunk, pairs, pi, pj, guide):  # type: ignore[no-untyped-def]
        # the rows of every pair in full, through the row-by-row path
        slot = np.repeat(np.arange(len(pairs), dtype=np.int64), chunk.rows)
        row = np.tile(np.arange(chunk.rows, dtype=np.int64), len(pairs))
        return candidates._rows(chunk, pairs, pi, pj, slot, row, guide, located=False)

    monkeypatch.setattr(candidates, "_whole", gathered)
    slow = state_of(columns, {}, 8192)
    for field in ("group", "x", "y", "at"):
        assert getattr(fast.hull, field).tobytes() == getattr(slow.hull, field).tobytes()
    assert fast.count.tolist() == slow.count.tolist()
