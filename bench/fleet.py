"""Inference on a Dask cluster: speed-up, memory per worker, bytes sent to the client.

    python bench/fleet.py [--bags 40] [--duration 30] [--repeats 2] [--folder DIR]
                          [--client-catalogue] [--no-pool] [--only-speedup] [--dask-defaults]

Writes ``--bags`` simulated runs of the landing system (``imrosc.sim``, ROS 1 bags of
``--duration`` s each) into ``DIR/bags`` (kept and reused), then runs ``imrosc infer``'s
detect stage on ``examples/landing_sim.xml``'s configuration over them:

(a) with a ``distributed.LocalCluster`` of 1 and of 2 single-threaded worker processes
    (loopback, no dashboard), each a fresh cluster with the Dask settings docs/fleet.md
    recommends (``imrosc.fleet.CLUSTER_CONFIG``; ``--dask-defaults``: Dask's own), and with the
    local pool ``-j 2``; it prints the seconds of
    inference (the catalogue of the bags: a task per bag, each bag's note merged by the client;
    the two passes over them; the merge) and of calibration (its held-out replays: on the
    cluster, or in the pool), and the speed-up of 2 workers over 1. Target: >= 1.7x on 2 cores.
    On a shared machine the wall time says little by itself, so each case also prints what the
    CPUs did during its inference: the CPU seconds of each worker, of this process (the client,
    the scheduler and the nannies), and the cores other processes took (the machine's busy time
    from ``/proc/stat`` less ours; 0 on an idle machine, 2 on two cores fully taken). The cases
    of 1 and 2 workers alternate ``--repeats`` times, so that each pair ran under about the same
    load; the speed-up is given per pair and as their median. Each case gives the catalogue's
    seconds and the client's CPU seconds in it, and the workers' and the client's CPU seconds
    over the whole stage, calibration included; ``--client-catalogue`` adds, per pair, 2 workers
    with the bags catalogued by the client one after another (as before the catalogue's tasks).
(b) the peak RSS of each worker process (its ``ru_maxrss``) for half the bags and for all of
    them: a worker holds one bag's states at a time, so the peak does not grow with the bags.
(c) per bag, for three of the bags and one ten times as long: the bag file, the samples made
    of it (the translated columns, which never leave the worker), the bag's answer (the
    states of every point and its calibration units; it stays on the cluster, where the
    joins merge it), what the client fetches of it (its summary: messages and calibration
    units), and the merged state of the bags so far, which the client fetches once per pass.

Every case checks that the invariants are byte for byte those of ``-j 1``'s merge order
(the cluster's and the pool's documents are compared).
"""

from __future__ import annotations

import argparse
import os
import pickle
import resource
import shutil
import statistics
import sys
import tempfile
import time
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from imrosc.calibrate.rule import HeldOut, Job  # noqa: E402
from imrosc.demo import example_configs  # noqa: E402
from imrosc.detect import DetectResult, prepare, run_detect  # noqa: E402
from imrosc.fleet import CLUSTER_CONFIG, Fleet  # noqa: E402
from imrosc.fleet.cluster import _join as fleet_join  # noqa: E402
from imrosc.fleet.cluster import _summary as fleet_summary  # noqa: E402
from imrosc.infer.engine import BagJob, Merged, run_bag, segments_for  # noqa: E402
from imrosc.invariants import dumps  # noqa: E402
from imrosc.sim import write_run  # noqa: E402
from imrosc.translate.catalog import BagNote, note_in_turn  # noqa: E402
from imrosc.translate.stream import BagTranslator  # noqa: E402

CONFIG = "landing_sim.xml"


def worker_peak_mb() -> float:
    """A worker process's peak RSS (MB): Linux's ``VmHWM``, which starts again at ``exec``
    (``ru_maxrss`` keeps the peak of the process that spawned the worker)."""
    try:
        with open("/proc/self/status") as status:
            for line in status:
                if line.startswith("VmHWM:"):
                    return int(line.split()[1]) / 1024
    except OSError:
        pass
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024


def write_bags(folder: Path, count: int, duration: float, first_seed: int = 0) -> list[Path]:
    """``count`` simulated nominal runs of ``duration`` s in ``folder`` (kept if there),
    seeds from ``first_seed`` on."""
    folder.mkdir(parents=True, exist_ok=True)
    bags = []
    for run in range(count):
        bag = folder / f"run_{run:03d}.bag"
        if not bag.exists():
            write_run(bag, seed=first_seed + run, fmt="ros1", duration=duration)
        bags.append(bag)
    return bags


def cpu_seconds() -> float:
    """This process's CPU seconds, its threads' included (run on each worker)."""
    return time.process_time()


def machine_busy() -> tuple[float, float]:
    """Seconds every core of the machine was busy so far (``/proc/stat``: all but idle and
    iowait), and this process's CPU seconds with its ended children's."""
    with open("/proc/stat") as stat:
        fields = [int(x) for x in stat.readline().split()[1:]]
    ticks = os.sysconf("SC_CLK_TCK")
    busy = (sum(fields[:8]) - fields[3] - fields[4]) / ticks
    own = os.times()
    return busy, own.user + own.system + own.children_user + own.children_system


@dataclass
class Cpu:
    """What the CPUs did during a case's inference (seconds)."""

    wall: float = 0.0
    workers: list[float] = field(default_factory=list)
    """Each worker's CPU seconds."""
    client: float = 0.0
    """This process's: the client, the scheduler and the nannies (threads of it)."""
    catalogue: float = 0.0
    """Seconds of the catalogue's pre-pass over the bags (before the first inference task)."""
    catalogue_client: float = 0.0
    """This process's CPU seconds during the catalogue."""
    others: float = 0.0
    """The other processes' busy seconds on every core (the machine's less ours)."""
    whole_workers: float = 0.0
    """The workers' CPU seconds over the whole stage, calibration included."""
    whole_client: float = 0.0
    """This process's CPU seconds over the whole stage, calibration included."""
    whole_others: float = 0.0
    """The other processes' cores over the whole stage."""

    def __str__(self) -> str:
        workers = " + ".join(f"{s:.1f}" for s in self.workers)
        cores = self.others / self.wall if self.wall else 0.0
        return (
            f"CPU: workers {workers} s, client {self.client:.1f} s; "
            f"other processes {cores:.2f} cores; catalogue {self.catalogue:.1f} s, "
            f"client {self.catalogue_client:.1f} s CPU in it; with calibration: workers "
            f"{self.whole_workers:.1f} s, client {self.whole_client:.1f} s, other processes "
            f"{self.whole_others:.2f} cores"
        )


def on_cluster(
    config: Path,
    bags: Sequence[Path],
    workers: int,
    settings: Mapping[str, Any],
    catalogue: str = "workers",
) -> tuple[DetectResult, list[float], list[float], Cpu]:
    """The detect stage on a fresh LocalCluster of ``workers`` processes with the Dask
    ``settings`` (the scheduler's, the nannies' and the workers'), calibration's
    replays included, the bags catalogued by the ``catalogue`` (``workers``: a task per bag;
    ``client``: this process reads them in turn, as before); the workers' RSS when they
    started (the least), then each worker's peak RSS (MB) when inference was done (before
    calibration's replays), then at the end; and what the CPUs did during inference."""
    import dask
    import distributed

    with (
        dask.config.set(settings),
        distributed.LocalCluster(
            n_workers=workers,
            processes=True,
            threads_per_worker=1,
            host="127.0.0.1",
            scheduler_port=0,
            dashboard_address=None,
            silence_logs=40,
        ) as cluster,
        distributed.Client(cluster, set_as_default=False) as client,
    ):
        started = min(client.run(worker_peak_mb).values())
        fleet = Fleet(client, cluster.scheduler_address)
        inferred: list[float] = []
        cpu = Cpu()
        worker_cpu = client.run(cpu_seconds)
        busy, own = machine_busy()
        begun = time.monotonic()

        def replays(jobs: Sequence[Job]) -> list[list[HeldOut]]:
            cpu.wall = time.monotonic() - begun
            done = client.run(cpu_seconds)
            busy_now, own_now = machine_busy()
            cpu.workers = sorted(done[w] - worker_cpu[w] for w in done)
            cpu.client = own_now - own
            cpu.others = max(0.0, busy_now - busy - cpu.client - sum(cpu.workers))
            inferred.extend(sorted(client.run(worker_peak_mb).values()))
            return fleet.replay_held_out(jobs)

        def noter(found: Sequence[Path]) -> list[BagNote]:
            begun, (_, own) = time.monotonic(), machine_busy()
            notes = list(fleet.note_bags(found) if catalogue == "workers" else note_in_turn(found))
            cpu.catalogue = time.monotonic() - begun
            cpu.catalogue_client = machine_busy()[1] - own
            return notes

        result = run_detect(config, bags=list(bags), reducer=fleet, replays=replays, noter=noter)
        done = client.run(cpu_seconds)
        busy_now, own_now = machine_busy()
        cpu.whole_workers = sum(done[w] - worker_cpu[w] for w in done)
        cpu.whole_client = own_now - own
        whole = time.monotonic() - begun
        spent = busy_now - busy - cpu.whole_client - cpu.whole_workers
        cpu.whole_others = max(0.0, spent) / whole if whole else 0.0
        peaks = [started, *sorted(client.run(worker_peak_mb).values())]
    return result, [started, *inferred], peaks, cpu


def samples_bytes(job: BagJob) -> int:
    """The bytes of the columns the translator makes of one bag (object columns pickled)."""
    translator = BagTranslator(
        job.specs, job.layouts, {k: set(v) for k, v in job.callerids.items()}
    )
    total = 0
    for samples in translator.translate(job.bag, job.run):
        total += samples.time.nbytes
        for column in samples.columns.values():
            total += len(pickle.dumps(column)) if column.dtype == object else column.nbytes
    return total


def sizes(config: Path, bags: Sequence[Path], longer: Path) -> None:
    """(c): per bag, what goes back to the client against the samples and the file; the
    ``longer`` bag (ten times as long) shows what grows with the bag and what does not; the
    merged state, joined as the cluster's joins do, what the client fetches per pass."""
    prepared, _ = prepare(config, bags=list(bags))
    assert prepared is not None
    project, catalog = prepared.project, prepared.catalog
    assert project.detect is not None
    frozen = {topic: frozenset(names) for topic, names in catalog.callerids.items()}
    units = segments_for(len(bags))
    template = BagJob(
        bags[0],
        0,
        tuple(prepared.specs),
        prepared.layouts,
        frozen,
        project.detect.tunables,
        units=units,
    )
    job_kib = len(pickle.dumps(template, 5)) / 1024
    print(f"(c) sent once per worker: the pass's job, {job_kib:,.0f} KiB")
    print(
        "    per bag: the file; the samples made of it (never sent); the bag's answer, kept on"
        " the cluster: its states and its calibration units; what the client fetches of it"
        " (its summary: messages and units); the merged state of the bags so far, which the"
        " client fetches once per pass"
    )
    print(
        f"    {'bag':<14}{'file':>10}{'samples':>11}{'answer':>10}{'states':>10}{'units':>9}"
        f"{'to client':>12}{'merged':>10}"
    )
    merged: Merged | None = None
    total_samples = 0
    for run, bag in enumerate([*bags[:3], longer]):
        job = BagJob(
            bag, run, template.specs, template.layouts, frozen, template.tunables, units=units
        )
        result = run_bag(job)
        answer = len(pickle.dumps(result, 5))
        states = len(pickle.dumps(result.states, 5))
        unit_bytes = len(pickle.dumps(result.units, 5))
        made = samples_bytes(job)
        total_samples += made
        own = Merged.of(result)
        fetched = len(pickle.dumps(fleet_summary(own), 5))
        merged = own if merged is None else fleet_join(merged, own)
        root = len(pickle.dumps(Merged(merged.states, merged.failed, merged.messages), 5))
        print(
            f"    {bag.name:<14}{bag.stat().st_size / 1024:>8,.0f} K{made / 1024:>9,.0f} K"
            f"{answer / 1024:>8,.0f} K{states / 1024:>8,.0f} K{unit_bytes / 1024:>7,.0f} K"
            f"{fetched / 1024:>10,.0f} K{root / 1024:>8,.0f} K"
        )
    print(
        f"    the {run + 1} bags' samples: {total_samples / 1024:,.0f} K; their merged state:"
        f" {root / 1024:,.0f} K (the client fetches that once per pass, and each bag's summary)"
    )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--bags", type=int, default=40)
    parser.add_argument("--duration", type=float, default=30.0)
    parser.add_argument("--repeats", type=int, default=2, help="pairs of 1 and 2 workers")
    parser.add_argument("--folder", type=Path, help="where the bags are kept [a temporary one]")
    parser.add_argument(
        "--client-catalogue",
        action="store_true",
        help="each repeat also runs 2 workers with the bags catalogued by the client in turn "
        "(as before the catalogue's tasks), to compare the client's CPU",
    )
    parser.add_argument("--no-pool", action="store_true", help="skip the -j 2 case")
    parser.add_argument("--only-speedup", action="store_true", help="(a) only")
    parser.add_argument(
        "--dask-defaults",
        action="store_true",
        help="clusters with Dask's default settings instead of docs/fleet.md's recommended ones "
        "(imrosc.fleet.CLUSTER_CONFIG)",
    )
    args = parser.parse_args()
    settings = {} if args.dask_defaults else CLUSTER_CONFIG
    folder = args.folder or Path(tempfile.mkdtemp(prefix="imrosc-fleet-"))
    folder.mkdir(parents=True, exist_ok=True)
    source = next(p for p in example_configs() if p.name == CONFIG)
    config = folder / CONFIG
    shutil.copyfile(source, config)
    started = time.monotonic()
    bags = write_bags(folder / "bags", args.bags, args.duration)
    megabytes = sum(b.stat().st_size for b in bags) / 2**20
    print(
        f"{len(bags)} bags of {args.duration:g} s in {folder / 'bags'} ({megabytes:,.0f} MB, "
        f"written in {time.monotonic() - started:.1f} s)"
    )

    print("(a) imrosc infer's detect stage, the same invariants file checked in each case:")
    reference: str | None = None
    peaks: dict[int, list[float]] = {}
    after_inference: dict[int, list[float]] = {}

    def report(label: str, result: DetectResult, cpu: Cpu | None = None) -> None:
        nonlocal reference
        assert result.document is not None and result.result is not None
        text = dumps(result.document)
        if reference is None:
            reference = text
        assert text == reference, f"{label}: not the invariants of the other runs"
        messages = result.result.messages
        load = " ".join(f"{x:.1f}" for x in os.getloadavg())
        print(
            f"    {label:<26}infer {result.seconds:5.1f} s ({messages / result.seconds:,.0f} "
            f"msg/s), calibration {result.calibration_seconds:5.1f} s  [load {load}]"
        )
        if cpu is not None:
            print(f"    {'':<26}{cpu}")

    if not args.no_pool:
        result = run_detect(config, bags=bags, workers=2)
        report("-j 2 (local pool)", result)
    client_cases: list[tuple[float, float, float, float]] = []
    """Per repeat, 2 workers: the catalogue's seconds and client CPU seconds, the catalogue
    on the workers, then on the client."""
    pairs: list[tuple[float, float, float, float]] = []
    """Per repeat: the inference seconds of 1 and 2 workers, and with calibration."""
    for repeat in range(args.repeats):
        seconds: dict[int, tuple[float, float]] = {}
        for workers in (1, 2):
            result, inferred, peak, cpu = on_cluster(config, bags, workers, settings)
            report(f"LocalCluster {workers} worker{'s' * (workers > 1)} #{repeat + 1}", result, cpu)
            seconds[workers] = (result.seconds, result.seconds + result.calibration_seconds)
            if workers == 2:
                peaks[len(bags)] = peak
                after_inference[len(bags)] = inferred
        pairs.append((*seconds[1], *seconds[2]))
        if args.client_catalogue:
            on_workers = cpu
            result, _, _, cpu = on_cluster(config, bags, 2, settings, catalogue="client")
            report(f"  the same, client catalogue #{repeat + 1}", result, cpu)
            client_cases.append(
                (
                    on_workers.catalogue,
                    on_workers.catalogue_client,
                    cpu.catalogue,
                    cpu.catalogue_client,
                )
            )
    ratios = [one / two for one, _, two, _ in pairs]
    wholes = [one / two for _, one, _, two in pairs]
    print(
        f"    speed-up of 2 workers over 1: {statistics.median(ratios):.2f}x inference "
        f"(per pair {', '.join(f'{r:.2f}x' for r in ratios)}), "
        f"{statistics.median(wholes):.2f}x with calibration (target >= 1.7x)"
    )
    for index, (wall, own, wall_before, own_before) in enumerate(client_cases):
        print(
            f"    catalogue of {len(bags)} bags, 2 workers #{index + 1}: on the workers "
            f"{wall:.1f} s ({own:.1f} s client CPU), on the client {wall_before:.1f} s "
            f"({own_before:.1f} s client CPU)"
        )
    if args.only_speedup:
        return

    half = bags[: len(bags) // 2]
    _, after_inference[len(half)], peaks[len(half)], _ = on_cluster(config, half, 2, settings)
    print("(b) peak RSS of each of 2 workers, after inference and at the end (calibration):")
    for count in sorted(peaks):
        started, *peak = peaks[count]
        _, *inferred = after_inference[count]
        shown = ", ".join(f"{mb:,.0f} MB" for mb in inferred)
        final = ", ".join(f"{mb:,.0f} MB" for mb in peak)
        print(f"    {count:>3} bags: {shown}; {final} (started at {started:,.0f} MB)")
    longer = folder / "longer" / "run_longer.bag"
    if not longer.exists():
        write_run(longer, seed=len(bags), fmt="ros1", duration=10 * args.duration)
    sizes(config, bags, longer)


if __name__ == "__main__":
    main()
