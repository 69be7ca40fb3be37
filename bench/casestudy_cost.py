"""What a simulated second of the landing system costs in CPU, with or without a monitor.

Runs one trial of ``--scenario`` (seed ``--seed``) twice on a roscore of its own: once to
``--short`` simulated seconds and once to ``--long``, and prints the CPU seconds (user and
system, of every process the trials started) per simulated second between them, so that
starting and stopping the graph's processes cancels out. ``--repeat`` runs the pair again;
``--monitor DIR`` runs the trials through the ``system_monitored.launch`` that ``imrosc
build --backend ros1`` wrote into ``DIR`` (``bench/casestudy.py --keep DIR`` leaves it in
``DIR/build/<project>-ros1``).

The system is this script's tree's ``examples/landing_system`` (``tests.live.landing_system``
runs it): two trees (a branch and ``main``) measured one after the other on the same seed
compare their costs as a ratio. Run it under ``flock /tmp/imrosc-heavy.lock`` on a quiet
machine; each line gives the load beside the figure::

    python bench/casestudy_cost.py --repeat 2
"""

from __future__ import annotations

import argparse
import os
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from bench.casestudy import children_cpu  # noqa: E402
from tests.live.harness import Ros, ros_missing  # noqa: E402
from tests.live.landing_system import LAUNCH, Outcome, prepare, trial  # noqa: E402


def measured(
    ros: Ros, launch: Path, args: argparse.Namespace, timeout: float
) -> tuple[float, Outcome]:
    """The CPU seconds of one trial and its outcome."""
    before = children_cpu()
    outcome = trial(ros, args.scenario, args.seed, launch=launch, speed=0.0, timeout=timeout)
    return children_cpu() - before, outcome


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--scenario", default="normal")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--short", type=float, default=0.5, help="simulated s (default 0.5)")
    parser.add_argument("--long", type=float, default=25.0, help="simulated s (default 25)")
    parser.add_argument("--repeat", type=int, default=1)
    parser.add_argument("--monitor", type=Path, help="a folder holding system_monitored.launch")
    args = parser.parse_args(argv)
    missing = ros_missing()
    if missing:
        sys.exit(f"needs ROS 1 here: {missing}")
    launch = LAUNCH
    if args.monitor is not None:
        launch = next(args.monitor.rglob("system_monitored.launch"))
    with tempfile.TemporaryDirectory(prefix="imrosc-cost-") as home:
        ros = Ros(Path(home) / "ros")
        prepare(ros)
        if args.monitor is not None:
            ros.add_package_path(launch.parents[2])
        ros.start()
        try:
            for _ in range(args.repeat):
                short, first = measured(ros, launch, args, args.short)
                long, second = measured(ros, launch, args, args.long)
                seconds = second.time - first.time
                load = os.getloadavg()[0]
                print(
                    f"{args.scenario} seed {args.seed}: {short:.2f} CPU s for {first.time:.2f}"
                    f" simulated s, {long:.2f} for {second.time:.2f} ({second.outcome}):"
                    f" {(long - short) / seconds:.3f} CPU s per simulated s (load {load:.2f})",
                    flush=True,
                )
        finally:
            ros.shutdown()


if __name__ == "__main__":
    main()
