"""Daikon's default invariant families (thesis 3.4) as mergeable states.

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

from collections.abc import Callable

from imrosc.infer.core import FamilyState, Variable
from imrosc.infer.daikon.array import ArrayState
from imrosc.infer.daikon.bounds import BoundsState
from imrosc.infer.daikon.equality import EqualityState
from imrosc.infer.daikon.function import FunctionState
from imrosc.infer.daikon.linear import LinearState
from imrosc.infer.daikon.non_zero import NonZeroState
from imrosc.infer.daikon.one_of import OneOfState
from imrosc.infer.daikon.order import OrderState
from imrosc.infer.daikon.string_one_of import StringOneOfState
from imrosc.infer.daikon.ternary import TernaryState
from imrosc.ir import Tunables
from imrosc.runtime.families import in_group

FAMILIES = in_group("default")
"""The families this package builds, in the order ``make_states`` returns them."""

__all__ = ["FAMILIES", "make_states"]


def make_states(
    variables: tuple[Variable, ...], tunables: Tunables, families: frozenset[str]
) -> list[FamilyState]:
    """Fresh states of the enabled Daikon families for a point with ``variables``."""
    del tunables  # justification reads the limit from the finalize context
    one_of = "one-of" in families
    builders: dict[str, Callable[[], FamilyState]] = {
        "bounds": lambda: BoundsState(variables, one_of=one_of, equality="equality" in families),
        "one-of": lambda: OneOfState(variables),
        "non-zero": lambda: NonZeroState(variables, one_of=one_of),
        "equality": lambda: EqualityState(variables),
        "order": lambda: OrderState(variables, bounds="bounds" in families),
        "linear": lambda: LinearState(variables),
        "ternary": lambda: TernaryState(variables),
        "function": lambda: FunctionState(variables),
        "string-one-of": lambda: StringOneOfState(variables),
        "array": lambda: ArrayState(variables),
    }
    states: list[FamilyState] = []
    for family in FAMILIES:
        if family in families:
            states.append(builders[family]())
    return states
