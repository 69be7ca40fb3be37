"""Reading ROS 1 bags cut short: the cost of the scan against reading through the index.

    python bench/recover.py [BAG] [--repeat 3] [--ros2]

For a bag (default: the largest real bag in ../shared/data, else a generated one) it times
opening and reading every raw message (a) of the whole bag through its index, and (b) of
copies cut at 25, 50, 75 and 99 % of their bytes and of a copy with no index, which
imrosc scans record by record (imrosc.bagrecover). It prints per copy the messages
recovered, the time, the rate and the time against (a). Target: no copy takes more than 2x
the time of reading the whole bag through its index.

With ``--ros2``, the same for generated ROS 2 bags (MCAP and sqlite3, 200,000 messages):
their storage file cut at 25, 50, 75 and 99 %, and the whole storage without
``metadata.yaml`` (imrosc.bagrecover_ros2).
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

from imrosc.bags import BagError, open_bag, recovered  # noqa: E402

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


def generated_ros2(folder: Path, storage: str) -> Path:
    from rosbags.rosbag2 import StoragePlugin, Writer

    from tests.graph import ros2_typestore

    store = ros2_typestore()
    plugin = StoragePlugin.MCAP if storage == "mcap" else StoragePlugin.SQLITE3
    path = folder / f"generated-{storage}"
    with Writer(path, version=9, storage_plugin=plugin) as writer:
        connection = writer.add_connection("/x", "std_msgs/msg/Float64", typestore=store)
        for i in range(200_000):
            data = store.serialize_cdr(
                store.types["std_msgs/msg/Float64"](data=float(i)), "std_msgs/msg/Float64"
            )
            writer.write(connection, i * 1_000_000, bytes(data))
    return path


def ros2(folder: Path, repeat: int) -> float:
    """The ROS 2 table: per storage, the whole bag, then its damaged copies; the worst ratio."""
    import shutil

    worst = 0.0
    for storage in ("mcap", "sqlite3"):
        bag = generated_ros2(folder, storage)
        (stored,) = [p for p in bag.iterdir() if p.suffix in (".mcap", ".db3")]
        data = stored.read_bytes()
        count, seconds, _ = best(bag, repeat)
        print(f"{bag} ({len(data):,} bytes of {stored.suffix} storage)")
        print(
            f"{'whole, indexed':<16} {count:>9,} msgs {seconds * 1e3:8.1f} ms "
            f"{count / seconds:>12,.0f} msg/s"
        )
        copies = {f"cut at {p} %": data[: len(data) * p // 100] for p in (25, 50, 75, 99)}
        copies["no metadata"] = data
        for name, content in copies.items():
            copy = folder / f"copy-{storage}"
            shutil.rmtree(copy, ignore_errors=True)
            shutil.copytree(bag, copy)
            (copy / stored.name).write_bytes(content)
            if name == "no metadata":
                (copy / "metadata.yaml").unlink()
            try:
                found, took, note = best(copy, repeat)
            except BagError as error:  # sqlite cannot reach the first rows through its tree
                print(f"{name:<16} not read: {error.message}")
                continue
            ratio = took / seconds
            worst = max(worst, ratio)
            print(
                f"{name:<16} {found:>9,} msgs {took * 1e3:8.1f} ms {found / took:>12,.0f} "
                f"msg/s  {ratio:4.2f}x  ({note})"
            )
    return worst


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
    parser.add_argument("--ros2", action="store_true", help="Generated ROS 2 bags instead.")
    args = parser.parse_args()
    if args.ros2:
        with tempfile.TemporaryDirectory() as folder:
            worst = ros2(Path(folder), args.repeat)
        print(f"worst: {worst:.2f}x the whole bag's indexed read (target <= 2x)")
        return
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
