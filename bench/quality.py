"""Quality of Daikon's families on a generated point with planted properties.

    python bench/quality.py [--rows 20000] [--seed 7] [--chunk 4096]

The point holds ranges, a constant, a one-of set, a string set, a non-zero integer, an
equal copy, ``y = 2*x + 3``, ``z = x - 2*m + 1``, ``lead < lag``, a positive variable and its
negation, array statistics and independent uniform noise. Every Daikon family runs on it
(``imrosc.infer.daikon.make_states``, chunks of ``--chunk`` rows) and the script prints:

* **recovered**: planted properties reported, or implied by what is reported. A range
  counts when a bound pair lies inside the planted range within 1 % of its width of each
  end; ``p > 0`` when ``p``'s reported lower bound is positive; ``lead < lag`` when the
  order is reported or the reported bounds imply it; a linear or ternary relation only
  when its text is exactly the planted one ("coefficients printed as written"); sets and
  equalities when reported with exactly the planted members.
* **not implied by the plan**: a reported bound is implied when it lies inside the planted
  support of its variable (interval arithmetic for derived variables); any other
  invariant is implied when it holds on a fresh sample of the plan 10 times larger, plus
  rows where every uniform draw sits at an end of its range.

Targets: every planted property recovered, at most 5 % of reported invariants not implied.
"""

from __future__ import annotations

import argparse
import sys
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import numpy.typing as npt

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from imrosc.infer.core import FinalizeContext, Invariant, Samples, Variable  # noqa: E402
from imrosc.infer.daikon import FAMILIES, make_states  # noqa: E402
from imrosc.ir import Tunables  # noqa: E402

Columns = dict[str, npt.NDArray[Any]]
NOISE = 20
ARRAY = 8
POINT = "bench"


@dataclass(frozen=True)
class Planted:
    """A planted property and how to tell it was recovered."""

    label: str
    recovered: Callable[[list[Invariant]], Invariant | None]


class Draw:
    """Uniform draws, or draws at the ends of each range (the corner rows)."""

    def __init__(self, rng: np.random.Generator, rows: int, *, corners: bool) -> None:
        self.rng = rng
        self.rows = rows
        self.corners = corners

    def uniform(self, lo: float, hi: float, shape: tuple[int, ...] = ()) -> npt.NDArray[np.float64]:
        size = (self.rows, *shape)
        if self.corners:
            return np.asarray(self.rng.choice([lo, hi], size=size), dtype=np.float64)
        return self.rng.uniform(lo, hi, size=size)

    def choice(self, values: list[Any]) -> npt.NDArray[Any]:
        return np.asarray(self.rng.choice(np.array(values, dtype=object), size=self.rows))


def noise_ranges(seed: int) -> list[tuple[float, float]]:
    """Ranges of the noise variables (overlapping, at least 2 wide)."""
    rng = np.random.default_rng(seed + 1000)
    out = []
    for _ in range(NOISE):
        lo = float(np.round(rng.uniform(-10, 6), 2))
        out.append((lo, float(np.round(lo + rng.uniform(2, 4), 2))))
    return out


def variables() -> tuple[Variable, ...]:
    """The point's variables, in order."""
    found = [
        Variable("r1", "float"),
        Variable("r2", "float"),
        Variable("k", "float"),
        Variable("mode", "int"),
        Variable("nz", "int"),
        Variable("state", "string"),
        Variable("x", "float"),
        Variable("x_copy", "float"),
        Variable("y", "float"),
        Variable("m", "float"),
        Variable("z", "float"),
        Variable("lead", "float"),
        Variable("lag", "float"),
        Variable("p", "float"),
        Variable("q", "float"),
    ]
    found += [Variable(f"n{i}", "float") for i in range(NOISE)]
    found += [
        Variable(f"{stat}(scan)", "uint" if stat == "len" else "float", path="scan", derived=stat)
        for stat in ("len", "avg", "std", "min", "max")
    ]
    return tuple(found)


def generate(draw: Draw, seed: int) -> Columns:
    """The columns of the planted point."""
    nonzero = [v for v in range(-20, 21) if v != 0]
    x = draw.uniform(0, 10)
    m = draw.uniform(-5, 5)
    lead = draw.uniform(0, 10)
    p = draw.uniform(0.5, 3)
    scan = draw.uniform(0.1, 30, (ARRAY,))
    columns: Columns = {
        "r1": draw.uniform(-1, 5),
        "r2": draw.uniform(0.25, 0.75),
        "k": np.full(draw.rows, 4.5),
        "mode": draw.choice([1.0, 2.0, 3.0]).astype(np.float64),
        "nz": draw.choice([float(v) for v in nonzero]).astype(np.float64),
        "state": draw.choice(["idle", "run"]),
        "x": x,
        "x_copy": x.copy(),
        "y": 2 * x + 3,
        "m": m,
        "z": x - 2 * m + 1,
        "lead": lead,
        "lag": lead + draw.uniform(0.5, 2),
        "p": p,
        "q": -p,
    }
    for i, (lo, hi) in enumerate(noise_ranges(seed)):
        columns[f"n{i}"] = draw.uniform(lo, hi)
    columns["len(scan)"] = np.full(draw.rows, float(ARRAY))
    columns["avg(scan)"] = scan.mean(axis=1)
    columns["std(scan)"] = scan.std(axis=1)
    columns["min(scan)"] = scan.min(axis=1)
    columns["max(scan)"] = scan.max(axis=1)
    return columns


def supports(seed: int) -> dict[str, tuple[float, float]]:
    """Where each numeric variable can lie according to the plan."""
    found = {
        "r1": (-1.0, 5.0),
        "r2": (0.25, 0.75),
        "k": (4.5, 4.5),
        "mode": (1.0, 3.0),
        "nz": (-20.0, 20.0),
        "x": (0.0, 10.0),
        "x_copy": (0.0, 10.0),
        "y": (3.0, 23.0),
        "m": (-5.0, 5.0),
        "z": (-9.0, 21.0),
        "lead": (0.0, 10.0),
        "lag": (0.5, 12.0),
        "p": (0.5, 3.0),
        "q": (-3.0, -0.5),
        "len(scan)": (ARRAY, ARRAY),
        "avg(scan)": (0.1, 30.0),
        "std(scan)": (0.0, (30.0 - 0.1) / 2),
        "min(scan)": (0.1, 30.0),
        "max(scan)": (0.1, 30.0),
    }
    for i, bounds in enumerate(noise_ranges(seed)):
        found[f"n{i}"] = bounds
    return found


def infer(columns: Columns, chunk: int) -> list[Invariant]:
    """Every Daikon family over the point, fed in chunks."""
    point_variables = variables()
    tunables = Tunables()
    states = make_states(point_variables, tunables, frozenset(FAMILIES))
    rows = len(columns["x"])
    for start in range(0, rows, chunk):
        stop = min(rows, start + chunk)
        samples = Samples(
            POINT,
            0,
            np.arange(start, stop, dtype=np.float64) * 0.01,
            {name: column[start:stop] for name, column in columns.items()},
            point_variables,
        )
        for state in states:
            state.update(samples)
    for state in states:
        state.end_run()
    context = FinalizeContext(tunables, point_variables, POINT, None, 1)
    return [invariant for state in states for invariant in state.finalize(context)]


# -- recovery ---------------------------------------------------------------------------------


def _find(found: list[Invariant], test: Callable[[Invariant], bool]) -> Invariant | None:
    return next((inv for inv in found if test(inv)), None)


def planted_range(name: str, lo: float, hi: float) -> Planted:
    slack = 0.01 * (hi - lo)

    def test(inv: Invariant) -> bool:
        if inv.variables != (name,) or inv.kind != "range":
            return False
        low, high = inv.params["min"], inv.params["max"]
        return bool(lo <= low <= lo + slack and hi - slack <= high <= hi)

    return Planted(f"range {lo:g} <= {name} <= {hi:g}", lambda found: _find(found, test))


def planted_lower(name: str, lo: float, label: str) -> Planted:
    def test(inv: Invariant) -> bool:
        return (
            inv.variables == (name,) and inv.kind in ("range", "lower") and inv.params["min"] >= lo
        )

    return Planted(label, lambda found: _find(found, test))


def planted_set(name: str, values: list[Any], family: str) -> Planted:
    def test(inv: Invariant) -> bool:
        return (
            inv.family == family
            and inv.variables == (name,)
            and list(inv.params["values"]) == values
        )

    shown = "{" + ", ".join(str(v) for v in values) + "}"
    return Planted(f"{family} {name} in {shown}", lambda found: _find(found, test))


def planted_text(family: str, text: str) -> Planted:
    return Planted(f"{family} {text}", lambda found: _find(found, lambda i: i.text == text))


def planted_equal(names: tuple[str, ...]) -> Planted:
    def test(inv: Invariant) -> bool:
        return inv.family == "equality" and inv.variables == names

    return Planted("equality " + " == ".join(names), lambda found: _find(found, test))


def planted_less(small: str, large: str) -> Planted:
    def test(inv: Invariant) -> bool:
        return inv.family == "order" and inv.variables == (small, large) and inv.kind == "<"

    def recovered(found: list[Invariant]) -> Invariant | None:
        reported = _find(found, test)
        if reported is not None:
            return reported
        upper = _find(found, lambda i: i.variables == (small,) and "max" in i.params)
        lower = _find(found, lambda i: i.variables == (large,) and "min" in i.params)
        if upper is not None and lower is not None and upper.params["max"] < lower.params["min"]:
            return upper
        return None

    return Planted(f"order {small} < {large}", recovered)


def plan() -> list[Planted]:
    """The planted properties of the supported families."""
    return [
        planted_range("r1", -1, 5),
        planted_range("r2", 0.25, 0.75),
        planted_set("k", [4.5], "one-of"),
        planted_set("mode", [1.0, 2.0, 3.0], "one-of"),
        planted_text("non-zero", "nz != 0"),
        planted_range("nz", -20, 20),
        planted_set("state", ["idle", "run"], "string-one-of"),
        planted_range("x", 0, 10),
        planted_equal(("x", "x_copy")),
        planted_text("linear", "y = 2*x + 3"),
        planted_range("m", -5, 5),
        planted_text("ternary", "z = x - 2*m + 1"),
        planted_less("lead", "lag"),
        planted_lower("p", 0.5, "p > 0 (bounds)"),
        planted_text("linear", "q = -p"),
        planted_text("array", "len(scan) == 8"),
        planted_lower("min(scan)", 0.1, "array scan[] elements >= 0.1"),
        Planted(
            "array scan[] elements <= 30",
            lambda found: _find(
                found, lambda i: i.variables == ("max(scan)",) and i.params.get("max", 99) <= 30
            ),
        ),
    ]


# -- implication ------------------------------------------------------------------------------


def holds(inv: Invariant, columns: Columns) -> bool:
    """Whether a relation-like invariant holds on every row of ``columns``."""
    params = inv.params
    values = [columns[name] for name in inv.variables]
    if inv.kind in ("one-of", "string-one-of"):
        return set(values[0].tolist()) <= set(params["values"])
    if inv.kind == "!=0":
        return bool(np.all(values[0] != 0))
    if inv.kind == "==":
        return all(bool(np.all(v == values[0])) for v in values[1:])
    if inv.kind == "<":
        return bool(np.all(values[0] < values[1]))
    if inv.kind == "<=":
        return bool(np.all(values[0] <= values[1]))
    if inv.kind == "linear":
        residual = values[0] - (params["a"] * values[1] + params["b"])
        return bool(np.all(np.abs(residual) <= params["tolerance"]))
    if inv.kind == "ternary":
        fitted = params["a"] * values[1] + params["b"] * values[2] + params["c"]
        return bool(np.all(np.abs(values[0] - fitted) <= params["tolerance"]))
    raise ValueError(f"no check for {inv.kind}")


def implied(inv: Invariant, support: dict[str, tuple[float, float]], stress: Columns) -> bool:
    """Whether the plan implies a reported invariant (see the module docstring)."""
    if inv.kind in ("lower", "upper", "range"):
        lo, hi = support[inv.variables[0]]
        return bool(inv.params.get("min", lo) >= lo and inv.params.get("max", hi) <= hi)
    return holds(inv, stress)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--rows", type=int, default=20000)
    parser.add_argument("--chunk", type=int, default=4096)
    parser.add_argument("--seed", type=int, default=7)
    args = parser.parse_args(argv)

    rng = np.random.default_rng(args.seed)
    columns = generate(Draw(rng, args.rows, corners=False), args.seed)
    started = time.perf_counter()
    found = infer(columns, args.chunk)
    elapsed = time.perf_counter() - started

    planted = plan()
    recovered = 0
    print(f"planted properties ({args.rows} rows, {len(variables())} variables):")
    for item in planted:
        match = item.recovered(found)
        recovered += match is not None
        shown = match.text if match is not None else "-"
        print(f"  [{'x' if match else ' '}] {item.label:<34} {shown}")

    fresh = generate(
        Draw(np.random.default_rng(args.seed + 1), 10 * args.rows, corners=False), args.seed
    )
    corners = generate(Draw(np.random.default_rng(args.seed + 2), 4096, corners=True), args.seed)
    stress = {name: np.concatenate([fresh[name], corners[name]]) for name in fresh}
    support = supports(args.seed)
    spurious = [inv for inv in found if not implied(inv, support, stress)]
    share = 100.0 * len(spurious) / max(1, len(found))
    print(f"recovered: {recovered}/{len(planted)} planted properties")
    print(
        f"reported: {len(found)} invariants in {elapsed:.2f} s; not implied by the plan: "
        f"{len(spurious)} ({share:.1f} %)"
    )
    for inv in spurious:
        print(f"  not implied: {inv.text}")
    ok = recovered == len(planted) and share <= 5.0
    print("PASS" if ok else "FAIL")
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
