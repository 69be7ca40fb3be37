"""The runtime's per-message flattener against the translator's columnar one."""

from __future__ import annotations

import dataclasses
import math
import operator
from collections.abc import Iterator, Sequence
from pathlib import Path
from types import SimpleNamespace as M
from typing import Any

import numpy as np
import pytest
from rosbags.typesys import Stores, get_typestore

from imrosc.bags import open_bag
from imrosc.msgtypes import FieldSpec, flatten
from imrosc.runtime.flatten import make_flattener
from imrosc.sim import write_run
from imrosc.translate.catalog import build_catalog
from imrosc.translate.columns import Flattener
from imrosc.translate.layout import TopicLayout, topic_layout

EPS = 2.0**-52
STORE = get_typestore(Stores.ROS1_NOETIC)


def as_json(layout: TopicLayout) -> list[dict[str, Any]]:
    """The topic's variables as the invariants file lists them."""
    return [
        {"name": v.name, "path": v.path, "type": v.type, "derived": v.derived}
        for v in layout.variables
    ]


def same(a: float, b: float) -> bool:
    """Equal bit for bit (any NaN equals any NaN)."""
    if math.isnan(a) or math.isnan(b):
        return math.isnan(a) and math.isnan(b)
    return a == b and math.copysign(1.0, a) == math.copysign(1.0, b)


def compare(layout: TopicLayout, messages: Sequence[Any]) -> int:
    """Assert the two flatteners agree on every message; the values compared."""
    with np.errstate(invalid="ignore"):  # the deviation of an array holding inf is NaN
        columns = Flattener(layout)(messages)
        flat = make_flattener(as_json(layout))
        rows = [flat(m) for m in messages]
    compared = 0
    for j, variable in enumerate(layout.variables):
        expected = columns[variable.name]
        for k, message in enumerate(messages):
            got = rows[k][j]
            want = expected[k]
            if variable.type == "string":
                assert got == want, (variable.name, k)
            elif variable.derived in ("avg", "std") and math.isfinite(want):
                # the summation order may differ: a few ulps of the elements' magnitude
                array = np.asarray(operator.attrgetter(variable.path)(message), np.float64)
                scale = float(np.abs(array).max())
                assert abs(got - want) <= 8 * EPS * scale, (variable.name, k, got, want)
            else:
                assert isinstance(got, float)
                assert same(got, float(want)), (variable.name, k, got, want)
            compared += 1
    return compared


def without_lengths(fields: Sequence[FieldSpec]) -> tuple[FieldSpec, ...]:
    """The fields as if their sequences had no observed length (statistics, not elements)."""
    return tuple(
        dataclasses.replace(f, length=None) if f.array == "sequence" else f for f in fields
    )


@pytest.fixture(scope="module")
def simulated(tmp_path_factory: pytest.TempPathFactory) -> Path:
    folder = tmp_path_factory.mktemp("sim")
    return write_run(folder / "nominal.bag", seed=3, fmt="ros1", duration=3.0)


def messages_of(bag: Path, topic: str) -> Iterator[Any]:
    with open_bag(bag) as reader:
        wanted = [c for c in reader.connections if c.topic == topic]
        for connection, _, raw in reader.messages(connections=wanted):
            yield reader.deserialize(raw, connection.msgtype)


def test_simulated_bag_messages(simulated: Path) -> None:
    catalog = build_catalog([simulated])
    assert len(catalog.types) >= 5
    compared = 0
    for topic, (msgtype, fields) in sorted(catalog.types.items()):
        messages = list(messages_of(simulated, topic))
        assert messages, topic
        short = topic.rsplit("/", 1)[-1]
        for specs in (fields, without_lengths(fields)):
            layout = topic_layout(topic, msgtype, specs, short, trigger=True)
            compared += compare(layout, messages)
    assert compared > 5000


def test_simulated_battery_status_has_every_kind_of_variable(simulated: Path) -> None:
    catalog = build_catalog([simulated])
    msgtype, fields = catalog.types["/a/subject_status"]
    layout = topic_layout("/a/subject_status", msgtype, without_lengths(fields), "s", trigger=True)
    types = {(v.type, v.derived) for v in layout.variables}
    assert {("float", None), ("uint", None), ("bool", None), ("string", None)} <= types
    assert {("float", "avg"), ("float", "std"), ("uint", "len")} <= types


def roundtrip(msgtype: str, **fields: Any) -> Any:
    """A message built with rosbags' typestore, serialized and read back as a bag gives it."""
    header = STORE.types["std_msgs/msg/Header"](
        seq=7, stamp=STORE.types["builtin_interfaces/msg/Time"](sec=1, nanosec=5), frame_id="f"
    )
    if "header" in dict(STORE.fielddefs[msgtype][1]):
        fields["header"] = header
    message = STORE.types[msgtype](**fields)
    return STORE.deserialize_ros1(STORE.serialize_ros1(message, msgtype), msgtype)


def layout_of(msgtype: str, lengths: dict[str, int] | None = None) -> TopicLayout:
    fields = tuple(
        dataclasses.replace(f, length=(lengths or {}).get(f.path, f.length))
        for f in flatten(STORE, msgtype)
    )
    return topic_layout("/t", msgtype, fields, "t", trigger=True)


def test_laser_scans_of_every_length() -> None:
    rng = np.random.default_rng(1)
    scans = []
    for size in (0, 1, 2, 7, 8, 9, 100, 1000, 5):
        ranges = rng.uniform(0.1, 30.0, size).astype(np.float32)
        if size > 4:
            ranges[rng.integers(0, size, 2)] = [np.inf, np.nan][: 1 + size % 2]
        scans.append(
            roundtrip(
                "sensor_msgs/msg/LaserScan",
                angle_min=-1.5,
                angle_max=1.5,
                angle_increment=0.01,
                time_increment=0.0,
                scan_time=0.1,
                range_min=0.1,
                range_max=30.0,
                ranges=ranges,
                intensities=rng.uniform(0, 1e4, size).astype(np.float32),
            )
        )
    layout = layout_of("sensor_msgs/msg/LaserScan")
    assert "avg(t.ranges)" in {v.name for v in layout.variables}
    assert compare(layout, scans) > 100
    # one length for all (the translator's matrix path) and varying lengths alike
    assert compare(layout, scans[6:7] * 3)
    assert compare(layout, [s for s in scans if len(s.ranges) == 0])


def test_fixed_arrays_and_short_sequences() -> None:
    rng = np.random.default_rng(2)
    imus, arrays = [], []
    for k in range(6):
        imus.append(
            roundtrip(
                "sensor_msgs/msg/Imu",
                orientation=STORE.types["geometry_msgs/msg/Quaternion"](x=0, y=0, z=0, w=1),
                orientation_covariance=rng.normal(0, 1e-3, 9),
                angular_velocity=STORE.types["geometry_msgs/msg/Vector3"](x=k, y=-k, z=0.5),
                angular_velocity_covariance=np.full(9, 0.1),
                linear_acceleration=STORE.types["geometry_msgs/msg/Vector3"](x=0, y=0, z=9.81),
                linear_acceleration_covariance=np.zeros(9),
            )
        )
        multi = STORE.types["std_msgs/msg/MultiArrayLayout"](dim=[], data_offset=0)
        data = rng.normal(0, 1e6, (1, 3, 5, 0, 3, 4)[k])
        arrays.append(roundtrip("std_msgs/msg/Float64MultiArray", layout=multi, data=data))
    assert compare(layout_of("sensor_msgs/msg/Imu"), imus) > 50
    # a sequence first seen with 3 elements gives 3 element variables: shorter messages lack
    # some (NaN), longer ones have more than are kept
    short = layout_of("std_msgs/msg/Float64MultiArray", {"data": 3})
    assert [v.name for v in short.variables][-4:] == [
        "t.data[0]",
        "t.data[1]",
        "t.data[2]",
        "len(t.data)",
    ]
    assert compare(short, arrays)
    assert compare(short, [arrays[1], arrays[4]])  # one length: the matrix path
    assert compare(layout_of("std_msgs/msg/Float64MultiArray"), arrays)


def test_images_bytes_and_strings() -> None:
    images = [
        roundtrip(
            "sensor_msgs/msg/Image",
            height=2,
            width=size,
            encoding=encoding,
            is_bigendian=0,
            step=size,
            data=np.arange(2 * size, dtype=np.uint8),
        )
        for size, encoding in ((3, "mono8"), (0, ""), (5, "rgb8"))
    ]
    layout = layout_of("sensor_msgs/msg/Image")
    assert {"len(t.data)", "t.encoding"} <= {v.name for v in layout.variables}
    assert compare(layout, images)


PLAIN_FIELDS = (
    FieldSpec("x", "float"),
    FieldSpec("count", "uint"),
    FieldSpec("flag", "bool"),
    FieldSpec("name", "string"),
    FieldSpec("pose.position.x", "float"),
    FieldSpec("ranges", "float", "sequence"),
    FieldSpec("data", "bytes", "sequence"),
    FieldSpec("values", "float", "fixed", 3),
    FieldSpec("names", "string", "sequence"),
)


def plain(x: float, ranges: tuple[float, ...], data: bytes, values: tuple[float, ...]) -> M:
    """A message as rospy gives it: tuples for arrays, ``bytes`` for ``uint8[]``."""
    return M(
        x=x,
        count=3,
        flag=True,
        name="base",
        pose=M(position=M(x=-x)),
        ranges=ranges,
        data=data,
        values=values,
        names=("a", "b"),
    )


def test_plain_objects_with_tuples_and_bytes() -> None:
    layout = topic_layout("/t", "T", PLAIN_FIELDS, "t", trigger=True)
    messages = [
        plain(1.5, (1.0, 2.0, 4.0, 5.0), b"\x01\x02\x03", (1.0, 2.0, 3.0)),
        plain(2.5, (), b"", (4.0, 5.0, 6.0)),
        plain(-1.0, (0.5,), b"\xff", (7.0, 8.0, 9.0)),
    ]
    assert compare(layout, messages)
    flat = make_flattener(as_json(layout))
    got = dict(zip([v.name for v in layout.variables], flat(messages[0]), strict=True))
    assert got == {
        "t.x": 1.5,
        "t.count": 3.0,
        "t.flag": 1.0,
        "t.name": "base",
        "t.pose.position.x": -1.5,
        "len(t.ranges)": 4.0,
        "avg(t.ranges)": 3.0,
        "std(t.ranges)": math.sqrt(2.5),
        "min(t.ranges)": 1.0,
        "max(t.ranges)": 5.0,
        "len(t.data)": 3.0,
        "t.values[0]": 1.0,
        "t.values[1]": 2.0,
        "t.values[2]": 3.0,
        "len(t.values)": 3.0,
        "len(t.names)": 2.0,
    }
    empty = dict(zip(got, flat(messages[1]), strict=True))
    assert empty["len(t.ranges)"] == 0.0
    assert all(math.isnan(empty[f"{s}(t.ranges)"]) for s in ("avg", "std", "min", "max"))


def test_missing_fields_and_values_that_are_no_numbers() -> None:
    flat = make_flattener(
        [
            {"name": "x", "path": "x", "type": "float", "derived": None},
            {"name": "s", "path": "s", "type": "string", "derived": None},
            {"name": "deep", "path": "a.b", "type": "float", "derived": None},
            {"name": "v[4]", "path": "v[4]", "type": "float", "derived": None},
            {"name": "avg(v)", "path": "v", "type": "float", "derived": "avg"},
            {"name": "avg(w)", "path": "w", "type": "float", "derived": "avg"},
            {"name": "len(w)", "path": "w", "type": "uint", "derived": "len"},
        ]
    )
    values = flat(M(x="fast", v=[1.0, 2.0], w=["a", "b"], a=M()))
    assert values[1] == ""  # no field s
    assert [math.isnan(values[k]) for k in (0, 2, 3, 5)] == [True] * 4
    assert (values[4], values[6]) == (1.5, 2.0)
    values = flat(M(x=None, s=5, a=M(b=2), v=(0.0,) * 5, w=()))
    assert math.isnan(values[0])
    assert values[1:5] == ["5", 2.0, 0.0, 0.0]
    assert math.isnan(values[5])  # an empty array has no average
    assert values[6] == 0.0
