"""Replay throughput against rosbags' plain read-and-deserialize loop, in one run.

    python bench/replay.py [--messages 400000] [--repeat 3] [--engine] [--classify]

Invariants are inferred once from ``examples/crazyflie.xml``'s training flights and from a
20,000-message bag of ``bench/translate.py``'s generator (Imu 200 Hz, PoseStamped and
Float64 100 Hz, each point paired with the other topics). Then, alternately (best of
``--repeat``), it times (a) rosbags' AnyReader reading and deserializing every message
replay reads (the invariants' topics and the records), and (b) ``imrosc replay``'s checking
of the same bags (plots kept, as the command does): the four Crazyflie flights, and a
generated bag of ``--messages`` messages. Target: (b) at least 0.5x the rate of (a).
``--engine`` also times the per-message engine (the path before column chunks);
``--classify`` also times classify's observation of each run (its chunked replay with the
samples traced for learnt detectors, against the same rosbags rate) and the whole ``imrosc
classify examples/crazyflie.xml`` both ways. Times are CPU seconds (the process's, the
command's for classify): the machine is shared, and wall time moves with the other jobs;
``--bags`` adds a line per Crazyflie flight.
"""

from __future__ import annotations

import argparse
import importlib.util
import json
import os
import resource
import subprocess
import sys
import tempfile
import time
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

from rosbags.highlevel import AnyReader

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from imrosc.classify import observe, replayer_of  # noqa: E402
from imrosc.records import ARCH_TOPIC, PARAMS_TOPIC, SRVS_TOPIC  # noqa: E402
from imrosc.replay import RunReplayer  # noqa: E402

RECORDS = {PARAMS_TOPIC, SRVS_TOPIC, ARCH_TOPIC}
CRAZYFLIE = ROOT.parent / "shared" / "data" / "real" / "crazyflie"


def _generator() -> Any:
    spec = importlib.util.spec_from_file_location(
        "bench_translate", ROOT / "bench" / "translate.py"
    )
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def baseline(bags: Sequence[Path], document: Mapping[str, Any]) -> tuple[int, float]:
    """Messages and CPU seconds of rosbags reading and deserializing what replay reads."""
    started = time.process_time()
    count = 0
    for bag in bags:
        with AnyReader([bag]) as reader:
            wanted = [
                c
                for c in reader.connections
                if (c.topic in document["topics"] or c.topic in RECORDS) and c.msgcount
            ]
            for connection, _, raw in reader.messages(connections=wanted) if wanted else ():
                reader.deserialize(raw, connection.msgtype)
                count += 1
    return count, time.process_time() - started


def replayed(bags: Sequence[Path], document: Mapping[str, Any], chunked: bool) -> tuple[int, float]:
    """Messages and CPU seconds of ``imrosc replay``'s checking (plots kept)."""
    started = time.process_time()
    replay = RunReplayer(document, plots=True)
    replay.replayer.chunked = chunked
    count = sum(replay(bag)[0].messages for bag in bags)
    return count, time.process_time() - started


def observed(bags: Sequence[Path], document: Mapping[str, Any]) -> tuple[int, float]:
    """Messages and CPU seconds of ``imrosc classify``'s observation of each run (its replay
    by column chunks, the samples traced for learnt detectors, what classification keeps)."""
    started = time.process_time()
    replayer, sampler = replayer_of(document, collect=True)
    count = sum(observe(replayer, (bag, None), sampler).messages for bag in bags)
    return count, time.process_time() - started


def infer(config: Path) -> dict[str, Any]:
    command = [sys.executable, "-m", "imrosc", "infer", str(config), "-q", "-j", "1"]
    subprocess.run(command, check=True, env={**os.environ, "PYTHONPATH": str(ROOT)})
    written: dict[str, Any] = json.loads(config.with_suffix(".inv").read_text())
    return written


def measure(
    name: str,
    bags: Sequence[Path],
    document: Mapping[str, Any],
    repeat: int,
    engine: bool,
    classifying: bool = False,
) -> None:
    best_b = best_r = best_e = best_c = float("inf")
    messages = read = 0
    for _ in range(repeat):  # alternate, keep the best of each: the machine is shared
        read, seconds = baseline(bags, document)
        best_b = min(best_b, seconds)
        messages, seconds = replayed(bags, document, chunked=True)
        best_r = min(best_r, seconds)
        if classifying:
            _, seconds = observed(bags, document)
            best_c = min(best_c, seconds)
    if not read:
        print(f"{name:<24} reads no message of the invariants' topics", flush=True)
        return
    rate_b, rate_r = read / best_b, messages / best_r
    line = (
        f"{name:<24} {messages:>8,} msgs  rosbags read+deserialize {rate_b:>9,.0f} msg/s  "
        f"imrosc replay {rate_r:>9,.0f} msg/s (ratio {rate_r / rate_b:.2f})"
    )
    if classifying:
        rate_c = messages / best_c
        line += f"  classify's replay {rate_c:>9,.0f} msg/s (ratio {rate_c / rate_b:.2f})"
    if engine:
        _, seconds = replayed(bags, document, chunked=False)
        best_e = seconds
        line += (
            f"  per-message engine {messages / best_e:,.0f} msg/s ({best_e / best_r:.1f}x slower)"
        )
    print(line, flush=True)


def classify(config: Path) -> None:
    """``imrosc classify`` on the Crazyflie flights, by column chunks and message by message."""
    seconds = {}
    for chunked in ("1", "0"):
        env = {**os.environ, "PYTHONPATH": str(ROOT), "IMROSC_CHUNKED": chunked}
        started = _children_cpu()
        command = [sys.executable, "-m", "imrosc", "classify", str(config), "-q", "-j", "1"]
        subprocess.run(command, env=env, stdout=subprocess.DEVNULL, check=False)
        seconds[chunked] = _children_cpu() - started
    print(
        f"classify crazyflie       chunked {seconds['1']:.1f} s CPU, per-message engine "
        f"{seconds['0']:.1f} s CPU ({seconds['0'] / seconds['1']:.1f}x)"
    )


def _children_cpu() -> float:
    """CPU seconds of the finished child processes so far."""
    usage = resource.getrusage(resource.RUSAGE_CHILDREN)
    return usage.ru_utime + usage.ru_stime


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--messages", type=int, default=400_000)
    parser.add_argument("--repeat", type=int, default=3)
    parser.add_argument("--engine", action="store_true", help="also time the per-message engine")
    parser.add_argument("--classify", action="store_true", help="also time imrosc classify")
    parser.add_argument(
        "--bags", action="store_true", help="also a line per Crazyflie flight (engine built each)"
    )
    args = parser.parse_args()
    generator = _generator()
    with tempfile.TemporaryDirectory() as name:
        folder = Path(name)
        example = (ROOT / "examples" / "crazyflie.xml").read_text()
        config = folder / "crazyflie.xml"
        config.write_text(example.replace("../../shared/data/real/crazyflie", str(CRAZYFLIE)))
        document = infer(config)
        flights = sorted(CRAZYFLIE.glob("*.bag"))
        measure("crazyflie (4 flights)", flights, document, args.repeat, args.engine, args.classify)
        for flight in flights if args.bags else ():
            measure(f"  {flight.name}", [flight], document, args.repeat, False)
        if args.classify:
            classify(config)
        train = generator.generate(folder / "train.bag", 20_000)
        generated = folder / "generated.xml"
        text = generator.GENERATED_CONFIG.decode()
        generated.write_text(
            text.replace(
                "</scope>", f"</scope>\n  <detect inv='generated.inv'><bag>{train}</bag></detect>"
            )
        )
        document = infer(generated)
        started = time.perf_counter()
        bag = generator.generate(folder / "generated.bag", args.messages)
        print(f"(generated {args.messages:,} messages in {time.perf_counter() - started:.1f} s)")
        measure("generated.bag", [bag], document, args.repeat, args.engine, args.classify)


if __name__ == "__main__":
    main()
