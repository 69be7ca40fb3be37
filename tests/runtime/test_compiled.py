"""The compiled kernel clears exactly the samples in which numpy's checks find nothing.

The kernel (:func:`imrosc.runtime.compiled.clears`) is plain Python that numba compiles, so
it is tested twice: uncompiled here, against :meth:`Checks._numeric` on points of every
family (inferred from planted data, as in ``test_checks``) and on points of many polygons
(the hulls of ``test_polygons``, with each size of grid); and compiled, under Debian's
python where ``make test`` installs ``python3-numba``, against its uncompiled answers and
the checks' violations with numba turned off (``IMROSC_NUMBA=0``).
"""

from __future__ import annotations

import json
import math
import subprocess
from pathlib import Path
from typing import Any

import numpy as np
import numpy.typing as npt
import pytest

import imrosc.runtime
from imrosc.runtime import checks as checks_module
from imrosc.runtime import polygons as polygon_module
from imrosc.runtime.checks import Checks
from imrosc.runtime.compiled import clears as python_clears
from imrosc.runtime.compiled import compile_checks, numba_module
from tests.live.harness import ROS_PYTHON, _clean_environment, ros_python_version_of
from tests.runtime.support import (
    NUMERIC,
    clouds_over,
    hull_polygons,
    infer,
    inv,
    on_the_tolerance,
    planted,
)

RUNTIME = Path(imrosc.runtime.__file__).parent

Case = dict[str, Any]
"""``invariants``, ``index`` (numeric names to positions) and ``queries`` (samples)."""


def every_family(seed: int) -> Case:
    """Every family, inferred from planted columns; queries on and off the data, some
    values missing or infinite."""
    rng = np.random.default_rng(seed)
    columns = planted(rng, 120, [1.0, 1e-6, 1e6][seed % 3])
    invariants = infer(columns, 1000)
    data = np.stack([columns[name] for name in NUMERIC], axis=1)
    return {
        "invariants": invariants,
        "index": {name: k for k, name in enumerate(NUMERIC)},
        "queries": queries(rng, data, holes=True),
    }


def hulls(seed: int, shape: str, variables: int) -> Case:
    """The hulls of every pair of ``variables`` random columns."""
    rng = np.random.default_rng(seed)
    clouds, data = clouds_over(rng, variables, 200, shape)
    shapes, _, _ = hull_polygons(clouds)
    invariants = [
        inv(f"p{k}", "polygon", "hull", [f"v{x}", f"v{y}"], **made["params"])
        for k, ((x, y), made) in enumerate(zip(clouds, shapes, strict=True))
    ]
    index = {f"v{k}": k for k in range(variables)}
    return {"invariants": invariants, "index": index, "queries": queries(rng, data, holes=False)}


def queries(rng: np.random.Generator, data: npt.NDArray[Any], holes: bool) -> list[list[float]]:
    """The training samples, samples near them (one value or all; one value zero), on
    their edges and far off, and (``holes``) some with a value missing or infinite."""
    finite = data[np.isfinite(data).all(axis=1)]
    low, high = finite.min(axis=0), finite.max(axis=0)
    span = np.where(high > low, high - low, 1.0)
    picked = finite[rng.integers(0, len(finite), 80)]
    nudged = finite[rng.integers(0, len(finite), 80)]  # one value a little off: a relation
    column = rng.integers(0, data.shape[1], 80)
    nudged[np.arange(80), column] += rng.choice([-1e-6, 1e-6], 80) * span[column]
    zeroed = finite[rng.integers(0, len(finite), 40)]  # one value zero: non-zero
    zeroed[np.arange(40), rng.integers(0, data.shape[1], 40)] = 0.0
    made = [
        *data[:60],
        *nudged,
        *zeroed,
        *(picked * (1 + rng.normal(0, 1e-12, picked.shape))),
        *(picked + rng.normal(0, 0.03, picked.shape) * span),
        *(low + rng.uniform(-0.1, 1.1, (80, data.shape[1])) * span),
    ]
    if holes:
        for k in range(0, len(made), 7):
            made[k] = made[k].copy()
            made[k][rng.integers(0, data.shape[1])] = rng.choice([math.nan, math.inf, -math.inf])
    return [list(map(float, q)) for q in made]


def cases() -> list[Case]:
    return [
        *(every_family(seed) for seed in range(3)),
        hulls(1, "walk", 6),
        hulls(2, "ints", 5),
        hulls(3, "mixed", 7),
        hulls(4, "", 8),
    ]


def build(case: Case) -> Checks:
    return Checks(case["invariants"], case["index"], {"mode": 0}, ["avg(a)"])


@pytest.mark.parametrize("budget", [polygon_module.TABLE_BUDGET, 200_000, 40_000])
def test_the_kernel_clears_the_samples_that_break_nothing(
    budget: int, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Uncompiled, on every case; ``budget`` makes the polygons' grids 64, 32 and 8 cells a
    side (the coarse bits' shift 3, 2, 0)."""
    monkeypatch.setattr(polygon_module, "TABLE_BUDGET", budget)
    counts = {"cleared": 0, "broken": 0}
    for case in cases():
        checks = build(case)
        tables = checks.tables()
        polygons = checks.polygon_checks
        for sample in case["queries"]:
            row = np.asarray(sample)
            with np.errstate(all="ignore"):
                cleared = bool(python_clears(row, *tables))
                found = [v.invariant for v in checks._numeric(0.0, "p", row)]
            counts["cleared" if cleared else "broken"] += 1
            if cleared:
                assert not found, (sample, found)  # never clears a violation
                continue
            if found:
                continue
            # not cleared, nothing found: only where numpy's exact paths decide
            outside = polygons.count and not polygons.in_range(row)
            edge = any(on_the_tolerance(i, row) for i in case["invariants"])
            assert outside or edge, sample
    assert counts["cleared"] > 300 and counts["broken"] > 300, counts


def test_the_coarse_bits_cover_the_fine_ones(monkeypatch: pytest.MonkeyPatch) -> None:
    """A sample whose coarse cell is clear is in no fine cell near an edge."""
    for budget in (polygon_module.TABLE_BUDGET, 200_000, 40_000):
        monkeypatch.setattr(polygon_module, "TABLE_BUDGET", budget)
        checks = build(hulls(5, "walk", 7)).polygon_checks
        _, shapes, shift = checks.compiled()
        fine = checks.grid << polygon_module._SPLIT
        assert fine >> shift == 16
        for j, shape in enumerate(shapes):
            words = np.asarray(shape.coarse, dtype=np.int32).view(np.uint32)
            coarse = np.unpackbits(words.view(np.uint8), bitorder="little").reshape(16, 16)
            steps = np.arange(fine)
            near = checks.bits[checks.fine_base[j] + steps[:, None] + 256 * steps[None, :]]
            near = (near & checks.bit[j]) != 0  # [column cell, row cell]
            cells = near.reshape(16, fine >> 4, 16, fine >> 4).any(axis=(1, 3))
            assert (coarse == cells.T).all()  # [row, column], bit column + 16 * row
            assert near.any() and not near.all()


SCRIPT = r"""
import json, os, sys
import numpy as np
sys.path.insert(0, sys.argv[1])
from runtime.checks import Checks
from runtime.compiled import clears
np.seterr(all="ignore")
out = []
for case in json.load(open(sys.argv[2])):
    build = lambda: Checks(case["invariants"], case["index"], {"mode": 0}, ["avg(a)"])
    compiled = build()
    assert compiled._clears is not None, "numba did not compile the checks"
    os.environ["IMROSC_NUMBA"] = "0"
    plain = build()
    del os.environ["IMROSC_NUMBA"]
    assert plain._clears is None
    later = Checks(case["invariants"], case["index"], {"mode": 0}, ["avg(a)"], compile=False)
    assert not later.compiled and later.compile() and later.compiled
    answers = []
    for sample in case["queries"]:
        row = np.asarray(sample, dtype=np.float64)
        data = row.tobytes()
        kinds = [row, np.frombuffer(data), np.frombuffer(b"\0" + data, offset=1)]
        got = {bool(compiled._clears(r, *compiled._tables)) for r in kinds}
        assert got == {bool(clears(row, *compiled._tables))}, sample
        with_numba = [v.invariant for v in compiled.check(0.0, "p", kinds[2], ["idle"])]
        without = [v.invariant for v in plain.check(0.0, "p", row, ["idle"])]
        assert [v.invariant for v in later.check(0.0, "p", row, ["idle"])] == with_numba
        answers.append([got.pop(), with_numba, without])
    out.append(answers)
print(json.dumps(out))
"""


def debian_numba() -> None:
    """Skip unless Debian's python imports numba (``make test`` installs python3-numba)."""
    if ros_python_version_of("numba") is None:
        pytest.skip(f"{ROS_PYTHON} cannot import numba (apt-get install python3-numba)")


def test_compiled_the_kernel_answers_as_uncompiled_and_the_violations_are_numpys(
    tmp_path: Path,
) -> None:
    debian_numba()
    package = tmp_path / "runtime"
    package.mkdir()
    for module in RUNTIME.glob("*.py"):
        (package / module.name).write_bytes(module.read_bytes())
    made = cases()
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
    cleared = 0
    for case, answers in zip(made, json.loads(done.stdout), strict=True):
        by_id = {i["id"]: i for i in case["invariants"]}
        for sample, (clear, with_numba, without) in zip(case["queries"], answers, strict=True):
            cleared += clear
            if with_numba != without:  # a relation on its tolerance: summation orders
                differ = set(with_numba) ^ set(without)
                assert all(on_the_tolerance(by_id[i], np.asarray(sample)) for i in differ)
    assert cleared > 300


def test_turned_off_nothing_is_compiled(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("IMROSC_NUMBA", "0")
    assert numba_module() is None
    checks = build(every_family(0))
    assert checks._clears is None
    assert compile_checks(checks.tables(), len(checks.index)) is None


def test_compiling_waits_until_asked_and_the_violations_stay_the_same(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """``compile=False`` (what the monitor nodes do, to compile in a thread of their own):
    numpy checks until :meth:`Checks.compile`, which compiles once; the kernel (here the
    uncompiled one, standing in for numba's) then clears the samples, and every sample's
    violations are the same before and after."""
    kernels: list[Any] = []

    def compile_checks(tables: Any, width: int) -> Any:
        kernels.append(tables)
        return python_clears

    monkeypatch.setattr(checks_module, "numba_module", object)
    monkeypatch.setattr(checks_module, "compile_checks", compile_checks)
    case = hulls(1, "walk", 6)
    later = Checks(case["invariants"], case["index"], {"mode": 0}, ["avg(a)"], compile=False)
    assert not later.compiled and not kernels

    def violations() -> list[list[str]]:
        return [
            [v.invariant for v in later.check(0.0, "p", np.asarray(q, dtype=np.float64))]
            for q in case["queries"]
        ]

    before = violations()
    assert later.compile() and later.compiled and len(kernels) == 1
    assert later.compile() and len(kernels) == 1  # once
    assert violations() == before
    assert any(before) and not all(before)


def test_without_numba_compiling_later_leaves_numpy_checking(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    monkeypatch.setenv("IMROSC_NUMBA", "0")
    case = hulls(2, "ints", 5)
    later = Checks(case["invariants"], case["index"], {"mode": 0}, ["avg(a)"], compile=False)
    assert not later.compile() and not later.compiled
