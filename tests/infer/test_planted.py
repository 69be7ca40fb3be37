"""bench/infer.py's planted point, small: every family together finds every planted
property (ranges, ``b = 2*a + 3``, ``a < c``, the constant, the one-of, the ternary over a
3-valued variable, ``q = -p``, ``max``, ``|x|``, ``s = ab + 5``), chunked as the bench."""

from __future__ import annotations

from bench.infer import ALL, GROUP, planted, planted_missed
from imrosc.infer.core import FinalizeContext, Samples, Variable
from imrosc.infer.registry import make_point_states
from imrosc.ir import Tunables
from imrosc.translate.points import PointSpec


def test_every_planted_property_is_found() -> None:
    rows, groups = 6000, 2
    time_s, data, names = planted(rows, groups=groups, seed=9)
    assert len(names) == groups * len(GROUP)
    variables = tuple(Variable(n, "float") for n in names)
    spec = PointSpec("a", "publish", variables, ALL, trigger="/x")
    states = make_point_states(spec, Tunables())
    for start in range(0, rows, 1500):
        stop = min(start + 1500, rows)
        columns = {v.name: data[k, start:stop] for k, v in enumerate(variables)}
        samples = Samples("a", 0, time_s[start:stop], columns, variables)
        for state in states:
            state.update(samples)
    for state in states:
        state.end_run()
    context = FinalizeContext(Tunables(), variables, "a")
    found = [inv for state in states for inv in state.finalize(context)]
    assert planted_missed(found, groups) == []
    # the lines are the linear family's, not polygons
    polygons = {inv.variables for inv in found if inv.family == "polygon"}
    assert not polygons & {("a0", "b0"), ("p0", "q0"), ("ab0", "s0")}
