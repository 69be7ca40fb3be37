"""Reading ROS 1 bags cut short: the cost of the scan against reading through the index.

    python bench/recover.py [BAG] [--repeat 3]

For a bag (default: the largest real bag in ../shared/data, else a generated one) it times
opening and reading every raw message (a) of the whole bag through its index, and (b) of
copies cut at 25, 50, 75 and 99 % of their bytes and of a copy with no index, which
imrosc scans record by record (imrosc.bagrecover). It prints per copy the messages
recovered, the time, the rate and the time against (a). Target: no copy takes more than 2x
the time of reading the whole bag through its index.
"""

from __future__ import annotations

import argparse
import struct
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from imrosc.bags import open_bag, recovered  # noqa: E402

DATA = ROOT.parent / "shared" / "data" / "real" / "hydra" / "hydra_flight.bag"


def generated(folder: Path) -> Path:
    from rosbags.rosbag1 import Writer

    from tests.translate import build, store

    path = folder / "generated.bag"
    with Writer(path) as writer:
        connection = writer.add_connection("/x", "std_msgs/msg/Float64", typestore=store())
        for i in range(200_000):
            data = store().serialize_ros1(
                build("std_msgs/msg/Float64", {"data": i}), "std_msgs/msg/Float64"
            )
            writer.write(connection, i * 1_000_000, bytes(data))
    return path


def read_all(bag: Path) -> tuple[int, float, str | None]:
    started = time.perf_counter()
    with open_bag(bag) as reader:
        count = sum(1 for _ in reader.messages())
        note = recovered(reader)
    return count, time.perf_counter() - started, note


def best(bag: Path, repeat: int) -> tuple[int, float, str | None]:
    runs = [read_all(bag) for _ in range(repeat)]
    return min(runs, key=lambda run: run[1])


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n", 1)[0])
    parser.add_argument("bag", nargs="?", type=Path)
    parser.add_argument("--repeat", type=int, default=3)
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as folder:
        bag = args.bag or (DATA if DATA.exists() else generated(Path(folder)))
        data = bag.read_bytes()
        count, seconds, _ = best(bag, args.repeat)
        print(f"{bag} ({len(data):,} bytes)")
        print(
            f"{'whole, indexed':<16} {count:>9,} msgs {seconds * 1e3:8.1f} ms "
            f"{count / seconds:>12,.0f} msg/s"
        )
        copies: dict[str, bytes] = {}
        for percent in (25, 50, 75, 99):
            copies[f"cut at {percent} %"] = data[: len(data) * percent // 100]
        raw = bytearray(data)
        field = raw.index(b"index_pos=") + len(b"index_pos=")
        (index_pos,) = struct.unpack_from("<Q", raw, field)
        raw[field : field + 8] = bytes(8)
        copies["no index"] = bytes(raw[:index_pos])
        worst = 0.0
        for name, content in copies.items():
            path = Path(folder) / "copy.bag"
            path.write_bytes(content)
            found, took, note = best(path, args.repeat)
            ratio = took / seconds
            worst = max(worst, ratio)
            print(
                f"{name:<16} {found:>9,} msgs {took * 1e3:8.1f} ms {found / took:>12,.0f} "
                f"msg/s  {ratio:4.2f}x  ({note})"
            )
        print(f"worst: {worst:.2f}x the whole bag's indexed read (target <= 2x)")


if __name__ == "__main__":
    main()
