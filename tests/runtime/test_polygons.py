"""Polygon checks: whatever path a sample takes (table, the edges of its cell, every edge,
the slow path), the answer is the polygons with an edge ``a*x + b*y > c``."""

from __future__ import annotations

import json
import math
from typing import Any

import numpy as np
import numpy.typing as npt
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from imrosc.runtime import polygons as module
from imrosc.runtime.polygons import DECODE, PolygonChecks, grid_size
from tests.runtime.support import Plain, clouds_over, hull_polygons


def build(clouds: dict[tuple[int, int], npt.NDArray[np.float64]]) -> tuple[PolygonChecks, Plain]:
    """Checks over the hulls of ``clouds``, and each polygon's plain ``(x, y, a, b, c)``."""
    invariants, edges, plain = hull_polygons(clouds)
    return PolygonChecks(invariants, edges), plain


def expected(plain: Plain, sample: list[float]) -> list[int]:
    found = []
    for owner, (x, y, a, b, c) in enumerate(plain):
        px, py = sample[x], sample[y]
        if math.isfinite(px) and math.isfinite(py) and bool(np.any(a * px + b * py > c)):
            found.append(owner)
    return found


def answers(checks: PolygonChecks, sample: list[float]) -> list[int]:
    row = np.asarray(sample, dtype=np.float64)
    with np.errstate(all="ignore"):
        found = checks.broken(row)
        assert found == checks.broken(row, checks.in_range(row))
    return found


@settings(max_examples=30, deadline=None)
@given(
    st.integers(0, 2**32 - 1),
    st.sampled_from(["walk", "ints", "mixed", "scaled"]),
    st.integers(4, 9),
    st.sampled_from([0, module._MANY, 10**9]),
    st.sampled_from([0, module._FEW, 10**9]),
    st.sampled_from([1, module._FINE_RUNS]),
)
def test_every_path_answers_like_the_half_planes(
    seed: int, shape: str, variables: int, many: int, few: int, remembered: int
) -> None:
    # many: candidates beyond it test every edge at once (0: always, 10**9: never); few:
    # candidates up to it read coordinates one by one; remembered: the fine cells' runs
    # kept (1: the memory is cleared at every new cell)
    with pytest.MonkeyPatch.context() as patch:
        patch.setattr(module, "_MANY", many)
        patch.setattr(module, "_FEW", few)
        patch.setattr(module, "_FINE_RUNS", remembered)
        every_path_answers_like_the_half_planes(seed, shape, variables)


def every_path_answers_like_the_half_planes(seed: int, shape: str, variables: int) -> None:
    rng = np.random.default_rng(seed)
    clouds, data = clouds_over(rng, variables, 200, shape)
    checks, plain = build(clouds)
    low, high = data.min(axis=0), data.max(axis=0)
    span = np.where(high > low, high - low, 1.0)
    queries = [
        *data[:60],  # training samples: inside everything
        *(low + rng.uniform(-0.1, 1.1, (150, variables)) * span),  # in and out of range
        *(data[rng.integers(0, len(data), 40)] * (1 + rng.normal(0, 1e-12, (40, variables)))),
        *(data[rng.integers(0, len(data), 40)] + rng.normal(0, 0.05, (40, variables)) * span),
        high + span,  # far out: every polygon
    ]
    for k, query in enumerate(queries):
        sample = query.tolist()
        for hole in ([], [0], [1, 2]):  # NaN and inf coordinates break no polygon
            broken = list(sample)
            for at in hole:
                broken[at] = [math.nan, math.inf, -math.inf][k % 3]
            assert answers(checks, broken) == expected(plain, broken), (k, hole)
        if k < 60:
            assert answers(checks, sample) == []


def test_a_sample_on_the_range_end_of_an_integer_variable_is_inside_without_edges() -> None:
    # the hull of (noise, integer) has edges along the integer's range ends: the cells
    # there are cut to the range, so the samples on them are inside by the table alone
    rng = np.random.default_rng(3)
    cloud = np.stack([rng.normal(0, 1, 500), rng.integers(0, 4, 500)], axis=1).astype(float)
    checks, _ = build({(0, 1): cloud})
    rows = [np.asarray([x, 0.0]) for x in np.linspace(-0.5, 0.5, 20)]
    codes = []
    for row in rows:
        g = (row - checks.origin) * checks.scale
        flat = g.astype(np.uint8)[checks.at].view(np.uint16) + checks.base
        codes.append(int(checks.table[flat][0]))
    assert codes == [0] * len(rows)
    assert answers(checks, [0.0, -1e-9]) == [0]
    assert answers(checks, [0.0, 3.0 + 1e-9]) == [0]


def test_polygons_with_many_edges_test_the_edges_past_the_codes() -> None:
    angle = np.linspace(0, 2 * np.pi, 90, endpoint=False)
    circle = np.stack([np.cos(angle), np.sin(angle)], axis=1) * 5 + 1
    checks, plain = build({(0, 1): circle})
    assert len(plain[0][4]) == 90  # more edges than a table code can start at
    rng = np.random.default_rng(0)
    for point in rng.uniform(-5, 7, (3000, 2)):
        assert answers(checks, point.tolist()) == expected(plain, point.tolist())
    near = circle * (1 + 1e-13)  # just outside each vertex
    for point in near:
        assert answers(checks, point.tolist()) == expected(plain, point.tolist())


def test_degenerate_ranges_test_every_edge() -> None:
    # a constant variable (a vertical segment) and one whose range is below its ulps
    constant = np.stack([np.full(5, 2.0), np.arange(5.0)], axis=1)
    tiny = np.stack([1e15 + np.arange(4.0) * 0.125, np.arange(4.0) ** 2], axis=1)
    checks, plain = build({(0, 1): constant, (2, 3): tiny})
    for sample in ([2.0, 1.0, 1e15, 0.0], [2.0, 5.0, 1e15 + 0.25, 9.0], [2.5, 1.0, 1e15, 2.0]):
        assert answers(checks, sample) == expected(plain, sample)


def test_many_candidates_take_one_array_operation(monkeypatch: pytest.MonkeyPatch) -> None:
    rng = np.random.default_rng(5)
    clouds, data = clouds_over(rng, 9, 100, "walk")
    checks, plain = build(clouds)
    outside = data.max(axis=0) - 1e-9 * np.abs(data.max(axis=0))  # in range, at the top
    called = []
    original = PolygonChecks._outside

    def spy(self: PolygonChecks, row: Any, candidates: Any) -> list[int]:
        called.append(len(candidates))
        return original(self, row, candidates)

    monkeypatch.setattr(PolygonChecks, "_outside", spy)
    monkeypatch.setattr(module, "_MANY", 0)
    assert answers(checks, outside.tolist()) == expected(plain, outside.tolist())
    assert called and called[0] > 0


def test_table_codes_name_runs_of_edges() -> None:
    assert DECODE[0] == (0, 0)
    runs = {DECODE[code] for code in range(1, 255) if DECODE[code] != (0, 0)}
    assert (0, 1) in runs and (41, 47) in runs
    assert all(0 < stop - first <= 6 for first, stop in runs)


def test_the_grid_shrinks_to_keep_the_tables_in_budget() -> None:
    assert grid_size(10) == 64
    assert grid_size(5000) == 32
    assert grid_size(10**6) == 8
    assert all(256 % grid_size(n) == 0 for n in (1, 3000, 40000))


def test_samples_that_stay_in_their_cells_are_still_tested_exactly() -> None:
    # the lookup is skipped when no cell changed, the edges of the cell are not
    triangle = np.asarray([[0.0, 0.0], [1.0, 0.0], [0.0, 1.0]])
    checks, plain = build({(0, 1): triangle})
    samples = [[0.5, 0.5 - 1e-9], [0.5, 0.5 + 1e-9], [0.5, 0.5 - 2e-9], [0.5, 0.5 + 2e-9]]
    assert [answers(checks, s) for s in samples] == [[], [0], [], [0]]
    assert [expected(plain, s) for s in samples] == [[], [0], [], [0]]
    assert answers(checks, [0.1, 0.1]) == []  # another cell, inside
    assert answers(checks, [0.5, 0.5 + 1e-9]) == [0]


def test_fine_bits_split_the_cells_near_an_edge() -> None:
    # a fine cell near an edge lies in a coarse cell near one (its code is not 0), and
    # splitting leaves fewer samples for the exact test
    rng = np.random.default_rng(11)
    clouds, data = clouds_over(rng, 5, 2000, "walk")
    checks, _ = build(clouds)
    grid, fine = checks.grid, 2 * checks.grid
    steps, fine_steps = np.arange(grid), np.arange(fine)
    for owner in range(checks.count):
        codes = checks.table[checks.base[owner] + steps[:, None] + 256 * steps[None, :]]
        spots = checks.fine_base[owner] + fine_steps[:, None] + 256 * fine_steps[None, :]
        bits = (checks.bits[spots.T if checks.flipped[owner] else spots] & checks.bit[owner]) != 0
        assert not (bits & (np.repeat(np.repeat(codes, 2, 0), 2, 1) == 0)).any()
        assert 0 < bits.sum() < 4 * (codes != 0).sum()
    coarse = fine_near = 0
    for row in data:
        g = (row - checks.origin) * checks.scale
        coarse += int(
            np.count_nonzero(
                checks.table[g.astype(np.uint8)[checks.at].view(np.uint16) + checks.base]
            )
        )
        f = ((row - checks.origin) * checks.fine_scale).astype(np.uint8)
        hit = checks.bits[f[checks.fine_at].view(np.uint16) + checks.fine_base] & checks.bit
        fine_near += int(np.count_nonzero(hit))
    assert fine_near < 0.75 * coarse


def test_polygons_sharing_bytes_read_the_same_row_variable() -> None:
    # a slot's polygons read one row of it per sample: one row variable, one bit each
    rng = np.random.default_rng(2)
    data = rng.normal(0, 1, (300, 17))
    pairs = [(0, j) for j in range(1, 17)] + [(1, 2), (3, 4), (5, 6)]
    checks, _ = build({pair: data[:, list(pair)] for pair in pairs})
    slots: dict[int, list[tuple[int, int]]] = {}
    for owner in range(checks.count):
        row = checks.xs[owner] if checks.flipped[owner] else checks.ys[owner]
        slots.setdefault(int(checks.fine_base[owner]), []).append((row, int(checks.bit[owner])))
    for members in slots.values():
        assert len({row for row, _ in members}) == 1
        assert len({bit for _, bit in members}) == len(members) <= 8
    # the sixteen polygons over variable 0 fill two slots (x is their row variable)
    full = [members for members in slots.values() if len(members) == 8]
    assert len(full) == 2 and all(row == 0 for members in full for row, _ in members)
    assert len(slots) == 5


def test_lazy_tables_are_built_at_first_use_and_answer_alike() -> None:
    """``lazy``: no tables until a sample or the compiled kernel needs them; then the
    answers and the kernel's tables are those of tables built at once."""
    rng = np.random.default_rng(7)
    clouds, data = clouds_over(rng, 5, 200, "mixed")
    invariants, edges, plain = hull_polygons(clouds)
    built, lazy = PolygonChecks(invariants, edges), PolygonChecks(invariants, edges, lazy=True)
    assert not hasattr(lazy, "bits")
    low, high = data.min(axis=0), data.max(axis=0)
    for query in (data[0], low - 1.0, high + 1.0, (low + high) / 2):
        sample = query.tolist()
        assert answers(lazy, sample) == answers(built, sample) == expected(plain, sample)
    compiled_lazy = PolygonChecks(invariants, edges, lazy=True).compiled()
    assert _json(compiled_lazy) == _json(built.compiled())


def _json(value: Any) -> str:
    return json.dumps(value, default=lambda array: np.asarray(array).tolist())


@pytest.mark.parametrize("block", [1, 7, 4096])
def test_tables_built_a_few_edges_at_a_time_are_those_built_at_once(
    monkeypatch: pytest.MonkeyPatch, block: int
) -> None:
    """The worst corners are summed for a block of edges at a time (:data:`_BLOCK`), so a
    hull of a thousand edges does not take tens of MB to build: the codes and the bits are
    those of every edge at once (block 1: one edge; 4096: one row of coarse cells)."""
    angle = np.linspace(0, 2 * np.pi, 1200, endpoint=False)
    circle = np.stack([np.cos(angle), 3 * np.sin(angle)], axis=1) + 2
    rng = np.random.default_rng(3)
    clouds, _ = clouds_over(rng, 4, 300, "walk")
    clouds[(4, 5)] = circle
    invariants, edges, _ = hull_polygons(clouds)
    assert max(len(inv["params"]["A"]) for inv in invariants) == 1200
    monkeypatch.setattr(module, "_BLOCK", 1 << 40)  # every edge at once
    whole = PolygonChecks(invariants, edges)
    monkeypatch.setattr(module, "_BLOCK", block)
    parts = PolygonChecks(invariants, edges)
    assert np.array_equal(parts.table, whole.table)
    assert np.array_equal(parts.bits, whole.bits)
    assert whole.bits.any() and (whole.table != 0).any()
