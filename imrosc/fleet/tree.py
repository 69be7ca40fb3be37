"""An ordered tree reduction: answers arrive in any order, adjacent ones are joined.

The merge of inference states is exact and associative, but not commutative: a state absorbs
the runs that come *after* its own. :class:`OrderedTree` joins the answers of consecutive bags
as they complete, in a tree fixed by the count alone, so the grouping is the same whatever
order the answers arrive in and the result equals a left fold in bag order.

The tree is shaped for bags that complete about in order: the bags are cut in consecutive
shares (one per worker, which reads its share in order), each share cut in consecutive blocks
of halving size (20, 10, 5, 3, 1 and 1 of 40 bags), each block a balanced tree, the blocks
joined left to right, and the shares joined as a balanced tree. The joins inside a share's
early blocks run beside its later bags, and when its last bag completes, one or two joins are
left (a balanced tree over every bag leaves a chain as deep as the tree, a join and a transfer
of the states between workers each); the shares, which end about together, then take as many
joins as the depth of their tree.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from typing import Generic, TypeVar

T = TypeVar("T")


def blocks(count: int) -> list[tuple[int, int]]:
    """The consecutive blocks ``(first, stop)`` of halving size that cover ``count`` bags.

    >>> blocks(40)
    [(0, 20), (20, 30), (30, 35), (35, 38), (38, 39), (39, 40)]
    """
    found, first = [], 0
    while first < count:
        size = (count - first + 1) // 2
        found.append((first, first + size))
        first += size
    return found


def cut(count: int, parts: int) -> list[int]:
    """The sizes of ``parts`` consecutive shares of ``count`` values (the first ones a value
    more; no empty share).

    >>> cut(40, 3)
    [14, 13, 13]
    """
    parts = max(1, min(parts, count))
    return [count // parts + (part < count % parts) for part in range(parts)]


class OrderedTree(Generic[T]):
    """Join ``count`` values, given by position in any order, as a tree of :func:`blocks` in
    each of the consecutive ``shares`` (their sizes; one share of every value by default),
    the shares joined as a balanced tree.

    >>> tree = OrderedTree(5, lambda a, b: f"({a}{b})")
    >>> for index in (4, 1, 3, 0, 2):
    ...     tree.add(index, "abcde"[index])
    >>> tree.result()
    '((((ab)c)d)e)'
    >>> tree = OrderedTree(8, lambda a, b: f"({a}{b})")
    >>> for index in range(8):
    ...     tree.add(index, "abcdefgh"[index])
    >>> tree.result()
    '(((((ab)(cd))(ef))g)h)'
    >>> tree = OrderedTree(8, lambda a, b: f"({a}{b})", shares=[4, 4])
    >>> for index in range(8):
    ...     tree.add(index, "abcdefgh"[index])
    >>> tree.result()
    '((((ab)c)d)(((ef)g)h))'
    """

    def __init__(
        self, count: int, join: Callable[[T, T], T], shares: Sequence[int] | None = None
    ) -> None:
        if count < 1:
            raise ValueError("an ordered tree needs at least one value")
        sizes = list(shares) if shares is not None else [count]
        if sum(sizes) != count or min(sizes) < 1:
            raise ValueError(f"shares {sizes} do not cut {count} values")
        self.count = count
        self.join = join
        self.parent: list[int] = [-1] * count
        """Each node's parent (the leaves are the nodes ``0 .. count - 1``; -1: the root)."""
        self.children: dict[int, tuple[int, int]] = {}
        """Each inner node's left and right child."""
        self.pending: dict[int, T] = {}
        """The nodes whose value waits for its sibling's."""
        self.added = 0
        self._root: list[T] = []
        roots, first = [], 0
        for size in sizes:
            spine = -1
            for start, stop in blocks(size):
                block = self._joined(list(range(first + start, first + stop)))
                spine = block if spine < 0 else self._node(spine, block)
            roots.append(spine)
            first += size
        self._joined(roots)

    def _joined(self, nodes: list[int]) -> int:
        """The root of a balanced tree over ``nodes`` (consecutive, in order; the left half
        the larger): a block's leaves, or the shares' roots."""
        if len(nodes) == 1:
            return nodes[0]
        middle = (len(nodes) + 1) // 2
        return self._node(self._joined(nodes[:middle]), self._joined(nodes[middle:]))

    def _node(self, left: int, right: int) -> int:
        node = len(self.parent)
        self.parent.append(-1)
        self.parent[left] = self.parent[right] = node
        self.children[node] = (left, right)
        return node

    def add(self, index: int, value: T) -> None:
        """The value at ``index`` (each index once)."""
        if not 0 <= index < self.count:
            raise IndexError(f"position {index} out of 0..{self.count - 1}")
        self.added += 1
        node = index
        while True:
            parent = self.parent[node]
            if parent < 0:
                self._root.append(value)
                return
            left, right = self.children[parent]
            other = self.pending.pop(right if node == left else left, None)
            if other is None:
                self.pending[node] = value
                return
            value = self.join(value, other) if node == left else self.join(other, value)
            node = parent

    def result(self) -> T:
        """The join of every value, once all are added."""
        if self.added != self.count or len(self._root) != 1:
            raise ValueError(f"{self.count - self.added} of {self.count} values are missing")
        return self._root[0]
