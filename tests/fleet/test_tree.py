"""The ordered tree reduction: any arrival order gives the left fold in position order; the
held-out replays' shares of the folds."""

from __future__ import annotations

import pytest
from hypothesis import given
from hypothesis import strategies as st

from imrosc.fleet.cluster import shares
from imrosc.fleet.tree import OrderedTree, cut


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


@given(st.integers(1, 40).flatmap(lambda n: st.permutations(range(n))), st.integers(1, 8))
def test_shares_join_adjacent_values_in_position_order(order: list[int], parts: int) -> None:
    """Each worker's consecutive share, then the shares: still the left fold in position
    order, whatever the order the values come in, and the same grouping every time."""
    count = len(order)
    sizes = cut(count, parts)
    assert sum(sizes) == count and len(sizes) == min(parts, count)
    assert max(sizes) - min(sizes) <= 1
    names = [f"<{i}>" for i in range(count)]
    flat: OrderedTree[str] = OrderedTree(count, lambda a, b: a + b, sizes)
    grouped: OrderedTree[str] = OrderedTree(count, lambda a, b: f"({a}{b})", sizes)
    first: OrderedTree[str] = OrderedTree(count, lambda a, b: f"({a}{b})", sizes)
    for index in order:
        flat.add(index, names[index])
        grouped.add(index, names[index])
    for index in range(count):
        first.add(index, names[index])
    assert flat.result() == "".join(names)
    assert grouped.result() == first.result()
    # the shares' own trees are those of the shares alone
    if len(sizes) == 2:
        alone: OrderedTree[str] = OrderedTree(sizes[0], lambda a, b: f"({a}{b})")
        for index in range(sizes[0]):
            alone.add(index, names[index])
        assert first.result().startswith("(" + alone.result())


def test_shares_that_do_not_cut_the_values_are_an_error() -> None:
    with pytest.raises(ValueError, match="do not cut"):
        OrderedTree(4, lambda a, b: a + b, [2, 1])
    with pytest.raises(ValueError, match="do not cut"):
        OrderedTree(4, lambda a, b: a + b, [4, 0])


@given(st.integers(1, 64))
def test_pending_values_stay_few_when_answers_come_in_order(count: int) -> None:
    tree = OrderedTree(count, lambda a, b: a + b)
    most = 0
    for index in range(count):
        tree.add(index, 1)
        most = max(most, len(tree.pending))
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


@given(st.lists(st.integers(0, 12), min_size=1, max_size=8), st.integers(1, 10))
def test_held_out_shares_are_consecutive_slices_of_even_size(sizes: list[int], parts: int) -> None:
    """Calibration's held-out replays: every fold's bags once, in order, in shares whose
    bags differ by one at most; a share holds one slice per fold it spans."""
    cut = shares(sizes, parts)
    every = [
        (fold, bag) for share in cut for fold, first, stop in share for bag in range(first, stop)
    ]
    assert every == [(fold, bag) for fold, size in enumerate(sizes) for bag in range(size)]
    counts = [sum(stop - first for _, first, stop in share) for share in cut]
    assert len(cut) == max(1, min(parts, sum(sizes)))
    assert max(counts) - min(counts) <= 1
    for share in cut:
        folds = [fold for fold, _, _ in share]
        assert folds == sorted(set(folds))
        assert all(first < stop for _, first, stop in share)
