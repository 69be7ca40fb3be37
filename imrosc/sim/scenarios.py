"""Fault scenarios: a nominal run with one thing wrong (thesis Table 5.1, and section 3.4.3).

A :class:`Scenario` names a fault and when it starts (and, optionally, how long it lasts). The
fault is injected into what is recorded, after the nominal run has been simulated: the physics
and the controller are those of the nominal run with the same seed, so a faulty bag differs
from its nominal twin only where the fault shows, which is what checking invariants needs.
Each fault is made for one invariant family:

==================== =========================================================== ==============
kind                 what changes                                                family
==================== =========================================================== ==============
slowed               /a/car_pose drops to 0.5 Hz for 5 s in every 10 s (s5)     frequency
spoofed              /a/car_pose jumps 1.5 m towards the room's centre (s6)      rate, bounds,
                                                                                 polygon
stuck                /a/subject_status repeats its last values: zero variance    variance
tilt                 the platform tips 0.3 rad in roll, -0.2 in pitch (s4) on    bounds
                     /vicon/car and /a/car_pose
extra_publisher      /a/car2 also publishes /a/car_pose (20 Hz, its own          architecture
                     connection and callerid) and shows in the graph record
missing_subscriber   /a/launch_ctrl leaves the graph record                      architecture
out_of_order         /a/car_ctrl sends the waypoint before the state command     interval
                     of the same cycle
==================== =========================================================== ==============

A graph change is recorded at the recording node's next poll (every 0.5 s). The swapped order
shows in the ordered-pair intervals (command -> waypoint grows from under 1 ms to about 50 ms,
waypoint -> command shrinks from about 50 ms to under 1 ms); a pattern over the event sequence
alone cannot see it, since the swapped pairs still alternate with the other cycles' waypoints.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from typing import Literal, get_args

import numpy as np
from numpy.typing import NDArray

from imrosc.records import ARCH_TOPIC, encode
from imrosc.runtime.families import (
    ARCHITECTURE,
    BOUNDS,
    FREQUENCY,
    INTERVAL,
    POLYGON,
    RATE,
    VARIANCE,
)
from imrosc.sim import world as w
from imrosc.sim.recording import (
    POSE_TYPE,
    SECOND,
    START_NS,
    Stream,
    arch_snapshot,
    poll_time,
)

__all__ = [
    "EXTRA_PUBLISHER",
    "FAMILIES",
    "MISSING_SUBSCRIBER",
    "SCENARIO_KINDS",
    "SLOW_PERIOD",
    "SLOW_RATE",
    "SPOOF_JUMP",
    "TILT",
    "Scenario",
    "ScenarioKind",
    "apply_scenario",
]

ScenarioKind = Literal[
    "slowed",
    "spoofed",
    "stuck",
    "tilt",
    "extra_publisher",
    "missing_subscriber",
    "out_of_order",
]
SCENARIO_KINDS: tuple[ScenarioKind, ...] = get_args(ScenarioKind)

FAMILIES: dict[ScenarioKind, tuple[str, ...]] = {
    "slowed": (FREQUENCY,),
    "spoofed": (RATE, BOUNDS, POLYGON),
    "stuck": (VARIANCE,),
    "tilt": (BOUNDS,),
    "extra_publisher": (ARCHITECTURE, FREQUENCY),
    "missing_subscriber": (ARCHITECTURE,),
    "out_of_order": (INTERVAL,),
}
"""The invariant families that see each fault (a spoofed jump also leaves the room's bounds
when the platform is near a wall; a second publisher doubles /a/car_pose's frequency)."""

SLOW_PERIOD = 5.0
"""The link is slow for 5 s, then normal for 5 s, and so on (s)."""
SLOW_RATE = 0.5
"""The rate of /a/car_pose while the link is slow (Hz)."""
SPOOF_JUMP = 1.5
"""How far the fake platform is from the real one (m)."""
TILT = (0.3, -0.2)
"""Roll and pitch of the tipped platform (rad), reached 0.5 s after the start of the fault."""
TILT_RAMP = 0.5
EXTRA_PUBLISHER = "/a/car2"
"""A second copy of the platform driver, launched by mistake."""
MISSING_SUBSCRIBER = "/a/launch_ctrl"
"""The subscriber of /a/subject_ctrl_state that dies."""


@dataclass(frozen=True)
class Scenario:
    """A fault of the given kind from ``start`` seconds into the run, for ``length`` seconds.

    ``length`` None means until the end of the run.
    """

    kind: ScenarioKind
    start: float = 10.0
    length: float | None = None

    def __post_init__(self) -> None:
        if self.kind not in SCENARIO_KINDS:
            raise ValueError(
                f"unknown scenario {self.kind!r}; expected one of {', '.join(SCENARIO_KINDS)}"
            )
        if not (math.isfinite(self.start) and self.start >= 0):
            raise ValueError(f"scenario start must be a time >= 0 s, not {self.start!r}")
        if self.length is not None and not (math.isfinite(self.length) and self.length > 0):
            raise ValueError(f"scenario length must be positive, not {self.length!r}")

    @property
    def end(self) -> float:
        """When the fault ends (s from the start of the run; infinite if it does not)."""
        return math.inf if self.length is None else self.start + self.length

    def active(self, time_ns: NDArray[np.int64]) -> NDArray[np.bool_]:
        """Which of the bag times fall while the fault is on."""
        seconds = (time_ns - START_NS) / SECOND
        on: NDArray[np.bool_] = (seconds >= self.start) & (seconds < self.end)
        return on


def _find(streams: list[Stream], topic: str, callerid: str | None = None) -> int:
    for index, stream in enumerate(streams):
        if stream.topic == topic and (callerid is None or stream.callerid == callerid):
            return index
    raise KeyError(topic)


def _tilted(
    values: NDArray[np.float64], roll: NDArray[np.float64], pitch: NDArray[np.float64]
) -> NDArray[np.float64]:
    """Poses whose orientation is turned by roll and pitch about the body's own axes."""
    x, y, z, q = values[:, 3], values[:, 4], values[:, 5], values[:, 6]
    cr, sr = np.cos(roll / 2), np.sin(roll / 2)
    cp, sp = np.cos(pitch / 2), np.sin(pitch / 2)
    tx, ty, tz, tw = sr * cp, cr * sp, -sr * sp, cr * cp  # roll then pitch, as a quaternion
    out: NDArray[np.float64] = values.copy()
    out[:, 3] = q * tx + x * tw + y * tz - z * ty
    out[:, 4] = q * ty - x * tz + y * tw + z * tx
    out[:, 5] = q * tz + x * ty - y * tx + z * tw
    out[:, 6] = q * tw - x * tx - y * ty - z * tz
    return out


def _slowed(scenario: Scenario, stream: Stream) -> Stream:
    on = scenario.active(stream.time_ns)
    since = (stream.time_ns - START_NS) / SECOND - scenario.start
    slow = on & (np.mod(since, 2 * SLOW_PERIOD) < SLOW_PERIOD)
    tick = np.floor(np.where(slow, since, 0.0) * SLOW_RATE).astype(np.int64)
    first = np.ones(len(stream), dtype=bool)
    first[1:] = (tick[1:] != tick[:-1]) | ~slow[:-1]
    return stream.select(~slow | first)


def _arch_changes(scenario: Scenario, arch: Stream, text: str) -> Stream:
    """The architecture records with the faulty graph from the next poll after the start."""
    times = [int(t) for t in arch.time_ns]
    texts = list(arch.texts)
    times.append(poll_time(scenario.start))
    texts.append(text)
    if math.isfinite(scenario.end):
        times.append(poll_time(scenario.end))
        texts.append(encode(arch_snapshot()))
    order = sorted(range(len(times)), key=lambda i: times[i])
    return replace(
        arch,
        time_ns=np.asarray([times[i] for i in order], dtype=np.int64),
        texts=tuple(texts[i] for i in order),
    )


def apply_scenario(scenario: Scenario, world: w.World, streams: list[Stream]) -> list[Stream]:
    """The streams of a run with the scenario's fault; the nominal streams are not changed."""
    out = list(streams)
    kind = scenario.kind
    if kind == "slowed":
        index = _find(out, "/a/car_pose", "/a/car")
        out[index] = _slowed(scenario, out[index])
    elif kind == "spoofed":
        index = _find(out, "/a/car_pose", "/a/car")
        stream = out[index]
        step = min(round(scenario.start / w.DT), world.time.size - 1)
        x, y = world.platform[step, 0], world.platform[step, 1]
        norm = math.hypot(x, y)
        dx, dy = (-x / norm, -y / norm) if norm > 0.1 else (1.0, 0.0)
        values = stream.values.copy()
        on = scenario.active(stream.time_ns)
        values[on, 0] += SPOOF_JUMP * dx
        values[on, 1] += SPOOF_JUMP * dy
        out[index] = replace(stream, values=values)
    elif kind == "stuck":
        index = _find(out, "/a/subject_status")
        stream = out[index]
        on = scenario.active(stream.time_ns)
        if on.any():
            first = int(np.argmax(on))
            values = stream.values.copy()
            values[on] = values[max(first - 1, 0)]
            out[index] = replace(stream, values=values)
    elif kind == "tilt":
        for topic in ("/vicon/car", "/a/car_pose"):
            index = _find(out, topic)
            stream = out[index]
            on = scenario.active(stream.time_ns)
            since = (stream.time_ns[on] - START_NS) / SECOND - scenario.start
            ramp = np.minimum(since / TILT_RAMP, 1.0)
            values = stream.values.copy()
            values[on] = _tilted(values[on], TILT[0] * ramp, TILT[1] * ramp)
            out[index] = replace(stream, values=values)
    elif kind == "extra_publisher":
        vicon = out[_find(out, "/vicon/car")]
        rows = np.flatnonzero(
            (np.arange(len(vicon)) % w.CTRL_PERIOD_STEPS == w.CTRL_PHASE_STEPS)
            & scenario.active(vicon.time_ns)
        )
        extra = Stream(
            "/a/car_pose",
            POSE_TYPE,
            EXTRA_PUBLISHER,
            vicon.time_ns[rows] + 800_000,
            vicon.values[rows],
            None if vicon.stamp_ns is None else vicon.stamp_ns[rows],
            np.arange(rows.size),
            frame_id=vicon.frame_id,
            best_effort=True,
        )
        out.insert(_find(out, "/a/car_pose") + 1, extra)
        index = _find(out, ARCH_TOPIC)
        edges = {"subscribes": ("/vicon/car",), "publishes": ("/a/car_pose",)}
        text = encode(arch_snapshot(extra={EXTRA_PUBLISHER: edges}))
        out[index] = _arch_changes(scenario, out[index], text)
    elif kind == "missing_subscriber":
        index = _find(out, ARCH_TOPIC)
        text = encode(arch_snapshot(drop=frozenset({MISSING_SUBSCRIBER})))
        out[index] = _arch_changes(scenario, out[index], text)
    else:  # out_of_order
        cmd_index = _find(out, "/a/cmd_subject_ctrl_state")
        way_index = _find(out, "/a/task_waypose")
        cmd, way = out[cmd_index], out[way_index]
        assert cmd.cycle is not None and way.cycle is not None and way.stamp_ns is not None
        rows = np.flatnonzero(scenario.active(cmd.time_ns))
        position = np.searchsorted(way.cycle, cmd.cycle[rows])
        inside = position < len(way)
        rows, position = rows[inside], position[inside]
        cmd_time, way_time = cmd.time_ns.copy(), way.time_ns.copy()
        way_stamp = way.stamp_ns.copy()
        cmd_time[rows], way_time[position] = way.time_ns[position], cmd.time_ns[rows]
        way_stamp[position] += way_time[position] - way.time_ns[position]
        out[cmd_index] = replace(cmd, time_ns=cmd_time)
        out[way_index] = replace(way, time_ns=way_time, stamp_ns=way_stamp)
    return out
