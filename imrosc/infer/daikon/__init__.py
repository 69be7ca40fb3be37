"""Daikon's default invariant families (thesis 3.4) as mergeable states.

Each module registers the state builder of its family (:mod:`imrosc.infer.builders`);
``make_states`` builds, for one program point, a state per enabled family:

* ``bounds``: ``x >= a``, ``x <= b``, ``a <= x <= b``;
* ``one-of``: ``x one of {1, 2, 3}``, ``x == c``;
* ``non-zero``: ``x != 0`` (integers, Daikon's rule);
* ``equality``: equality sets ``a == b == c``;
* ``order``: ``x < y``, ``x <= y``;
* ``linear``: ``y = a*x + b``;
* ``ternary``: ``z = a*x + b*y + c``;
* ``string-one-of``: ``mode one of {"a", "b"}``;
* ``array``: bounds of ``len``/``avg``/``std`` and element bounds of numeric arrays.

Every state keeps order-independent summaries, so updating one state with chunks in order
and merging states built from parts give the same invariants (``docs/families/daikon.md``).
"""

from __future__ import annotations

from imrosc.infer.builders import point_states, variables_point
from imrosc.infer.core import FamilyState, Variable
from imrosc.ir import Tunables
from imrosc.runtime.families import in_group

FAMILIES = in_group("default")
"""The families this package builds, in the order ``make_states`` returns them."""

__all__ = ["FAMILIES", "make_states"]


def make_states(
    variables: tuple[Variable, ...], tunables: Tunables, families: frozenset[str]
) -> list[FamilyState]:
    """Fresh states of the enabled Daikon families for a point with ``variables`` (each
    module registers its family's builder: :mod:`imrosc.infer.builders`)."""
    return point_states(variables_point(variables, families), tunables, FAMILIES)
