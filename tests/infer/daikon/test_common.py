"""Shared summaries of Daikon's families: the distinct values of a column."""

from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from imrosc.infer.daikon.common import Distinct, _few_values, summarize

LEVELS = np.array([-1.0, 0.0, 2.0, np.inf, -np.inf, 5e-324, 3.5])


@settings(max_examples=300, deadline=None)
@given(st.lists(st.integers(0, len(LEVELS) - 1), max_size=40), st.integers(1, 5))
def test_few_values_are_numpys_unique_with_first_positions(picks: list[int], limit: int) -> None:
    kept = LEVELS[np.array(picks, np.int64)]
    values, first = np.unique(kept, return_index=True)
    wanted = None
    if len(values) <= limit:
        wanted = ([float(v) for v in values], [int(p) for p in first], len(kept))
    assert _few_values(kept, limit) == wanted


def test_states_of_one_chunk_share_its_distinct_values() -> None:
    """The first state to look fills the column summary's cache; the next one reads it, and
    a state with a lower limit finds its own answer."""
    column = np.array([2.0, 0.0, np.nan, 2.0, -1.0, 0.0])
    summary = summarize(column)
    first, second, strict = Distinct(1), Distinct(1), Distinct(1, limit=2)
    first.update([column], [summary])
    assert set(summary.distinct) == {"head", "full3"}
    second.update([column], [summary])
    strict.update([column], [summary])
    assert first.values == second.values == [{-1.0: 3, 0.0: 1, 2.0: 0}]
    assert strict.overflow == [True]
    assert "full2" not in summary.distinct  # the first rows' three values decided it
