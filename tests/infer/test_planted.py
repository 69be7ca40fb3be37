"""bench/infer.py's planted point, small: every family together finds every planted
property (ranges, ``b = 2*a + 3``, ``a < c``, the constant, the one-of, the ternary over a
3-valued variable, ``q = -p``, ``max``, ``|x|``, ``s = ab + 5``), chunked as the bench."""

from __future__ import annotations

from bench.infer import ALL, GROUP, infer_point, planted, planted_missed
from imrosc.infer.core import Variable


def test_every_planted_property_is_found() -> None:
    rows, groups = 6000, 2
    time_s, data, names = planted(rows, groups=groups, seed=9)
    assert len(names) == groups * len(GROUP)
    variables = tuple(Variable(n, "float") for n in names)
    found = infer_point(ALL, time_s, data, variables, chunk=1500)
    assert planted_missed(found, groups) == []
    # the lines are the linear family's, not polygons
    polygons = {inv.variables for inv in found if inv.family == "polygon"}
    assert not polygons & {("a0", "b0"), ("p0", "q0"), ("ab0", "s0")}
