"""An ordered tree reduction: answers arrive in any order, adjacent ones are joined.

The merge of inference states is exact and associative, but not commutative: a state absorbs
the runs that come *after* its own. :class:`OrderedTree` joins the answers of consecutive bags
pairwise, level by level, as they complete (bags 0 and 1, 2 and 3, then 0-1 and 2-3, ...),
so the grouping is the same whatever order the answers arrive in, the client holds at most
one pending answer per level and bag, and the result equals a left fold in bag order.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Generic, TypeVar

T = TypeVar("T")


class OrderedTree(Generic[T]):
    """Join ``count`` values, given by position in any order, as a balanced binary tree.

    >>> tree = OrderedTree(5, lambda a, b: f"({a}{b})")
    >>> for index in (4, 1, 3, 0, 2):
    ...     tree.add(index, "abcde"[index])
    >>> tree.result()
    '(((ab)(cd))e)'
    """

    def __init__(self, count: int, join: Callable[[T, T], T]) -> None:
        if count < 1:
            raise ValueError("an ordered tree needs at least one value")
        self.count = count
        self.join = join
        self.pending: list[dict[int, T]] = []
        """Per level, the nodes that wait for their sibling, by position at that level."""
        self.added = 0
        self._root: list[T] = []

    def add(self, index: int, value: T) -> None:
        """The value at ``index`` (each index once)."""
        if not 0 <= index < self.count:
            raise IndexError(f"position {index} out of 0..{self.count - 1}")
        self.added += 1
        level, width = 0, self.count
        while width > 1:
            if len(self.pending) <= level:
                self.pending.append({})
            sibling = index ^ 1
            if sibling < width:  # else the odd one out at this level goes up alone
                other = self.pending[level].pop(sibling, None)
                if other is None:
                    self.pending[level][index] = value
                    return
                value = self.join(other, value) if sibling < index else self.join(value, other)
            index //= 2
            width = (width + 1) // 2
            level += 1
        self._root.append(value)

    def result(self) -> T:
        """The join of every value, once all are added."""
        if self.added != self.count or len(self._root) != 1:
            raise ValueError(f"{self.count - self.added} of {self.count} values are missing")
        return self._root[0]
