"""Which summary group holds which family, and the states inference builds at a point
(each family's builder is registered against the family catalog: :mod:`.builders`)."""

from __future__ import annotations

from imrosc.infer.builders import load, point_states
from imrosc.infer.core import FamilyState
from imrosc.ir import Tunables
from imrosc.runtime.families import GROUPS, group_of, in_group
from imrosc.translate.points import PointSpec

__all__ = ["DAIKON_FAMILIES", "FAMILY_GROUPS", "TIME_FAMILIES", "group_of", "make_point_states"]

FAMILY_GROUPS = {group: frozenset(in_group(group)) for group in GROUPS}
"""How summaries group families (:data:`imrosc.runtime.families.GROUPS`)."""
DAIKON_FAMILIES = FAMILY_GROUPS["default"]
TIME_FAMILIES = FAMILY_GROUPS["time-related"]
load()  # every family package registers its builders now, not within the first inference


def make_point_states(spec: PointSpec, tunables: Tunables) -> list[FamilyState]:
    """Fresh states of every family the job enables at this point, in catalog order."""
    return point_states(spec, tunables)
