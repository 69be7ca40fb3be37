"""What a rosbag of the simulated run holds: the topics of Figure 3.6 and the records.

:func:`record` turns a :class:`~imrosc.sim.world.World` into :class:`Stream` s, one per topic
and publishing node, each message with its bag (receive) time, header stamp and sequence
number, with the Vicon noise of the world and the timing of real publishers: a phase per
node, a fraction of a millisecond of jitter, and a transport latency.

======================== ================================ ===== =========================
topic                    type                             rate  publisher
======================== ================================ ===== =========================
/vicon/car               geometry_msgs/TransformStamped   100   /vicon
/a/car_pose              geometry_msgs/PoseStamped        20    /a/car
/a/subject_pose          geometry_msgs/PoseStamped        50    /a/uav
/a/subject_status        sensor_msgs/BatteryState         10    /a/robot_monitor
/a/subject_ctrl_state    std_msgs/UInt8                   10    /a/ctrl_state_machine
/a/cmd_subject_ctrl_state std_msgs/UInt8                  5 +   /a/car_ctrl (and on change)
/a/task_waypose          geometry_msgs/PoseStamped        20    /a/car_ctrl
/imrosc/arch, /params    std_msgs/String                  once  /imrosc_record (on change)
/imrosc/srvs             std_msgs/String                  calls /imrosc_record
======================== ================================ ===== =========================

The controller publishes each state command just before the waypoint of the same cycle
(0.5 ms apart), which the ``out_of_order`` scenario swaps.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field, replace

import numpy as np
from numpy.typing import NDArray

from imrosc.records import (
    ARCH_TOPIC,
    PARAMS_TOPIC,
    RECORD_TYPE,
    SRVS_TOPIC,
    ArchSnapshot,
    ParamSnapshot,
    ServiceCall,
    TopicEnds,
    encode,
)
from imrosc.sim import world as w

__all__ = [
    "BATTERY_COLUMNS",
    "CELLS",
    "GRAPH",
    "POSE_TYPE",
    "RECORDER",
    "RECORD_PERIOD",
    "SECOND",
    "SERVICES",
    "START_NS",
    "STATE_TYPE",
    "STATUS_TYPE",
    "TOPICS",
    "TRANSFORM_TYPE",
    "Stream",
    "TopicSpec",
    "arch_snapshot",
    "clip",
    "parameters",
    "poll_time",
    "quaternions",
    "record",
]

SECOND = 1_000_000_000
START_NS = 1_379_178_100 * SECOND
"""Bag time of the start of every run (September 2013, when the thesis' bags were recorded)."""
RECORDER = "/imrosc_record"
"""The recording node that publishes the records."""
RECORD_PERIOD = 0.5
"""How often the recording node polls the master (s); a change is recorded at the next poll."""

POSE_TYPE = "geometry_msgs/msg/PoseStamped"
TRANSFORM_TYPE = "geometry_msgs/msg/TransformStamped"
STATUS_TYPE = "sensor_msgs/msg/BatteryState"
STATE_TYPE = "std_msgs/msg/UInt8"
WORLD_FRAME = "world"

BATTERY_COLUMNS = (
    "voltage",
    "temperature",
    "current",
    "charge",
    "capacity",
    "design_capacity",
    "percentage",
    "cell_voltage0",
    "cell_voltage1",
    "cell_voltage2",
    "cell_temperature0",
    "cell_temperature1",
    "cell_temperature2",
)
"""The numeric fields of /a/subject_status, in the order of a status stream's columns."""
CELLS = 3
CAPACITY = 2.1
"""The Hummingbird's 3-cell 2100 mAh LiPo (Ah)."""


@dataclass(frozen=True)
class TopicSpec:
    """One topic of Figure 3.6: its type, nominal rate (Hz, 0 when irregular) and publisher."""

    topic: str
    msgtype: str
    rate: float
    publisher: str
    best_effort: bool = False


TOPICS: tuple[TopicSpec, ...] = (
    TopicSpec("/vicon/car", TRANSFORM_TYPE, 100.0, "/vicon", best_effort=True),
    TopicSpec("/a/car_pose", POSE_TYPE, 20.0, "/a/car", best_effort=True),
    TopicSpec("/a/subject_pose", POSE_TYPE, 50.0, "/a/uav", best_effort=True),
    TopicSpec("/a/subject_status", STATUS_TYPE, 10.0, "/a/robot_monitor"),
    TopicSpec("/a/subject_ctrl_state", STATE_TYPE, 10.0, "/a/ctrl_state_machine"),
    TopicSpec("/a/cmd_subject_ctrl_state", STATE_TYPE, 5.0, "/a/car_ctrl"),
    TopicSpec("/a/task_waypose", POSE_TYPE, 20.0, "/a/car_ctrl"),
)
"""The robot's topics; the state command also goes out on every change, so a little over 5 Hz."""

GRAPH: Mapping[str, Mapping[str, tuple[str, ...]]] = {
    "/vicon": {"publishes": ("/vicon/car",)},
    "/a/car": {
        "subscribes": ("/vicon/car",),
        "publishes": ("/a/car_pose",),
        "serves": ("/a/execute_task",),
    },
    "/a/uav": {"publishes": ("/a/subject_pose",)},
    "/a/robot_monitor": {"publishes": ("/a/subject_status",)},
    "/a/ctrl_state_machine": {
        "subscribes": ("/a/cmd_subject_ctrl_state", "/a/subject_status"),
        "publishes": ("/a/subject_ctrl_state",),
    },
    "/a/car_ctrl": {
        "subscribes": ("/a/car_pose", "/a/subject_ctrl_state", "/a/subject_pose"),
        "publishes": ("/a/cmd_subject_ctrl_state", "/a/task_waypose"),
        "serves": ("/a/poll_status",),
    },
    "/a/launch_ctrl": {"subscribes": ("/a/subject_ctrl_state",)},
    "/a/ctrl_input_arb": {"subscribes": ("/a/subject_ctrl_state",)},
    "/a/pid_ctrl": {"subscribes": ("/a/task_waypose", "/a/subject_pose")},
}
"""The node graph of ``examples/uav_landing.graph.yaml`` (thesis Figure 3.6)."""
SERVICES = ("/a/execute_task", "/a/poll_status")
POLL_CLIENT = "/a/robot_monitor"


@dataclass(frozen=True)
class Stream:
    """The messages one node published on one topic, in time order.

    ``time_ns`` are the bag's receive times. Stamped types have ``stamp_ns`` and (ROS 1)
    ``seq``; ``values`` holds the numbers of each message: seven columns (position, quaternion
    x, y, z, w) for poses and transforms, one for ``UInt8``, :data:`BATTERY_COLUMNS` for the
    status. Records have ``texts`` instead. ``cycle`` is the controller cycle of each message
    the controller published.
    """

    topic: str
    msgtype: str
    callerid: str
    time_ns: NDArray[np.int64]
    values: NDArray[np.float64] = field(default_factory=lambda: np.zeros((0, 0)))
    stamp_ns: NDArray[np.int64] | None = None
    seq: NDArray[np.int64] | None = None
    texts: tuple[str, ...] = ()
    frame_id: str = ""
    child_frame_id: str | None = None
    cycle: NDArray[np.int64] | None = None
    latched: bool = False
    best_effort: bool = False

    def __len__(self) -> int:
        return int(self.time_ns.size)

    def select(self, keep: NDArray[np.bool_]) -> Stream:
        """The stream with only the messages where ``keep`` is true."""
        texts = tuple(text for text, kept in zip(self.texts, keep, strict=False) if kept)
        return replace(
            self,
            time_ns=self.time_ns[keep],
            values=self.values[keep] if self.values.size else self.values,
            stamp_ns=None if self.stamp_ns is None else self.stamp_ns[keep],
            seq=None if self.seq is None else self.seq[keep],
            texts=texts,
            cycle=None if self.cycle is None else self.cycle[keep],
        )


def quaternions(
    roll: NDArray[np.float64], pitch: NDArray[np.float64], yaw: NDArray[np.float64]
) -> NDArray[np.float64]:
    """Quaternions (x, y, z, w) of roll, pitch and yaw (the ZYX convention of ROS' tf)."""
    cr, sr = np.cos(roll / 2), np.sin(roll / 2)
    cp, sp = np.cos(pitch / 2), np.sin(pitch / 2)
    cy, sy = np.cos(yaw / 2), np.sin(yaw / 2)
    return np.stack(
        [
            sr * cp * cy - cr * sp * sy,
            cr * sp * cy + sr * cp * sy,
            cr * cp * sy - sr * sp * cy,
            cr * cp * cy + sr * sp * sy,
        ],
        axis=1,
    )


def _poses(states: NDArray[np.float64]) -> NDArray[np.float64]:
    """Seven pose columns from (N, 6) x, y, z, roll, pitch, yaw."""
    return np.hstack([states[:, 0:3], quaternions(states[:, 3], states[:, 4], states[:, 5])])


def _ns(seconds: NDArray[np.float64] | float) -> NDArray[np.int64]:
    """Bag times of times in seconds from the start of the run."""
    return START_NS + _span(seconds)


def _span(seconds: NDArray[np.float64] | float) -> NDArray[np.int64]:
    """Durations in seconds as nanoseconds."""
    return np.round(np.asarray(seconds, dtype=np.float64) * SECOND).astype(np.int64)


def arch_snapshot(
    *,
    drop: frozenset[str] = frozenset(),
    extra: Mapping[str, Mapping[str, tuple[str, ...]]] | None = None,
) -> ArchSnapshot:
    """The graph as the master reports it: :data:`GRAPH` without ``drop``, plus ``extra``."""
    nodes = {name: edges for name, edges in GRAPH.items() if name not in drop}
    nodes.update(extra or {})
    pubs: dict[str, set[str]] = {}
    subs: dict[str, set[str]] = {}
    servers: dict[str, set[str]] = {name: set() for name in SERVICES}
    for name, edges in nodes.items():
        for topic in edges.get("publishes", ()):
            pubs.setdefault(topic, set()).add(name)
            subs.setdefault(topic, set())
        for topic in edges.get("subscribes", ()):
            subs.setdefault(topic, set()).add(name)
            pubs.setdefault(topic, set())
        for service in edges.get("serves", ()):
            servers.setdefault(service, set()).add(name)
    topics = {t: TopicEnds(frozenset(pubs[t]), frozenset(subs[t])) for t in pubs}
    return ArchSnapshot(topics, {s: frozenset(n) for s, n in servers.items()})


def parameters() -> dict[str, object]:
    """The parameter server of the run, by global name."""
    return {
        "/a/car_ctrl/landing_radius": w.LANDING_RADIUS,
        "/a/car_ctrl/landing_time": w.LANDING_TIME,
        "/a/car_ctrl/poll_rate": 2.0,
        "/a/car_ctrl/hover_height": w.HOVER_Z,
        "/a/car_ctrl/approach_height": w.APPROACH,
        "/a/car_ctrl/land_speed": w.LAND_SPEED,
        "/a/car_ctrl/max_speed": w.MAX_SPEED,
        "/a/car/rate": 20,
        "/a/uav/rate": 50,
        "/vicon/rate": 100,
        "/vicon/frame_id": WORLD_FRAME,
        "/use_sim_time": False,
    }


def _jitter(rng: np.random.Generator, count: int, low: float, high: float) -> NDArray[np.float64]:
    return rng.uniform(low, high, count)


def _battery(
    world: w.World, at: NDArray[np.int64], rng: np.random.Generator
) -> NDArray[np.float64]:
    """The battery of the UAV sampled at grid steps ``at``: a 3S LiPo under hover load."""
    current = np.where(world.motors, 9.0, 0.4) + rng.normal(0, 0.15, world.time.size)
    used = np.cumsum(np.clip(current, 0, None)) * w.DT / 3600.0  # Ah
    charge = 0.95 * CAPACITY - used
    fraction = charge / CAPACITY
    open_circuit = CELLS * (3.6 + 0.55 * fraction)
    voltage = open_circuit - 0.03 * current
    temperature = 24.0 + 0.2 * np.cumsum(world.motors) * w.DT / 10.0
    count = at.size
    cells = voltage[at, None] / CELLS + rng.normal(0, 0.004, (count, CELLS))
    cell_temperature = temperature[at, None] + rng.normal(0, 0.05, (count, CELLS))
    return np.column_stack(
        [
            cells.sum(axis=1),
            temperature[at] + rng.normal(0, 0.05, count),
            -current[at],  # discharging: negative, as sensor_msgs/BatteryState says
            charge[at],
            np.full(count, CAPACITY),
            np.full(count, CAPACITY),
            np.clip(fraction[at], 0.0, 1.0),
            cells,
            cell_temperature,
        ]
    )


def _service_call(
    service: str,
    client: str,
    server: str,
    request: dict[str, object],
    response: dict[str, object],
    stamp: float,
    delay: float,
) -> str:
    call = ServiceCall(service, client, server, request, response, True, stamp, delay)
    return encode(call)


def record(world: w.World, seed: int) -> list[Stream]:
    """The streams of a nominal run of ``world`` (the seed drives the timing jitter)."""
    rng = np.random.default_rng(np.random.SeedSequence(seed).spawn(8)[7])
    steps = world.time.size
    streams: list[Stream] = []

    # /vicon/car: every Vicon frame, 3 ms of processing and transport
    platform = world.platform + world.platform_noise
    vicon_stamp = _ns(world.time)
    vicon_time = vicon_stamp + _span(3e-3 + _jitter(rng, steps, 0, 5e-4))
    vicon_values = _poses(platform)
    streams.append(
        Stream(
            "/vicon/car",
            TRANSFORM_TYPE,
            "/vicon",
            vicon_time,
            vicon_values,
            vicon_stamp,
            np.arange(steps),
            frame_id=WORLD_FRAME,
            child_frame_id="car",
            best_effort=True,
        )
    )

    # /a/car_pose: /a/car forwards every fifth Vicon frame of the platform
    car_rows = np.arange(0, steps, w.CTRL_PERIOD_STEPS)
    car_time = vicon_time[car_rows] + _span(6e-4 + _jitter(rng, car_rows.size, 0, 2e-4))
    streams.append(
        Stream(
            "/a/car_pose",
            POSE_TYPE,
            "/a/car",
            car_time,
            vicon_values[car_rows],
            vicon_stamp[car_rows],
            np.arange(car_rows.size),
            frame_id=WORLD_FRAME,
            best_effort=True,
        )
    )

    # /a/subject_pose: the UAV's Vicon pose, every other frame, relayed by /a/uav
    uav_rows = np.arange(0, steps, 2)
    uav_stamp = vicon_stamp[uav_rows]
    uav_time = uav_stamp + _span(3e-3 + _jitter(rng, uav_rows.size, 0, 5e-4))
    streams.append(
        Stream(
            "/a/subject_pose",
            POSE_TYPE,
            "/a/uav",
            uav_time,
            _poses((world.uav + world.uav_noise)[uav_rows]),
            uav_stamp,
            np.arange(uav_rows.size),
            frame_id=WORLD_FRAME,
            best_effort=True,
        )
    )

    # /a/subject_status: the battery at 10 Hz
    status_at = np.arange(0.07, world.duration, 0.1)
    status_pub = status_at + _jitter(rng, status_at.size, 0, 1e-3)
    status_rows = np.minimum((status_pub / w.DT).astype(np.int64), steps - 1)
    status_stamp = _ns(status_pub)
    streams.append(
        Stream(
            "/a/subject_status",
            STATUS_TYPE,
            "/a/robot_monitor",
            status_stamp + _span(2e-4 + _jitter(rng, status_at.size, 0, 1e-4)),
            _battery(world, status_rows, rng),
            status_stamp,
            np.arange(status_at.size),
            frame_id="hummingbird",
        )
    )

    # the controller: a state command (on change and at 5 Hz), then the waypoint
    cycles = world.cycle_step.size
    cycle_time = world.cycle_step * w.DT
    cmd_pub = cycle_time + 3e-4 + _jitter(rng, cycles, 0, 1e-4)
    way_pub = cycle_time + 9e-4 + _jitter(rng, cycles, 0, 1e-4)
    cmd_time = _ns(cmd_pub + 1.5e-4 + _jitter(rng, cycles, 0, 1e-4))
    way_time = _ns(way_pub + 1.5e-4 + _jitter(rng, cycles, 0, 1e-4))
    sent = np.flatnonzero(world.cmd)
    streams.append(
        Stream(
            "/a/cmd_subject_ctrl_state",
            STATE_TYPE,
            "/a/car_ctrl",
            cmd_time[sent],
            world.mode[sent, None].astype(np.float64),
            cycle=sent,
        )
    )
    wp = world.waypoint
    way_values = _poses(np.column_stack([wp[:, 0:3], np.zeros((cycles, 2)), wp[:, 3]]))
    streams.append(
        Stream(
            "/a/task_waypose",
            POSE_TYPE,
            "/a/car_ctrl",
            way_time,
            way_values,
            _ns(way_pub),
            np.arange(cycles),
            frame_id=WORLD_FRAME,
            cycle=np.arange(cycles),
        )
    )

    # /a/subject_ctrl_state: the state machine takes each command as it arrives
    state_pub = np.arange(0.03, world.duration, 0.1)
    state_pub = state_pub + _jitter(rng, state_pub.size, 0, 1e-3)
    latest = np.searchsorted(cmd_time[sent], _ns(state_pub), side="right") - 1
    state = np.where(latest >= 0, world.mode[sent][np.maximum(latest, 0)], w.STARTUP)
    streams.append(
        Stream(
            "/a/subject_ctrl_state",
            STATE_TYPE,
            "/a/ctrl_state_machine",
            _ns(state_pub + 2e-4 + _jitter(rng, state_pub.size, 0, 1e-4)),
            state[:, None].astype(np.float64),
        )
    )

    streams += _records(world, rng)
    return clip(streams, world)


def clip(streams: list[Stream], world: w.World) -> list[Stream]:
    """The streams without the messages after the end of the run."""
    end = START_NS + round(world.duration * SECOND)
    return [stream.select(stream.time_ns < end) for stream in streams]


def _records(world: w.World, rng: np.random.Generator) -> list[Stream]:
    """What the recording node publishes: the graph and the parameters at start, the calls."""
    start = np.array([START_NS + 500_000], dtype=np.int64)
    arch = Stream(
        ARCH_TOPIC, RECORD_TYPE, RECORDER, start, texts=(encode(arch_snapshot()),), latched=True
    )
    params = Stream(
        PARAMS_TOPIC,
        RECORD_TYPE,
        RECORDER,
        start + 100_000,
        texts=(encode(ParamSnapshot(parameters())),),
        latched=True,
    )
    calls: list[tuple[float, str]] = []
    for call in world.calls:
        text = _service_call(
            "/a/execute_task",
            "/a/car_ctrl",
            "/a/car",
            {"task_id": call.task_id},
            {"status": "ok"},
            (START_NS + round(call.time * SECOND)) / SECOND,
            call.delay,
        )
        calls.append((call.time + call.delay, text))
    poll_rate = float(parameters()["/a/car_ctrl/poll_rate"])  # type: ignore[arg-type]
    poll_times = np.arange(0.31, world.duration, 1.0 / poll_rate)
    poll_delays = 0.002 + rng.exponential(0.001, poll_times.size)
    poll_cycles = np.searchsorted(world.cycle_step * w.DT, poll_times, side="right") - 1
    for when, delay, cycle in zip(poll_times, poll_delays, poll_cycles, strict=True):
        state = int(world.mode[cycle]) if cycle >= 0 else w.STARTUP
        text = _service_call(
            "/a/poll_status",
            POLL_CLIENT,
            "/a/car_ctrl",
            {},
            {"state": state, "status": "ok"},
            (START_NS + round(float(when) * SECOND)) / SECOND,
            float(delay),
        )
        calls.append((float(when + delay), text))
    calls.sort()
    srvs = Stream(
        SRVS_TOPIC,
        RECORD_TYPE,
        RECORDER,
        _ns(np.array([t for t, _ in calls]) + 2e-4),
        texts=tuple(t for _, t in calls),
    )
    return [arch, params, srvs]


def poll_time(seconds: float) -> int:
    """The bag time of the first poll of the recording node at or after ``seconds``."""
    polls = math.ceil(round(seconds / RECORD_PERIOD, 9)) * RECORD_PERIOD
    return START_NS + round(polls * SECOND) + 500_000
