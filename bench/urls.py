"""Bags by URL: what downloading costs against reading the same bags on disk.

    python bench/urls.py [--bags 12] [--duration 30] [--folder DIR] [--no-cluster]

Writes ``--bags`` simulated runs of the landing system (ROS 1 bags of ``--duration`` s) into
``DIR/bags`` (kept and reused), serves ``DIR`` over HTTP on loopback (a ``http.server`` thread,
127.0.0.1), and runs ``imrosc infer``'s detect stage on ``examples/landing_sim.xml``'s
configuration over the bags by path and by ``http://`` URL: with ``-j 2`` (local worker
processes), and on a ``distributed.LocalCluster`` of 2 single-threaded workers. It prints the
seconds of inference and calibration of each, and checks that a URL's invariants are those of
its path (the bags' names apart).
"""

from __future__ import annotations

import argparse
import os
import sys
import tempfile
import time
from collections.abc import Callable
from pathlib import Path

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from bench.fleet import write_bags  # noqa: E402
from imrosc.demo import example_configs  # noqa: E402
from imrosc.detect import DetectResult, run_detect  # noqa: E402
from imrosc.fleet import Fleet  # noqa: E402
from imrosc.invariants import dumps  # noqa: E402
from imrosc.remote import BagUrl  # noqa: E402
from tests.served import serve  # noqa: E402

CONFIG = "landing_sim.xml"


def timed(label: str, run: Callable[[], DetectResult]) -> DetectResult:
    started = time.monotonic()
    result = run()
    assert result.document is not None, result.diagnostics
    load = os.getloadavg()[0]
    print(
        f"{label:<28} {time.monotonic() - started:6.1f} s (inference {result.seconds:5.1f} s, "
        f"calibration {result.calibration_seconds:5.1f} s), load {load:.1f}",
        flush=True,
    )
    return result


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--bags", type=int, default=12)
    parser.add_argument("--duration", type=float, default=30.0)
    parser.add_argument("--folder", type=Path, help="where the bags are kept [a temporary one]")
    parser.add_argument("--no-cluster", action="store_true", help="only -j 2")
    options = parser.parse_args()
    folder = options.folder or Path(tempfile.mkdtemp(prefix="imrosc-bench-urls-"))
    config = next(p for p in example_configs() if p.name == CONFIG)
    bags = write_bags(folder / "bags", options.bags, options.duration, first_seed=1000)
    size = sum(bag.stat().st_size for bag in bags)
    print(f"{len(bags)} bags of {options.duration:g} s, {size / 1e6:.1f} MB, in {folder}")
    with serve(folder) as url:
        urls: list[Path] = [BagUrl(f"{url}/bags/{bag.name}") for bag in bags]

        def same(by_path: DetectResult, by_url: DetectResult) -> None:
            assert by_path.document is not None and by_url.document is not None
            got = dumps(by_url.document).replace(f"{url}/", f"{folder}/")
            assert got == dumps(by_path.document), "the invariants differ"

        local = timed("-j 2, paths", lambda: run_detect(config, workers=2, bags=bags))
        remote = timed("-j 2, http:// URLs", lambda: run_detect(config, workers=2, bags=urls))
        same(local, remote)
        if options.no_cluster:
            return
        import distributed

        with (
            distributed.LocalCluster(
                n_workers=2,
                processes=True,
                threads_per_worker=1,
                host="127.0.0.1",
                dashboard_address=":0",
                silence_logs=50,
            ) as cluster,
            distributed.Client(cluster, set_as_default=False) as client,
        ):
            fleet = Fleet(client, cluster.scheduler_address)

            def on_cluster(named: list[Path]) -> DetectResult:
                return run_detect(
                    config,
                    bags=named,
                    reducer=fleet,
                    replays=fleet.replay_held_out,
                    noter=fleet.note_bags,
                )

            timed("cluster of 2, paths", lambda: on_cluster(bags))
            same(local, timed("cluster of 2, http:// URLs", lambda: on_cluster(urls)))
    print("the invariants by URL are those by path")


if __name__ == "__main__":
    main()
