"""Writing simulated runs as bags: ROS 1 ``.bag`` files and ROS 2 sqlite3 or MCAP bags.

:func:`simulate` runs the world, records it and applies a scenario; :func:`write_run` writes
one run with rosbags' writers, every message in time order: ROS 1 with one connection per topic,
type and publishing node (its ``callerid``), the records latched; ROS 2 with one connection per
topic and type, sensor topics offered best effort, the records transient local. The same seed
gives the same bytes in every format.
"""

from __future__ import annotations

import functools
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Literal, get_args

import numpy as np
from rosbags.interfaces import (
    Connection,
    Qos,
    QosDurability,
    QosHistory,
    QosLiveliness,
    QosReliability,
    QosTime,
)
from rosbags.rosbag1 import Writer as Ros1Writer
from rosbags.rosbag2 import StoragePlugin
from rosbags.rosbag2 import Writer as Ros2Writer
from rosbags.typesys import Stores, get_typestore
from rosbags.typesys.store import Typestore

from imrosc.records import RECORD_TYPE
from imrosc.sim.encode import pose_layout, serialize_rows, stamp_columns, uint8_layout
from imrosc.sim.recording import (
    CELLS,
    POSE_TYPE,
    STATE_TYPE,
    STATUS_TYPE,
    TRANSFORM_TYPE,
    Stream,
    clip,
    record,
)
from imrosc.sim.scenarios import Scenario, apply_scenario
from imrosc.sim.world import World, simulate_world

__all__ = ["FORMATS", "BagFormat", "Run", "simulate", "write_run", "write_runs"]

BagFormat = Literal["ros1", "sqlite3", "mcap"]
FORMATS: tuple[BagFormat, ...] = get_args(BagFormat)

DISCHARGING, HEALTH_GOOD, LIPO = 2, 1, 3
"""sensor_msgs/BatteryState's POWER_SUPPLY_STATUS_DISCHARGING, _HEALTH_GOOD, _TECHNOLOGY_LIPO."""
_INFINITE = QosTime(9223372036, 854775807)
"""What ROS 2 writes for an unset deadline, lifespan or lease."""


@dataclass(frozen=True)
class Run:
    """One simulated run: the world, the streams a bag of it holds, and its scenario."""

    seed: int
    world: World
    streams: tuple[Stream, ...]
    scenario: Scenario | None

    def stream(self, topic: str, callerid: str | None = None) -> Stream:
        """The stream of a topic (published by ``callerid``, when given)."""
        for stream in self.streams:
            if stream.topic == topic and callerid in (None, stream.callerid):
                return stream
        raise KeyError(topic)


def simulate(seed: int, *, duration: float = 30.0, scenario: Scenario | None = None) -> Run:
    """Simulate and record one run: the same arguments give the same run."""
    world = simulate_world(seed, duration)
    streams = record(world, seed)
    if scenario is not None:
        streams = clip(apply_scenario(scenario, world, streams), world)
    return Run(seed, world, tuple(streams), scenario)


@functools.cache
def _typestore(ros1: bool) -> Typestore:
    return get_typestore(Stores.ROS1_NOETIC if ros1 else Stores.ROS2_HUMBLE)


def _battery(store: Typestore, stream: Stream, ros1: bool) -> list[bytes]:
    types = store.types
    header_type, time_type = types["std_msgs/msg/Header"], types["builtin_interfaces/msg/Time"]
    status_type = types[STATUS_TYPE]
    assert stream.stamp_ns is not None and stream.seq is not None
    payloads = []
    values = stream.values
    cells = values[:, 7 : 7 + CELLS].astype(np.float32)
    temperatures = values[:, 7 + CELLS : 7 + 2 * CELLS].astype(np.float32)
    serialize = store.serialize_ros1 if ros1 else store.serialize_cdr
    for row in range(len(stream)):
        stamp = int(stream.stamp_ns[row])
        time = time_type(sec=stamp // 1_000_000_000, nanosec=stamp % 1_000_000_000)
        if ros1:
            header = header_type(seq=int(stream.seq[row]), stamp=time, frame_id=stream.frame_id)
        else:
            header = header_type(stamp=time, frame_id=stream.frame_id)
        voltage, temperature, current, charge, capacity, design, percentage = (
            float(v) for v in values[row, :7]
        )
        message = status_type(
            header=header,
            voltage=voltage,
            temperature=temperature,
            current=current,
            charge=charge,
            capacity=capacity,
            design_capacity=design,
            percentage=percentage,
            power_supply_status=DISCHARGING,
            power_supply_health=HEALTH_GOOD,
            power_supply_technology=LIPO,
            present=True,
            cell_voltage=cells[row],
            cell_temperature=temperatures[row],
            location="hummingbird",
            serial_number="",
        )
        payloads.append(bytes(serialize(message, STATUS_TYPE)))
    return payloads


def _payloads(stream: Stream, ros1: bool) -> list[bytes]:
    """The serialized messages of a stream."""
    store = _typestore(ros1)
    if stream.msgtype in (POSE_TYPE, TRANSFORM_TYPE):
        assert stream.stamp_ns is not None and stream.seq is not None
        child = stream.child_frame_id if stream.msgtype == TRANSFORM_TYPE else None
        layout = pose_layout(not ros1, stream.frame_id, child)
        columns = stamp_columns(stream.stamp_ns)
        columns["seq"] = stream.seq
        columns["values"] = stream.values
        return serialize_rows(layout, columns, len(stream))
    if stream.msgtype == STATE_TYPE:
        data = np.round(stream.values[:, 0]).astype(np.uint8)
        return serialize_rows(uint8_layout(not ros1), {"data": data}, len(stream))
    if stream.msgtype == STATUS_TYPE:
        return _battery(store, stream, ros1)
    if stream.msgtype == RECORD_TYPE:
        string = store.types[RECORD_TYPE]
        serialize = store.serialize_ros1 if ros1 else store.serialize_cdr
        return [bytes(serialize(string(data=text), RECORD_TYPE)) for text in stream.texts]
    raise ValueError(f"no serializer for {stream.msgtype}")


def _qos(stream: Stream) -> Qos:
    if stream.latched:
        reliability, durability, depth = QosReliability.RELIABLE, QosDurability.TRANSIENT_LOCAL, 1
    elif stream.best_effort:
        reliability, durability, depth = QosReliability.BEST_EFFORT, QosDurability.VOLATILE, 5
    else:
        reliability, durability, depth = QosReliability.RELIABLE, QosDurability.VOLATILE, 10
    return Qos(
        QosHistory.KEEP_LAST,
        depth,
        reliability,
        durability,
        _INFINITE,
        _INFINITE,
        QosLiveliness.AUTOMATIC,
        _INFINITE,
        False,
    )


def _order(streams: Sequence[Stream]) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Every message as (time, stream, row), sorted by time, then stream, then row."""
    times = np.concatenate([s.time_ns for s in streams])
    which = np.concatenate([np.full(len(s), i, dtype=np.int64) for i, s in enumerate(streams)])
    rows = np.concatenate([np.arange(len(s), dtype=np.int64) for s in streams])
    order = np.lexsort((rows, which, times))
    return times[order], which[order], rows[order]


def write_run(
    path: Path | str,
    *,
    seed: int,
    fmt: BagFormat,
    duration: float = 30.0,
    scenario: Scenario | None = None,
) -> Path:
    """Simulate one run and write it as a bag at ``path``; the path is returned.

    ``fmt`` ``"ros1"`` writes a ``.bag`` file, ``"sqlite3"`` and ``"mcap"`` a ROS 2 bag
    directory (whose name must end in ``.bag`` for ROS 1). An existing ``path`` is an error:
    bags are not overwritten.
    """
    if fmt not in FORMATS:
        raise ValueError(f"unknown bag format {fmt!r}; expected one of {', '.join(FORMATS)}")
    target = Path(path)
    if fmt == "ros1" and target.suffix != ".bag":
        raise ValueError(f"{target}: a ROS 1 bag's name must end in .bag")
    if target.exists():
        raise FileExistsError(f"{target}: already exists; imrosc does not overwrite bags")
    target.parent.mkdir(parents=True, exist_ok=True)
    run = simulate(seed, duration=duration, scenario=scenario)
    streams = [s for s in run.streams if len(s)]
    ros1 = fmt == "ros1"
    payloads = [_payloads(stream, ros1) for stream in streams]
    times, which, rows = _order(streams)
    store = _typestore(ros1)
    if ros1:
        writer1 = Ros1Writer(target)
        keys1: dict[tuple[str, str, str], Connection] = {}
        with writer1:
            connections = []
            for stream in streams:
                key = (stream.topic, stream.msgtype, stream.callerid)
                if key not in keys1:
                    keys1[key] = writer1.add_connection(
                        stream.topic,
                        stream.msgtype,
                        typestore=store,
                        callerid=stream.callerid,
                        latching=1 if stream.latched else None,
                    )
                connections.append(keys1[key])
            for time, index, row in zip(times.tolist(), which.tolist(), rows.tolist(), strict=True):
                writer1.write(connections[index], time, payloads[index][row])
        return target
    plugin = StoragePlugin.SQLITE3 if fmt == "sqlite3" else StoragePlugin.MCAP
    keys2: dict[tuple[str, str], Connection] = {}
    with Ros2Writer(target, version=9, storage_plugin=plugin) as writer2:
        connections = []
        for stream in streams:
            key2 = (stream.topic, stream.msgtype)
            if key2 not in keys2:
                keys2[key2] = writer2.add_connection(
                    stream.topic,
                    stream.msgtype,
                    typestore=store,
                    offered_qos_profiles=[_qos(stream)],
                )
            connections.append(keys2[key2])
        for time, index, row in zip(times.tolist(), which.tolist(), rows.tolist(), strict=True):
            writer2.write(connections[index], time, payloads[index][row])
    return target


def write_runs(
    folder: Path | str,
    *,
    runs: int,
    seed: int,
    fmt: BagFormat,
    duration: float = 30.0,
    scenario: Scenario | None = None,
) -> list[Path]:
    """Write ``runs`` runs into ``folder``: run ``i`` has seed ``seed + i``.

    The bags are named after the scenario (``nominal`` without one) and the run number:
    ``nominal_000.bag`` in ROS 1, ``slowed_002/`` as a ROS 2 bag.
    """
    if runs < 0:
        raise ValueError(f"runs must not be negative, not {runs!r}")
    directory = Path(folder)
    directory.mkdir(parents=True, exist_ok=True)
    label = "nominal" if scenario is None else scenario.kind
    suffix = ".bag" if fmt == "ros1" else ""
    return [
        write_run(
            directory / f"{label}_{index:03d}{suffix}",
            seed=seed + index,
            fmt=fmt,
            duration=duration,
            scenario=scenario,
        )
        for index in range(runs)
    ]
