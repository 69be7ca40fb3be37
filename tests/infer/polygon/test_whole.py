"""Pairs whose every block of rows is open (samples drawn independently along a band) are
filtered on their columns as they are, their rows on ``y = x`` or ``y = -x`` exactly but
each line's ends left out: the same hulls as every row gathered and looked up."""

from __future__ import annotations

import numpy as np
import pytest

from imrosc.infer.polygon import candidates
from imrosc.infer.polygon.hull import GroupSet
from tests.infer.polygon.reference import hull_with_first
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
        "mx": np.maximum(n, rng.normal(size=rows)),  # half the samples on y = x
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

    on_lines: list[int] = []
    off_lines = candidates._off_lines

    def lines(x: np.ndarray, y: np.ndarray) -> tuple[np.ndarray | None, np.ndarray]:
        rest, ends = off_lines(x, y)
        if rest is not None:
            on_lines.append(len(x) - len(rest))
        return rest, ends

    monkeypatch.setattr(candidates, "_whole", counted)
    monkeypatch.setattr(candidates, "_off_lines", lines)
    fast = state_of(columns, {}, 8192)
    assert hits  # some pair had every block open
    assert sum(on_lines) > 10_000  # n beside |n| and max(n, .): rows on y = +-x left out

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


@pytest.mark.parametrize("seed", [4, 5, 6])
def test_rows_on_lines_left_out_keep_the_hull_and_its_first_occurrences(seed: int) -> None:
    """The rows :func:`candidates._off_lines` keeps (off both lines, and each line's ends)
    have the hull of all rows, each vertex at its earliest row (rational reference)."""
    rng = np.random.default_rng(seed)
    rows = 600
    x = rng.choice(np.array([-3.0, -1.5, -0.0, 0.0, 0.5, 2.0, 2.5]), rows)
    kind = rng.integers(0, 3, rows)
    y = np.where(kind == 0, x, np.where(kind == 1, -x, x + rng.uniform(0.1, 1.0, rows)))
    y[rng.random(rows) < 0.05] = np.nan
    y[:3] = x[:3]  # the head shows a row on y = x
    rest, ends = candidates._off_lines(x, y)
    assert rest is not None and len(rest) < rows
    kept = np.sort(np.concatenate([rest, ends]))
    on = (x == y) | (x == -y)
    assert not on[rest].any() and on[ends].all()

    def points(index: np.ndarray) -> list[tuple[float, float]]:
        pairs = zip(x[index].tolist(), y[index].tolist(), strict=True)
        return [(px, py) for px, py in pairs]

    present = np.flatnonzero(~np.isnan(y))
    want = hull_with_first(points(present))
    got = hull_with_first(points(kept[~np.isnan(y[kept])]))
    # first occurrences: positions in ``present`` and in ``kept``, both as rows
    assert [(vx, vy, int(present[k])) for vx, vy, k in want] == [
        (vx, vy, int(kept[~np.isnan(y[kept])][k])) for vx, vy, k in got
    ]
    assert candidates._off_lines(x + 7.0, y)[0] is None  # no row on a line in the head
