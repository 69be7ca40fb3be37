"""The ordered tree reduction: any arrival order gives the left fold in position order."""

from __future__ import annotations

import pytest
from hypothesis import given
from hypothesis import strategies as st

from imrosc.fleet.tree import OrderedTree


@given(st.integers(1, 40).flatmap(lambda n: st.permutations(range(n))))
def test_any_arrival_order_joins_adjacent_values_in_position_order(order: list[int]) -> None:
    joined: list[tuple[str, str]] = []

    def join(left: str, right: str) -> str:
        joined.append((left, right))
        return left + right

    count = len(order)
    tree = OrderedTree(count, join)
    names = [f"<{i}>" for i in range(count)]
    for index in order:
        tree.add(index, names[index])
    assert tree.result() == "".join(names)
    assert len(joined) == count - 1
    # the grouping is the tree's, whatever the order: the same joins as in order
    again: OrderedTree[str] = OrderedTree(count, lambda a, b: f"({a}{b})")
    first: OrderedTree[str] = OrderedTree(count, lambda a, b: f"({a}{b})")
    for index in order:
        again.add(index, names[index])
    for index in range(count):
        first.add(index, names[index])
    assert again.result() == first.result()


@given(st.integers(1, 64))
def test_pending_values_stay_few_when_answers_come_in_order(count: int) -> None:
    tree = OrderedTree(count, lambda a, b: a + b)
    most = 0
    for index in range(count):
        tree.add(index, 1)
        most = max(most, sum(len(level) for level in tree.pending))
    assert tree.result() == count
    assert most <= max(count.bit_length(), 1)


def test_a_missing_or_foreign_value_is_an_error() -> None:
    tree = OrderedTree(3, lambda a, b: a + b)
    tree.add(0, 1)
    with pytest.raises(ValueError, match="2 of 3 values are missing"):
        tree.result()
    with pytest.raises(IndexError):
        tree.add(3, 1)
    with pytest.raises(ValueError):
        OrderedTree(0, lambda a, b: a + b)
