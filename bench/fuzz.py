"""Fuzzed configurations through check -> infer -> replay: cases, crashes and time.

    python bench/fuzz.py [--cases 300] [--seed 0] [--keep DIR]

Runs ``--cases`` configurations drawn by ``tests/pipeline_fuzz.py`` (hypothesis, generation
only: no shrinking, no example database) through ``imrosc check``, ``imrosc infer`` and
``imrosc replay`` on short bags, and prints the number of cases, how far they went (exit
statuses per command), the crashes (an exception out of a command, a traceback in its
output, an exit status outside the README's table) with one configuration of each kept under
``--keep``, and the time. Target: 0 crashes.
"""

from __future__ import annotations

import argparse
import collections
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from hypothesis import HealthCheck, Phase, given, seed, settings  # noqa: E402
from hypothesis import strategies as st  # noqa: E402

from tests.pipeline_fuzz import cases, run_case, write_bags  # noqa: E402


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n", 1)[0])
    parser.add_argument("--cases", type=int, default=300)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--keep", type=Path, help="Write one configuration per crash here.")
    args = parser.parse_args()
    statuses: collections.Counter[str] = collections.Counter()
    crashes: dict[str, list[tuple[bytes, dict[str, bytes]]]] = collections.defaultdict(list)
    done = 0
    with tempfile.TemporaryDirectory() as folder:
        bags = write_bags(Path(folder) / "bags")

        @seed(args.seed)
        @settings(
            max_examples=args.cases,
            deadline=None,
            database=None,
            phases=[Phase.generate],
            suppress_health_check=list(HealthCheck),
        )
        @given(data=st.data())
        def one(data: st.DataObject) -> None:
            nonlocal done
            config, replayed, files = data.draw(cases(bags))
            bag = bags[replayed] if replayed in bags else Path(replayed)
            outcome = run_case(config, bag, None, files)
            done += 1
            statuses[" ".join(f"{k}={v}" for k, v in outcome.statuses.items())] += 1
            if outcome.crash is not None:
                crashes[outcome.crash].append((config, files))

        started = time.monotonic()
        one()
        seconds = time.monotonic() - started
    print(f"cases: {done}")
    print("how far they went (exit statuses):")
    for text, count in statuses.most_common():
        print(f"  {count:5d}  {text}")
    total = sum(len(v) for v in crashes.values())
    print(f"crashes: {total} ({len(crashes)} distinct)")
    for index, (crash, configs) in enumerate(sorted(crashes.items())):
        print(f"  {len(configs):5d}  {crash}")
        if args.keep is not None:
            args.keep.mkdir(parents=True, exist_ok=True)
            config, files = configs[0]
            (args.keep / f"crash-{index:02d}.xml").write_bytes(config)
            for name, content in files.items():
                (args.keep / f"crash-{index:02d}-{name}").write_bytes(content)
    print(f"time: {seconds:.1f} s ({seconds / max(done, 1):.2f} s per case)")
    return 1 if total else 0


if __name__ == "__main__":
    sys.exit(main())
