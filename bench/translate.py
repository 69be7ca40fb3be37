"""Translation throughput against rosbags' plain read-and-deserialize loop, in one run.

    python bench/translate.py [--messages 400000]

For each bag it times (a) rosbags' AnyReader reading and deserializing every message of the
topics the configuration uses, and (b) imrosc's translator producing every point's samples
(flattening, Algorithm 1 pairing, conditions). Target: (b) at least 0.7x the rate of (a).
The generated bag mixes sensor_msgs/Imu at 200 Hz, geometry_msgs/PoseStamped at 100 Hz and
std_msgs/Float64 at 100 Hz, each point pairing its topic with the others.
"""

from __future__ import annotations

import argparse
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
from rosbags.highlevel import AnyReader
from rosbags.rosbag1 import Writer
from rosbags.typesys import Stores, get_typestore

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from imrosc.backends.plan import render_job, render_plan  # noqa: E402
from imrosc.backends.registry import BuildInputs, TopicType  # noqa: E402
from imrosc.lower import lower  # noqa: E402
from imrosc.passes.context import PassContext  # noqa: E402
from imrosc.passes.pipeline import run_passes  # noqa: E402
from imrosc.schema.loader import load_config, parse_config_bytes  # noqa: E402
from imrosc.translate.catalog import build_catalog  # noqa: E402
from imrosc.translate.points import point_specs  # noqa: E402
from imrosc.translate.stream import BagTranslator  # noqa: E402

GENERATED_CONFIG = b"""<imROS project="bench">
  <scope>
    <publish id="i"><topic>/imu</topic><topic>/pose</topic></publish>
    <publish id="p"><topic>/pose</topic><topic>/imu</topic></publish>
    <publish id="v"><topic>/volt</topic><topic>/pose</topic></publish>
  </scope>
</imROS>
"""


def generate(path: Path, messages: int) -> Path:
    """A ROS 1 bag of ``messages`` messages (Imu 200 Hz, PoseStamped and Float64 100 Hz)."""
    store = get_typestore(Stores.ROS1_NOETIC)
    types = store.types
    rng = np.random.default_rng(7)
    header = types["std_msgs/msg/Header"]
    stamp = types["builtin_interfaces/msg/Time"]
    vector, quat = types["geometry_msgs/msg/Vector3"], types["geometry_msgs/msg/Quaternion"]
    point, pose = types["geometry_msgs/msg/Point"], types["geometry_msgs/msg/Pose"]
    cov = np.zeros(9)
    with Writer(path) as writer:
        imu_c = writer.add_connection(
            "/imu", "sensor_msgs/msg/Imu", typestore=store, callerid="/imu"
        )
        pose_c = writer.add_connection(
            "/pose", "geometry_msgs/msg/PoseStamped", typestore=store, callerid="/loc"
        )
        volt_c = writer.add_connection(
            "/volt", "std_msgs/msg/Float64", typestore=store, callerid="/bat"
        )
        for n in range(messages):
            t = n * 0.0025  # 400 messages per second: 200 imu, 100 pose, 100 volt
            ns = int(t * 1e9)
            h = header(seq=n, stamp=stamp(sec=int(t), nanosec=ns % 1_000_000_000), frame_id="base")
            x, y, z = rng.normal(size=3)
            kind = n % 4
            if kind in (0, 2):
                msg = types["sensor_msgs/msg/Imu"](
                    header=h,
                    orientation=quat(x=0.0, y=0.0, z=float(x), w=1.0),
                    orientation_covariance=cov,
                    angular_velocity=vector(x=float(x), y=float(y), z=float(z)),
                    angular_velocity_covariance=cov,
                    linear_acceleration=vector(x=float(y), y=float(z), z=9.81 + float(x)),
                    linear_acceleration_covariance=cov,
                )
                writer.write(imu_c, ns, bytes(store.serialize_ros1(msg, "sensor_msgs/msg/Imu")))
            elif kind == 1:
                msg = types["geometry_msgs/msg/PoseStamped"](
                    header=h,
                    pose=pose(
                        position=point(x=float(x), y=float(y), z=float(z)),
                        orientation=quat(x=0.0, y=0.0, z=0.0, w=1.0),
                    ),
                )
                writer.write(
                    pose_c, ns, bytes(store.serialize_ros1(msg, "geometry_msgs/msg/PoseStamped"))
                )
            else:
                msg = types["std_msgs/msg/Float64"](data=12.0 + float(x))
                writer.write(volt_c, ns, bytes(store.serialize_ros1(msg, "std_msgs/msg/Float64")))
    return path


def baseline(bag: Path, topics: set[str]) -> tuple[int, float]:
    started = time.perf_counter()
    count = 0
    with AnyReader([bag]) as reader:
        wanted = [c for c in reader.connections if c.topic in topics]
        for connection, _, raw in reader.messages(connections=wanted):
            reader.deserialize(raw, connection.msgtype)
            count += 1
    return count, time.perf_counter() - started


def translate(config: bytes, bag: Path) -> tuple[int, int, float, float, set[str]]:
    """Messages, samples, seconds with the catalog pre-pass, seconds without it, topics."""
    loaded, _ = parse_config_bytes(config, "bench.xml")
    assert loaded is not None
    started = time.perf_counter()
    catalog = build_catalog([bag])
    catalogued = time.perf_counter()
    project = run_passes(lower(loaded), PassContext())
    types = {t: TopicType(m, f) for t, (m, f) in catalog.types.items()}
    inputs = BuildInputs(project, (), types)
    specs, _, layouts = point_specs(render_plan(inputs), render_job(inputs), catalog)
    translator = BagTranslator(specs, layouts, catalog.callerids)
    samples = sum(len(s) for s in translator.translate(bag, 0))
    done = time.perf_counter()
    return translator.messages, samples, done - started, done - catalogued, set(translator.topics)


def measure(name: str, config: bytes, bag: Path, repeat: int) -> None:
    best_all = best_t = best_b = float("inf")
    messages = samples = 0
    for _ in range(repeat):  # alternate, keep the best of each: the machine is shared
        messages, samples, whole, seconds, topics = translate(config, bag)
        best_all, best_t = min(best_all, whole), min(best_t, seconds)
        _, base = baseline(bag, topics)
        best_b = min(best_b, base)
    rate_all, rate_t, rate_b = messages / best_all, messages / best_t, messages / best_b
    print(
        f"{name:<22} {messages:>8,} msgs  rosbags read+deserialize {rate_b:>9,.0f} msg/s  "
        f"imrosc translate {rate_t:>9,.0f} msg/s (ratio {rate_t / rate_b:.2f}; "
        f"{rate_all:,.0f} msg/s, ratio {rate_all / rate_b:.2f} with the catalog pre-pass)  "
        f"{samples:,} samples"
    )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--messages", type=int, default=400_000)
    parser.add_argument("--repeat", type=int, default=3)
    args = parser.parse_args()
    crazyflie = ROOT.parent / "shared" / "data" / "real" / "crazyflie"
    config_path = ROOT / "examples" / "crazyflie.xml"
    loaded, _ = load_config(config_path)
    assert loaded is not None
    config = config_path.read_bytes()
    for name in ("sine_1.bag", "sine_2.bag"):
        if (crazyflie / name).exists():
            measure(f"crazyflie/{name}", config, crazyflie / name, args.repeat)
    with tempfile.TemporaryDirectory() as folder:
        started = time.perf_counter()
        bag = generate(Path(folder) / "generated.bag", args.messages)
        print(f"(generated {args.messages:,} messages in {time.perf_counter() - started:.1f} s)")
        measure("generated.bag", GENERATED_CONFIG, bag, args.repeat)


if __name__ == "__main__":
    main()
