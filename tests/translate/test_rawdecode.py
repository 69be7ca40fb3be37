"""RawDecoder: columns from serialized chunks equal the Flattener's on deserialized messages."""

from __future__ import annotations

import functools
import time
from collections.abc import Callable, Sequence
from dataclasses import replace
from pathlib import Path
from typing import Any, Literal

import numpy as np
import numpy.typing as npt
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from rosbags.highlevel import AnyReader
from rosbags.interfaces import Nodetype
from rosbags.typesys import Stores, get_types_from_idl, get_types_from_msg, get_typestore
from rosbags.typesys.store import Typestore

from imrosc.msgtypes import FieldSpec, flatten
from imrosc.translate.columns import Flattener
from imrosc.translate.layout import TopicLayout, topic_layout
from imrosc.translate.rawdecode import RawDecoder

Serialization = Literal["ros1", "cdr"]
Columns = dict[str, npt.NDArray[Any]]
CRAZYFLIE = Path(__file__).resolve().parents[3] / "shared" / "data" / "real" / "crazyflie"

CUSTOM = {
    "imrosc_test/msg/Inner": """
int8 a
uint16 b
float32[3] f
string s
bool flag
""",
    "imrosc_test/msg/Fixed": """
uint8 a
float64 b
uint16 c
""",
    "imrosc_test/msg/Nest": """
uint8 k
imrosc_test/Fixed[2] two
""",
    "imrosc_test/msg/Everything": """
std_msgs/Header header
bool ok
byte by
char ch
int8 i8
uint8 u8
int16 i16
uint16 u16
int32 i32
uint32 u32
int64 i64
uint64 u64
float32 f32
float64 f64
string name
float64[] values
float32[] small
int32[2] pair
int64[] longs
uint64[12] wide
uint8[] blob
char[4] code
string[] names
string[2] pair_names
bool[] flags
imrosc_test/Inner inner
imrosc_test/Inner[2] inners
imrosc_test/Inner[] more
imrosc_test/Fixed[] fixed
imrosc_test/Fixed[3] fixed3
geometry_msgs/Point[] points
imrosc_test/Nest[] nests
time t
duration d
uint16 tail
""",
    "imrosc_test/msg/Odd": """
string s
imrosc_test/Fixed[2] two
float64 x
imrosc_test/Fixed[] more
string t
float32[] f
float64 y
""",
    "imrosc_test/msg/LogData": """
std_msgs/Header header
float64[] values
""",
}

TYPES = (
    "imrosc_test/msg/Everything",
    "imrosc_test/msg/LogData",
    "imrosc_test/msg/Inner",
    "imrosc_test/msg/Fixed",
    "sensor_msgs/msg/Imu",
    "geometry_msgs/msg/PoseStamped",
    "std_msgs/msg/Float64",
    "std_msgs/msg/String",
    "std_msgs/msg/Bool",
    "std_msgs/msg/Int8MultiArray",
    "sensor_msgs/msg/JointState",
    "sensor_msgs/msg/LaserScan",
    "sensor_msgs/msg/NavSatFix",
    "sensor_msgs/msg/Image",
    "sensor_msgs/msg/PointCloud",
    "geometry_msgs/msg/PolygonStamped",
    "diagnostic_msgs/msg/DiagnosticArray",
    "trajectory_msgs/msg/JointTrajectory",
)

TEXTS = ("", "base", "odom", "a", "ünï", "x" * 9, "map\x01")


@functools.cache
def store(serialization: Serialization) -> Typestore:
    typestore = get_typestore(Stores.ROS1_NOETIC if serialization == "ros1" else Stores.ROS2_HUMBLE)
    for name, text in CUSTOM.items():
        typestore.register(get_types_from_msg(text, name))
    return typestore


def serialize(serialization: Serialization, message: Any, msgtype: str) -> bytes:
    typestore = store(serialization)
    if serialization == "ros1":
        return bytes(typestore.serialize_ros1(message, msgtype))
    return bytes(typestore.serialize_cdr(message, msgtype))


def deserialize(serialization: Serialization, raw: bytes, msgtype: str) -> Any:
    typestore = store(serialization)
    if serialization == "ros1":
        return typestore.deserialize_ros1(raw, msgtype)
    return typestore.deserialize_cdr(raw, msgtype)


def observed(fields: tuple[FieldSpec, ...], first: Any) -> tuple[FieldSpec, ...]:
    """Numeric sequences get the length of the first message (as the catalog does)."""
    found = []
    for spec in fields:
        if (
            spec.array == "sequence"
            and "[]" not in spec.path
            and spec.type in ("float", "int", "uint")
        ):
            value = first
            for part in spec.path.split("."):
                value = getattr(value, part)
            found.append(replace(spec, length=len(value)))
        else:
            found.append(spec)
    return tuple(found)


def layout_of(
    serialization: Serialization, msgtype: str, first: Any | None, *, lengths: bool
) -> TopicLayout:
    fields = flatten(store(serialization), msgtype)
    if lengths and first is not None:
        fields = observed(fields, first)
    return topic_layout("/t", msgtype, fields, "t", trigger=True)


def assert_same(got: Columns | None, expected: Columns) -> None:
    assert got is not None
    assert got.keys() == expected.keys()
    for name, column in expected.items():
        mine = got[name]
        assert mine.dtype == column.dtype, name
        assert mine.shape == column.shape, name
        if column.dtype == object:
            assert mine.tolist() == column.tolist(), name
        else:  # bit for bit, NaN payloads and signed zeros included
            assert np.array_equal(mine.view(np.uint64), column.view(np.uint64)), (
                name,
                mine,
                column,
            )


def check(
    serialization: Serialization,
    msgtype: str,
    raws: Sequence[bytes],
    layout: TopicLayout | None = None,
    *,
    lengths: bool = True,
) -> Columns | None:
    """Decode ``raws``; compare with the Flattener when the decoder gives columns."""
    messages = [deserialize(serialization, raw, msgtype) for raw in raws]
    if layout is None:
        layout = layout_of(
            serialization, msgtype, messages[0] if messages else None, lengths=lengths
        )
    decoder = RawDecoder(store(serialization), msgtype, layout, serialization)
    got = decoder.decode(raws)
    if got is not None:
        assert_same(got, Flattener(layout)(messages))
    return got


# ---- random messages of any type, following its field definitions ----------------------------

INT_RANGES = {
    "byte": (-(2**7), 2**7 - 1),
    "char": (0, 2**8 - 1),
    "int8": (-(2**7), 2**7 - 1),
    "uint8": (0, 2**8 - 1),
    "int16": (-(2**15), 2**15 - 1),
    "uint16": (0, 2**16 - 1),
    "int32": (-(2**31), 2**31 - 1),
    "uint32": (0, 2**32 - 1),
    "int64": (-(2**63), 2**63 - 1),
    "uint64": (0, 2**64 - 1),
}
NUMPY_TYPES = {"bool": "bool_", "byte": "int8", "char": "uint8"}


def _ints(base: str) -> st.SearchStrategy[int]:
    low, high = INT_RANGES[base]
    edges = st.sampled_from([low, high, 0, high // 2 + 1, 2**53 + 1 if high > 2**53 else 1])
    return st.one_of(st.integers(low, high), edges)


def _primitive(base: str) -> st.SearchStrategy[Any]:
    if base == "bool":
        return st.booleans()
    if base == "float32":
        return st.floats(width=32)
    if base == "float64":
        return st.one_of(st.floats(), st.sampled_from([0.0, -0.0, np.nan, -np.inf, 1e-310]))
    return _ints(base)


class Maker:
    """Random messages whose lengths and strings come from small pools (so layouts repeat)."""

    def __init__(self, data: st.DataObject, serialization: Serialization) -> None:
        self.data = data
        self.store = store(serialization)
        pool = st.lists(st.integers(0, 3), min_size=1, max_size=2)
        self.counts: list[int] = data.draw(pool, label="sequence lengths")
        texts = st.lists(st.sampled_from(TEXTS), min_size=1, max_size=2)
        self.texts: list[str] = data.draw(texts, label="strings")

    def count(self) -> int:
        return self.data.draw(st.sampled_from(self.counts))

    def text(self) -> str:
        return self.data.draw(st.sampled_from(self.texts))

    def value(self, kind: int, detail: Any) -> Any:
        if kind == Nodetype.BASE:
            if detail[0] == "string":
                return self.text()
            return self.data.draw(_primitive(detail[0]))
        if kind == Nodetype.NAME:
            return self.message(detail)
        (element_kind, element_detail), length = detail
        size = length if kind == Nodetype.ARRAY else self.count()
        if element_kind == Nodetype.BASE and element_detail[0] != "string":
            base = element_detail[0]
            values = [self.data.draw(_primitive(base)) for _ in range(size)]
            return np.array(values, dtype=getattr(np, NUMPY_TYPES.get(base, base)))
        return [self.value(element_kind, element_detail) for _ in range(size)]

    def message(self, msgtype: str) -> Any:
        _, fields = self.store.fielddefs[msgtype]
        values = {name: self.value(kind, detail) for name, (kind, detail) in fields}
        return self.store.types[msgtype](**values)


@settings(max_examples=150, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(
    st.data(),
    st.sampled_from(["ros1", "cdr"]),
    st.sampled_from(TYPES),
    st.integers(1, 6),
    st.booleans(),
)
def test_random_messages_decode_as_the_flattener_flattens(
    data: st.DataObject, serialization: Serialization, msgtype: str, count: int, lengths: bool
) -> None:
    maker = Maker(data, serialization)
    raws = [serialize(serialization, maker.message(msgtype), msgtype) for _ in range(count)]
    got = check(serialization, msgtype, raws, lengths=lengths)
    assert got is not None  # every generated type is one the decoder supports


@pytest.mark.parametrize("serialization", ["ros1", "cdr"])
@pytest.mark.parametrize("msgtype", TYPES)
def test_every_type_is_supported(serialization: Serialization, msgtype: str) -> None:
    layout = layout_of(serialization, msgtype, None, lengths=False)
    decoder = RawDecoder(store(serialization), msgtype, layout, serialization)
    assert decoder.supported, decoder.reason


# ---- known chunks ---------------------------------------------------------------------------


def header(serialization: Serialization, index: int, frame: str) -> Any:
    types = store(serialization).types
    stamp = types["builtin_interfaces/msg/Time"](sec=index, nanosec=index * 1000)
    if serialization == "ros1":
        return types["std_msgs/msg/Header"](seq=index, stamp=stamp, frame_id=frame)
    return types["std_msgs/msg/Header"](stamp=stamp, frame_id=frame)


def imu(serialization: Serialization, index: int, frame: str, rng: np.random.Generator) -> Any:
    types = store(serialization).types
    vector, quat = types["geometry_msgs/msg/Vector3"], types["geometry_msgs/msg/Quaternion"]
    x = rng.normal(size=10)
    x[index % 10] = [np.nan, np.inf, -0.0, 0.0][index % 4]
    return types["sensor_msgs/msg/Imu"](
        header=header(serialization, index, frame),
        orientation=quat(x=x[0], y=x[1], z=x[2], w=x[3]),
        orientation_covariance=rng.normal(size=9),
        angular_velocity=vector(x=x[4], y=x[5], z=x[6]),
        angular_velocity_covariance=np.zeros(9),
        linear_acceleration=vector(x=x[7], y=x[8], z=x[9]),
        linear_acceleration_covariance=np.full(9, np.nan if index % 7 == 0 else 1.0),
    )


def pose(serialization: Serialization, index: int, frame: str, rng: np.random.Generator) -> Any:
    types = store(serialization).types
    x = rng.normal(size=7)
    return types["geometry_msgs/msg/PoseStamped"](
        header=header(serialization, index, frame),
        pose=types["geometry_msgs/msg/Pose"](
            position=types["geometry_msgs/msg/Point"](x=x[0], y=x[1], z=x[2]),
            orientation=types["geometry_msgs/msg/Quaternion"](x=x[3], y=x[4], z=x[5], w=x[6]),
        ),
    )


def volt(serialization: Serialization, index: int, frame: str, rng: np.random.Generator) -> Any:
    return store(serialization).types["std_msgs/msg/Float64"](data=float(rng.normal()))


def logdata(
    serialization: Serialization, index: int, frame: str, rng: np.random.Generator, width: int = 3
) -> Any:
    return store(serialization).types["imrosc_test/msg/LogData"](
        header=header(serialization, index, frame), values=rng.normal(size=width)
    )


Build = Callable[[Serialization, int, str, np.random.Generator], Any]
KNOWN: dict[str, Build] = {
    "sensor_msgs/msg/Imu": imu,
    "geometry_msgs/msg/PoseStamped": pose,
    "std_msgs/msg/Float64": volt,
    "imrosc_test/msg/LogData": logdata,
}


def chunk(
    serialization: Serialization, msgtype: str, frames: Sequence[str], rows: int
) -> list[bytes]:
    rng = np.random.default_rng(3)
    build = KNOWN[msgtype]
    return [
        serialize(serialization, build(serialization, i, frames[i % len(frames)], rng), msgtype)
        for i in range(rows)
    ]


@pytest.mark.parametrize("serialization", ["ros1", "cdr"])
@pytest.mark.parametrize("msgtype", list(KNOWN))
@pytest.mark.parametrize(
    "frames",
    [
        ("base_link",),
        ("base", "odom"),
        ("", "a", "map", "b"),
        tuple(f"frame{'_' * (i % 5)}{i}" for i in range(12)),  # more than a few distinct ids
    ],
)
def test_known_chunks(serialization: Serialization, msgtype: str, frames: tuple[str, ...]) -> None:
    raws = chunk(serialization, msgtype, frames, 300)
    assert check(serialization, msgtype, raws) is not None


@pytest.mark.parametrize("serialization", ["ros1", "cdr"])
def test_sequences_of_varying_length(serialization: Serialization) -> None:
    rng = np.random.default_rng(5)
    msgtype = "imrosc_test/msg/LogData"
    widths = [3, 3, 0, 5, 1, 3, 12, 0]
    raws = [
        serialize(serialization, logdata(serialization, i, "cf", rng, w), msgtype)
        for i, w in enumerate(widths)
    ]
    for lengths in (True, False):  # elements with NaN where short; statistics per message
        assert check(serialization, msgtype, raws, lengths=lengths) is not None
    layout = layout_of(
        serialization, msgtype, deserialize(serialization, raws[0], msgtype), lengths=True
    )
    short = [
        serialize(serialization, logdata(serialization, i, "cf", rng, 1), msgtype) for i in range(4)
    ]
    assert check(serialization, msgtype, short, layout) is not None  # elements past the end: NaN
    empty = [
        serialize(serialization, logdata(serialization, i, "cf", rng, 0), msgtype) for i in range(4)
    ]
    assert check(serialization, msgtype, empty, lengths=False) is not None


@pytest.mark.parametrize("serialization", ["ros1", "cdr"])
def test_offsets_that_differ_mod_8(serialization: Serialization) -> None:
    """CDR pads differently per message when strings before a float64 differ in length."""
    types = store(serialization).types
    fixed = types["imrosc_test/msg/Fixed"]
    rng = np.random.default_rng(9)

    def odd(index: int) -> Any:
        parts = [fixed(a=index % 256, b=float(v), c=index) for v in rng.normal(size=index % 3)]
        return types["imrosc_test/msg/Odd"](
            s="x" * (index % 5),
            two=[fixed(a=1, b=2.5, c=3), fixed(a=4, b=-0.0, c=6)],
            x=float(index),
            more=parts,
            t="y" * (index % 3),
            f=rng.normal(size=index % 4).astype(np.float32),
            y=-float(index),
        )

    msgtype = "imrosc_test/msg/Odd"
    raws = [serialize(serialization, odd(i), msgtype) for i in range(40)]
    assert check(serialization, msgtype, raws) is not None
    assert check(serialization, msgtype, raws[::5]) is not None  # same residues, other lengths


@pytest.mark.parametrize("serialization", ["ros1", "cdr"])
def test_one_long_message_among_short_ones(serialization: Serialization) -> None:
    types = store(serialization).types
    fixed = types["imrosc_test/msg/Fixed"](a=1, b=0.5, c=2)

    def odd(index: int, parts: int) -> Any:
        return types["imrosc_test/msg/Odd"](
            s="a" * (1 + 8 * (index % 2)),  # other lengths, same residue mod 8
            two=[fixed, fixed],
            x=float(index),
            more=[fixed] * parts,
            t="",
            f=np.ones(parts % 5, dtype=np.float32),
            y=1.0,
        )

    msgtype = "imrosc_test/msg/Odd"
    raws = [serialize(serialization, odd(i, w), msgtype) for i, w in enumerate([1, 2, 1, 3000, 0])]
    assert check(serialization, msgtype, raws) is not None


@pytest.mark.parametrize("serialization", ["ros1", "cdr"])
def test_empty_chunk(serialization: Serialization) -> None:
    msgtype = "imrosc_test/msg/Everything"
    layout = layout_of(serialization, msgtype, None, lengths=False)
    got = RawDecoder(store(serialization), msgtype, layout, serialization).decode([])
    assert_same(got, Flattener(layout)([]))


def test_memoryviews_are_raw_messages() -> None:
    raws = chunk("cdr", "sensor_msgs/msg/Imu", ("imu",), 20)
    layout = layout_of("cdr", "sensor_msgs/msg/Imu", None, lengths=False)
    decoder = RawDecoder(store("cdr"), "sensor_msgs/msg/Imu", layout, "cdr")
    assert_same(decoder.decode([memoryview(r) for r in raws]), decoder.decode(raws) or {})


# ---- what the decoder refuses -----------------------------------------------------------------


def test_malformed_chunks_fall_back() -> None:
    msgtype = "imrosc_test/msg/LogData"
    ros1 = chunk("ros1", msgtype, ("base",), 4)
    cdr = chunk("cdr", msgtype, ("base",), 4)
    ros1_decoder = RawDecoder(
        store("ros1"), msgtype, layout_of("ros1", msgtype, None, lengths=False), "ros1"
    )
    cdr_decoder = RawDecoder(
        store("cdr"), msgtype, layout_of("cdr", msgtype, None, lengths=False), "cdr"
    )
    assert ros1_decoder.decode(ros1) is not None and cdr_decoder.decode(cdr) is not None
    assert ros1_decoder.decode([*ros1[:3], ros1[3][:-1]]) is None  # truncated
    assert ros1_decoder.decode([*ros1[:3], ros1[3] + b"\0"]) is None  # trailing byte
    assert cdr_decoder.decode([*cdr[:3], cdr[3] + b"\0" * 8]) is None  # too much padding
    assert cdr_decoder.decode([cdr[0][:2]]) is None  # no room for the header
    big = store("cdr").serialize_cdr(
        logdata("cdr", 0, "b", np.random.default_rng()), msgtype, little_endian=False
    )
    assert cdr_decoder.decode([bytes(big)]) is None  # big-endian CDR
    bad_text = ros1[0].replace(b"base", b"b\xffse")
    assert ros1_decoder.decode([bad_text]) is None  # not UTF-8: rosbags raises
    unterminated = cdr[0].replace(b"base\0", b"basex")
    assert cdr_decoder.decode([unterminated]) is None  # CDR string without its NUL
    huge = bytearray(ros1[0])
    huge[-28:-24] = (10**6).to_bytes(4, "little")  # the values count
    assert ros1_decoder.decode([bytes(huge)]) is None


def test_layout_of_another_type_is_unsupported() -> None:
    layout = layout_of("ros1", "sensor_msgs/msg/Imu", None, lengths=False)
    decoder = RawDecoder(store("ros1"), "std_msgs/msg/Float64", layout, "ros1")
    assert not decoder.supported and decoder.decode([b"\0" * 8]) is None


def test_wstring_is_unsupported() -> None:
    typestore = get_typestore(Stores.ROS2_HUMBLE)
    idl = "module imrosc_test { module msg { struct Wide { wstring w; double x; }; }; };"
    typestore.register(get_types_from_idl(idl))
    msgtype = "imrosc_test/msg/Wide"
    layout = topic_layout("/w", msgtype, flatten(typestore, msgtype), "w", trigger=True)
    decoder = RawDecoder(typestore, msgtype, layout, "cdr")
    assert not decoder.supported and decoder.decode([b"\0\1\0\0" + b"\0" * 16]) is None


# ---- a real bag ---------------------------------------------------------------------------------


@pytest.mark.skipif(not (CRAZYFLIE / "sine_1.bag").exists(), reason="crazyflie bag not available")
def test_crazyflie_bag_topics() -> None:
    with AnyReader([CRAZYFLIE / "sine_1.bag"]) as reader:
        for connection in reader.connections:
            raws = [bytes(raw) for _, _, raw in reader.messages(connections=[connection])]
            messages = [reader.deserialize(raw, connection.msgtype) for raw in raws]
            fields = observed(flatten(reader.typestore, connection.msgtype), messages[0])
            layout = topic_layout(connection.topic, connection.msgtype, fields, "cf", trigger=True)
            decoder = RawDecoder(reader.typestore, connection.msgtype, layout, "ros1")
            for start in range(0, len(raws), 500):
                got = decoder.decode(raws[start : start + 500])
                assert got is not None, connection.topic
                assert_same(got, Flattener(layout)(messages[start : start + 500]))


def test_imu_rate() -> None:
    """Not a limit: prints msgs/s for a 16k chunk of sensor_msgs/Imu (``pytest -s``)."""
    base = chunk("ros1", "sensor_msgs/msg/Imu", ("base_link",), 256)
    raws = base * 64
    layout = layout_of("ros1", "sensor_msgs/msg/Imu", None, lengths=False)
    decoder = RawDecoder(store("ros1"), "sensor_msgs/msg/Imu", layout, "ros1")
    best = float("inf")
    for _ in range(3):
        started = time.perf_counter()
        assert decoder.decode(raws) is not None
        best = min(best, time.perf_counter() - started)
    print(f"RawDecoder sensor_msgs/Imu (ROS 1): {len(raws) / best:,.0f} msgs/s")
