"""The polygons' lookup compiled by numba finds numpy's candidates and the half-planes' answers.

numba lives where the monitor runs: Debian's ``python3-numba`` beside rospy (``make test``
installs it with ROS 1). The cases are made here (hulls over random clouds, as in
``test_polygons``); the checks are built under Debian's python twice, compiled and with
``IMROSC_NUMBA=0``, and asked every sample: the compiled lookup's candidates must be numpy's,
and its answers every edge's plain evaluation.
"""

from __future__ import annotations

import json
import subprocess
from pathlib import Path
from typing import Any

import numpy as np
import pytest

import imrosc.runtime
from imrosc.runtime.compiled import candidate_lookup
from tests.live.harness import ROS_PYTHON, _clean_environment
from tests.runtime.test_polygons import clouds_over, expected, hull_polygons

RUNTIME = Path(imrosc.runtime.__file__).parent

SCRIPT = r"""
import json, os, sys
import numpy as np
sys.path.insert(0, sys.argv[1])
from runtime.polygons import PolygonChecks
np.seterr(all="ignore")
answers = []
for case in json.load(open(sys.argv[2])):
    edges = [tuple(e) for e in case["edges"]]
    compiled = PolygonChecks(case["polygons"], edges)
    assert compiled._lookup is not None, "numba did not compile the lookup"
    os.environ["IMROSC_NUMBA"] = "0"
    plain = PolygonChecks(case["polygons"], edges)
    del os.environ["IMROSC_NUMBA"]
    assert plain._lookup is None
    found = []
    for sample in case["samples"]:
        row = np.asarray(sample, dtype=np.float64)
        readonly = row.copy()
        readonly.setflags(write=False)  # a monitor's values: a view of the bytes
        first = compiled.broken(row)
        assert first == compiled.broken(readonly, compiled.in_range(row)), sample
        assert first == plain.broken(row), sample
        if compiled.in_range(row):
            n = compiled._lookup(row, compiled._offsets, compiled._found)
            plain.forget()
            plain.broken(row, True)
            assert compiled._found[:n].tolist() == plain._last[0].tolist(), sample
            assert compiled._offsets.tolist() == plain._last[1].tolist(), sample
        found.append(first)
    answers.append(found)
print(json.dumps(answers))
"""


def debian_numba() -> None:
    """Skip unless Debian's python imports numba (``make test`` installs python3-numba)."""
    if not ROS_PYTHON.exists():
        pytest.skip(f"{ROS_PYTHON} is missing")
    probe = subprocess.run(
        [str(ROS_PYTHON), "-c", "import numba"],
        capture_output=True,
        text=True,
        check=False,
        timeout=120,
        env=_clean_environment(),
    )
    if probe.returncode != 0:
        pytest.skip("Debian's python has no numba (apt-get install python3-numba)")


def case(seed: int, shape: str, variables: int) -> tuple[dict[str, Any], list[list[int]]]:
    """Polygons over random clouds and samples in, near and out of them; the answers of
    every edge evaluated plainly."""
    rng = np.random.default_rng(seed)
    clouds, data = clouds_over(rng, variables, 200, shape)
    polygons, edges, plain = hull_polygons(clouds)
    low, high = data.min(axis=0), data.max(axis=0)
    span = np.where(high > low, high - low, 1.0)
    picked = data[rng.integers(0, len(data), 60)]
    queries = [
        *data[:40],  # training samples: inside everything
        *(low + rng.uniform(-0.1, 1.1, (200, variables)) * span),  # in and out of range
        *(picked * (1 + rng.normal(0, 1e-12, (60, variables)))),  # on the hulls' edges
        *(picked + rng.normal(0, 0.05, (60, variables)) * span),  # near them
    ]
    samples = [q.tolist() for q in queries]
    made = {"polygons": polygons, "edges": edges, "samples": samples}
    return made, [expected(plain, s) for s in samples]


def test_the_compiled_lookup_answers_as_numpy_and_the_half_planes(tmp_path: Path) -> None:
    debian_numba()
    package = tmp_path / "runtime"
    package.mkdir()
    for module in RUNTIME.glob("*.py"):
        (package / module.name).write_bytes(module.read_bytes())
    made, truth = [], []
    for seed, shape, variables in ((1, "walk", 6), (2, "ints", 5), (3, "mixed", 7), (4, "", 8)):
        one, answers = case(seed, shape, variables)
        made.append(one)
        truth.append(answers)
    (tmp_path / "cases.json").write_text(json.dumps(made), encoding="utf-8")
    done = subprocess.run(
        [str(ROS_PYTHON), "-c", SCRIPT, str(tmp_path), str(tmp_path / "cases.json")],
        capture_output=True,
        text=True,
        check=False,
        timeout=600,
        env=_clean_environment(),
    )
    assert done.returncode == 0, done.stdout + done.stderr
    assert json.loads(done.stdout) == truth
    assert sum(1 for answers in truth for found in answers if found) > 50  # many break some


def test_turned_off_the_lookup_is_numpys(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("IMROSC_NUMBA", "0")
    table = np.zeros(8, dtype=np.uint8)
    assert candidate_lookup(1, table[:1], table[:1], table[:2], table[:1], table, table) is None
