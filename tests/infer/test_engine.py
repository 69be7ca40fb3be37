"""The engine: bag-parallel inference equals -j 1 and one sequential pass, exactly.

A random stream of a small system (a published value and its input, a discrete mode, a
service, parameters, architecture snapshots, events) is split at random points into bags;
inference with one worker, with two workers, and one sequential pass (one state per point
updated with every bag in order) must give identical invariants, for every family.
"""

from __future__ import annotations

import itertools
from pathlib import Path
from typing import Any

import numpy as np
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from imrosc import records
from imrosc.infer.core import Invariant
from imrosc.infer.engine import infer, informative_only, new_states
from imrosc.ir import Tunables
from imrosc.translate.stream import BagTranslator
from tests.translate import Msg, msg, specs_for, write_bag

CONFIG = """<imROS project="t">
  <scope>
    <publish id="a"><topic>/out</topic><topic>/in</topic><param>/gain</param></publish>
    <publish id="m">/mode</publish>
    <publish id="s">/scan</publish>
    <publish id="b" conds="1">/out</publish>
    <call id="c">/srv</call>
    <param id="p">/gain</param>
    <arch id="d">pub,sub,srv</arch>
    <temporal id="e" events="a,m,c">
      <pattern>(AB)*</pattern>
    </temporal>
    <condition id="1"><topic>/mode</topic><value>mode == 1</value></condition>
  </scope>
</imROS>
"""
TUNABLES = Tunables(window=0.5, confidence=0.9, hull_chunk=5, discrete=3)
FAMILIES = {
    "bounds",
    "one-of",
    "equality",
    "linear",
    "ternary",
    "string-one-of",
    "array",
    "frequency",
    "variance",
    "rate",
    "polygon",
    "architecture",
    "interval",
    "pattern",
}


def stream(seed: int, length: int) -> list[Msg]:
    """A random run of a small system in which every family has something to find."""
    rng = np.random.default_rng(seed)
    out: list[Msg] = []
    t = 0.0
    ends = {"/out": (["/ctl"], ["/motor"]), "/in": (["/src"], ["/ctl"])}
    for _ in range(length):
        t += float(rng.uniform(0.02, 0.2))
        x = float(rng.uniform(-1, 1))
        point = {"x": x, "y": x * x, "z": x - 2 * x * x + 1}  # polygon (x, y); ternary z
        out.append(msg("/in", t, "geometry_msgs/msg/Point", "/src", **point))
        out.append(msg("/out", t + 0.001, "std_msgs/msg/Float64", "/ctl", data=2 * x + 3))
        out.append(
            msg("/mode", t + 0.002, "std_msgs/msg/UInt8", "/sm", data=int(rng.integers(0, 3)))
        )
        ranges = rng.uniform(0.5, 4.0, size=int(rng.integers(5, 9))).astype(np.float32)
        period = float(rng.uniform(0.09, 0.11))  # equality: two fields always equal
        scan = {"ranges": ranges, "scan_time": period, "time_increment": period}
        out.append(msg("/scan", t + 0.003, "sensor_msgs/msg/LaserScan", "/lidar", **scan))
        roll = rng.random()
        if roll < 0.15:
            call = records.ServiceCall(
                "/srv",
                "/ctl",
                "/server",
                {"task": int(rng.integers(0, 3))},
                {"ok": True},
                True,
                t + 0.004,
                float(rng.uniform(0.1, 0.3)),
            )
            out.append(_record(records.SRVS_TOPIC, t + 0.004, call))
        elif roll < 0.2:
            gain = float(rng.choice([1.0, 2.0]))
            out.append(
                _record(records.PARAMS_TOPIC, t + 0.004, records.ParamSnapshot({"/gain": gain}))
            )
        elif roll < 0.25:
            subs = ["/motor"] if rng.random() < 0.8 else []
            ends["/out"] = (["/ctl"], subs)
            snapshot = records.ArchSnapshot(
                {k: records.TopicEnds(frozenset(p), frozenset(s)) for k, (p, s) in ends.items()},
                {"/srv": frozenset({"/server"})},
            )
            out.append(_record(records.ARCH_TOPIC, t + 0.004, snapshot))
    return out


def _record(topic: str, time: float, value: Any) -> Msg:
    return msg(topic, time, "std_msgs/msg/String", "/imrosc_record", data=records.encode(value))


def as_rows(found: list[Invariant]) -> list[tuple[Any, ...]]:
    return sorted(
        (i.point, i.family, i.kind, i.variables, repr(sorted(i.params.items())), i.text, i.samples)
        for i in found
    )


@settings(
    max_examples=12,
    deadline=None,
    suppress_health_check=[HealthCheck.too_slow, HealthCheck.function_scoped_fixture],
)
@given(
    seed=st.integers(0, 10_000),
    length=st.integers(40, 160),
    cuts=st.lists(st.floats(0.05, 0.95), max_size=3),
)
def test_parallel_equals_serial_equals_one_sequential_pass(
    tmp_path_factory: Any, seed: int, length: int, cuts: list[float]
) -> None:
    folder: Path = tmp_path_factory.mktemp("bags")
    messages = stream(seed, length)
    bounds = sorted({int(c * len(messages)) for c in cuts} | {0, len(messages)})
    bags = [
        write_bag(folder / f"run{i}.bag", messages[lo:hi])
        for i, (lo, hi) in enumerate(itertools.pairwise(bounds))
        if hi > lo
    ]
    specs, layouts, catalog = specs_for(CONFIG, bags)
    serial = infer(bags, specs, layouts, catalog.callerids, TUNABLES, workers=1)
    parallel = infer(bags, specs, layouts, catalog.callerids, TUNABLES, workers=2)
    assert as_rows(serial.invariants(TUNABLES)) == as_rows(parallel.invariants(TUNABLES))

    states = new_states(specs, TUNABLES, discover=False)
    for run, bag in enumerate(sorted(bags)):
        for samples in BagTranslator(specs, layouts, catalog.callerids).translate(bag, run):
            states[samples.point].update(samples)
        for state in states.values():
            state.end_run()
    sequential = informative_only(
        [
            i
            for key, state in states.items()
            for i in state.finalize(
                TUNABLES, state.spec.condition.id if state.spec.condition else None
            )
        ]
    )
    declared = [i for i in serial.invariants(TUNABLES) if "==" not in (i.condition or "")]
    assert as_rows(sequential) == as_rows(declared)
    assert serial.invariants(TUNABLES)


def test_the_random_system_gives_every_family(tmp_path: Path) -> None:
    """So that the property above is about every family, not a few."""
    messages = stream(3, 160)
    bags = [
        write_bag(tmp_path / "r0.bag", messages[:300]),
        write_bag(tmp_path / "r1.bag", messages[300:]),
    ]
    specs, layouts, catalog = specs_for(CONFIG, bags)
    result = infer(bags, specs, layouts, catalog.callerids, TUNABLES, workers=1)
    found = {i.family for i in result.invariants(TUNABLES)}
    assert found >= FAMILIES, FAMILIES - found
