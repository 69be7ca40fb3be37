"""The ROS 2 monitor's CDR reader (``imrosc/onboard/monitor_ros2/cdr.py``) against rclpy: on random
messages of several types, serialised by rclpy, the reader gives what the generated
flattener's expressions give on the message, for every layout the plan covers, and a plan
exists for each of them.

Runs where ``tests/backends/ros2_support.py`` finds rclpy (``make test`` and so CI: marked
``live``, required under ``IMROSC_REQUIRE_ROS2=1``).
"""

from __future__ import annotations

import json
import subprocess
from pathlib import Path

import pytest

from imrosc.backends.monitor import flat_expression
from tests.backends.ros2_support import require_ros2, ros2_environment

pytestmark = pytest.mark.live

ROOT = Path(__file__).resolve().parents[2]
LAYOUTS: dict[str, list[tuple[str, str, str | None]]] = {
    "sensor_msgs/msg/JointState": [(f"position[{i}]", "float", None) for i in range(56)]
    + [
        ("header.frame_id", "string", None),
        ("header.stamp.sec", "float", None),
        ("effort", "float", "avg"),
        ("velocity[1]", "float", None),
        ("position", "float", "len"),
    ],
    "sensor_msgs/msg/Imu": [
        ("orientation.w", "float", None),
        ("angular_velocity_covariance[4]", "float", None),
        ("linear_acceleration_covariance", "float", "max"),
        ("header.frame_id", "string", None),
    ],
    "sensor_msgs/msg/NavSatFix": [
        ("status.status", "float", None),
        ("status.service", "float", None),
        ("latitude", "float", None),
        ("position_covariance_type", "float", None),
        ("position_covariance[8]", "float", None),
    ],
    "std_msgs/msg/Float32MultiArray": [
        ("layout.data_offset", "float", None),
        ("data[1]", "float", None),
        ("data", "float", "std"),
        ("data", "float", "min"),
    ],
    "std_msgs/msg/UInt8MultiArray": [
        ("data", "float", "len"),
        ("data[3]", "float", None),
        ("layout.data_offset", "float", None),
    ],
    "geometry_msgs/msg/PoseWithCovarianceStamped": [
        ("header.frame_id", "string", None),
        ("pose.pose.position.x", "float", None),
        ("pose.covariance[35]", "float", None),
    ],
    "std_msgs/msg/String": [("data", "string", None)],
    "std_msgs/msg/Bool": [("data", "float", None)],
    "std_msgs/msg/Int64": [("data", "float", None)],
}

SCRIPT = r"""
import json, math, random, sys
from rclpy.serialization import serialize_message
from imrosc.onboard.monitor_ros2 import cdr, plumbing
from imrosc.onboard.flat import at_, avg_, len_, max_, min_, std_

cases = json.loads(sys.argv[1])
rng = random.Random(20)


def word(letters):
    return "".join(rng.choice(letters) for _ in range(rng.randrange(0, 9)))


def fill(message, depth=0):
    # every field of the message at random: strings of odd lengths (and non-ASCII),
    # sequences of 0 to 60 elements, so that every padding of CDR occurs
    for name, kind in message.get_fields_and_field_types().items():
        value = getattr(message, name)
        many = kind.startswith("sequence") or "[" in kind
        base = kind.split("<")[1].split(",")[0].rstrip(">") if kind.startswith("sequence") else None
        base = base or kind.split("[")[0]
        if "/" in base:
            if kind.startswith("sequence"):
                cls = plumbing.message_class(base)
                setattr(message, name, [fill(cls(), depth + 1) for _ in range(rng.randrange(0, 3))])
            elif not many:
                fill(value, depth + 1)
            continue
        def one():
            if base == "string":
                return word("ab\u00e9_")
            if base == "boolean":
                return rng.random() < 0.5
            if base in ("float", "double"):
                return rng.uniform(-1e3, 1e3)
            if base == "int8":
                return rng.randrange(-128, 128)
            if base == "uint8":
                return rng.randrange(256)
            if base.startswith("uint"):
                return rng.randrange(2 ** int(base[4:]))
            if base.startswith("int"):
                bits = int(base[3:])
                return rng.randrange(-(2 ** (bits - 1)), 2 ** (bits - 1))
            raise AssertionError(kind)
        if not many:
            setattr(message, name, one())
        elif "[" in kind:
            setattr(message, name, [one() for _ in range(len(value))])
        else:
            setattr(message, name, [one() for _ in range(rng.randrange(0, 61))])
    return message


def same(got, want):
    return len(got) == len(want) and all(
        a == b or (isinstance(a, float) and math.isnan(a) and math.isnan(b))
        for a, b in zip(got, want)
    )


checked = 0
for msgtype, (paths, expressions) in cases.items():
    cls = plumbing.message_class(msgtype)
    read = cdr.reader(cls, paths, plumbing.message_class)
    if read is None:
        sys.exit(f"no plan for {msgtype}")
    flatten = eval("lambda m: [" + ", ".join(expressions) + "]")
    for _ in range(200):
        message = fill(cls())
        got = [v for v in read(serialize_message(message))]
        want = flatten(message)
        if not same(got, want):
            sys.exit(f"{msgtype}: read {got} where the flattener gives {want}")
        checked += 1
print(f"checked {checked}")
"""


def test_the_cdr_reader_gives_what_the_flattener_gives_on_rclpy_messages(tmp_path: Path) -> None:
    python = require_ros2()
    cases = {
        msgtype: (
            [{"path": path, "type": kind, "derived": derived} for path, kind, derived in layout],
            [flat_expression(path, kind, derived) for path, kind, derived in layout],
        )
        for msgtype, layout in LAYOUTS.items()
    }
    done = subprocess.run(
        [python, "-c", SCRIPT, json.dumps(cases)],
        env=ros2_environment(tmp_path, PYTHONPATH=str(ROOT)),
        capture_output=True,
        text=True,
        check=False,
        timeout=300,
    )
    assert done.returncode == 0, done.stdout + done.stderr
    assert done.stdout.split() == ["checked", str(200 * len(LAYOUTS))]
