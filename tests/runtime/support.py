"""What the runtime tests share: invariants by hand, points inferred from planted rows,
polygons of point clouds."""

from __future__ import annotations

import json
import math
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np
import numpy.typing as npt

from imrosc.infer.core import FinalizeContext, Samples, Variable
from imrosc.infer.polygon.hull import GroupSet, hulls
from imrosc.infer.polygon.state import half_planes
from imrosc.infer.registry import DAIKON_FAMILIES, make_point_states
from imrosc.invariants import document, dumps
from imrosc.ir import Tunables
from imrosc.translate.points import PointSpec

POINT = "p"


def inv(
    ident: str, family: str, kind: str, variables: Sequence[str], **params: Any
) -> dict[str, Any]:
    return {
        "id": ident,
        "family": family,
        "kind": kind,
        "point": POINT,
        "variables": list(variables),
        "params": params,
        "text": f"{ident} text",
    }


NUMERIC = ("x", "y", "z", "m", "k", "nz", "flag", "u", "v", "avg(a)")


def variables() -> tuple[Variable, ...]:
    kinds = {"k": "int", "nz": "int", "flag": "bool", "mode": "string"}
    found = [
        Variable(name, kinds.get(name, "float"), topic="/t", path=name)  # type: ignore[arg-type]
        for name in (*NUMERIC[:-1], "mode")
    ]
    found.append(Variable("avg(a)", "float", topic="/t", path="a", derived="avg"))
    return tuple(found)


def infer(columns: Mapping[str, npt.NDArray[Any]], chunk: int) -> list[dict[str, Any]]:
    chosen = variables()
    spec = PointSpec(POINT, "publish", chosen, (*sorted(DAIKON_FAMILIES), "polygon"), "/t")
    states = make_point_states(spec, Tunables())
    n = len(columns["x"])
    for start in range(0, n, chunk):
        part = {name: column[start : start + chunk] for name, column in columns.items()}
        time = np.arange(start, start + len(part["x"]), dtype=np.float64) * 0.01
        samples = Samples(POINT, 0, time, part, chosen)
        for state in states:
            state.update(samples)
    for state in states:
        state.end_run()
    context = FinalizeContext(Tunables(), chosen, POINT)
    found = [i for state in states for i in state.finalize(context)]
    doc = document(
        project="t", source="t.xml", bags=[], tunables={}, topics={}, points=[], invariants=found
    )
    loaded: list[dict[str, Any]] = json.loads(dumps(doc))["invariants"]
    return loaded


def planted(rng: np.random.Generator, n: int, scale: float = 1.0) -> dict[str, npt.NDArray[Any]]:
    """``n`` rows of columns that give every family (``scale``: of ``x`` and the
    relations on it)."""
    x = rng.uniform(-5, 5, n) * scale
    m = rng.uniform(0, 1, n)
    return {
        "x": x,
        "y": 2.5 * x + 3,
        "z": x - 2 * m + 1,
        "m": m,
        "k": rng.choice([1.0, 2.0, 3.0], n),
        "nz": rng.choice([-3.0, -1.0, 2.0, 5.0], n),
        "flag": rng.choice([0.0, 1.0], n),
        "u": x + rng.uniform(0, 1, n),
        "v": rng.uniform(0, 1, n) * (x - x.min() + 1),
        "avg(a)": rng.uniform(1, 2, n),
        "mode": rng.choice(np.array(["idle", "run"], dtype=object), n),
    }


def on_the_tolerance(inv: Mapping[str, Any], sample: npt.NDArray[np.float64]) -> bool:
    """Whether a linear or ternary relation's residual on ``sample`` is within rounding of
    the tolerance the check allows (1.25 times the stated one)."""
    if inv["family"] not in ("linear", "ternary"):
        return False
    values = [float(sample[NUMERIC.index(n)]) for n in inv["variables"]]
    params = inv["params"]
    names = ("a", "b") if inv["family"] == "linear" else ("a", "b", "c")
    coefficients = [float(params[n]) for n in names]
    terms = (
        [values[0]]
        + [-c * v for c, v in zip(coefficients[:-1], values[1:], strict=True)]
        + [-coefficients[-1]]
    )
    residual = math.fsum(terms)
    limit = 1.25 * float(params["tolerance"])
    return abs(abs(residual) - limit) <= 1e-14 * sum(abs(t) for t in terms)


def hull(points: npt.NDArray[np.float64]) -> npt.NDArray[np.float64]:
    """Counter-clockwise convex hull, collinear points dropped (inference's exact hull)."""
    n = len(points)
    cloud = GroupSet(np.zeros(n, np.int64), points[:, 0], points[:, 1], np.arange(n))
    found = hulls(cloud)
    return np.stack([found.x, found.y], axis=1)


def polygon(vertices: npt.NDArray[np.float64]) -> dict[str, Any]:
    normals, offsets, _ = half_planes(vertices)
    return {"params": {"vertices": vertices.tolist(), "A": normals.tolist(), "b": offsets.tolist()}}


Plain = list[tuple[int, int, Any, Any, Any]]


Edges = list[tuple[int, int, float, float, float, int]]


def hull_polygons(
    clouds: dict[tuple[int, int], npt.NDArray[np.float64]],
) -> tuple[list[dict[str, Any]], Edges, Plain]:
    """The polygon invariants of the hulls of ``clouds`` (keyed by the variables'
    positions), their edges as ``PolygonChecks`` takes them, and each polygon's ``(x, y, a,
    b, c)`` for the plain evaluation."""
    invariants: list[dict[str, Any]] = []
    edges: Edges = []
    plain: Plain = []
    for owner, ((x, y), cloud) in enumerate(clouds.items()):
        inv = polygon(hull(cloud))
        invariants.append(inv)
        a, b = np.asarray(inv["params"]["A"]).T
        c = np.asarray(inv["params"]["b"])
        plain.append((x, y, a, b, c))
        edges += [
            (x, y, float(ai), float(bi), float(ci), owner)
            for ai, bi, ci in zip(a, b, c, strict=True)
        ]
    return invariants, edges, plain


def clouds_over(
    rng: np.random.Generator, variables: int, n: int, shape: str
) -> tuple[dict[tuple[int, int], npt.NDArray[np.float64]], npt.NDArray[np.float64]]:
    """Samples of ``variables`` columns, and the clouds of every pair of them."""
    if shape == "walk":
        data = np.cumsum(rng.normal(0, 1, (n, variables)), axis=0)
    elif shape == "ints":
        data = rng.integers(0, 5, (n, variables)).astype(np.float64)
    elif shape == "mixed":
        data = rng.normal(0, 1, (n, variables))
        data[:, 0] = np.abs(data[:, 0])
        data[:, 1] = rng.integers(0, 3, n)
        data[:, 2] = 2 * data[:, 3] + 1e6  # a line far from the origin
    else:
        data = rng.normal(0, 1, (n, variables)) * rng.uniform(1e-3, 1e3, variables)
    pairs = [(i, j) for i in range(variables) for j in range(i + 1, variables)]
    return {(i, j): data[:, [i, j]] for i, j in pairs}, data


def var(name: str, path: str, kind: str = "float", trigger: bool = True) -> dict[str, Any]:
    """A variable of a point as the invariants file lists it."""
    return {"name": name, "type": kind, "path": path, "derived": None, "trigger": trigger}


def point_inv(
    ident: str, point: str, family: str, kind: str, variables: Sequence[str], **params: Any
) -> dict[str, Any]:
    return {
        "id": ident,
        "family": family,
        "kind": kind,
        "point": point,
        "condition": None,
        "variables": list(variables),
        "params": params,
        "text": ident,
    }


def alarm_document(alarms: dict[str, Any] | None) -> dict[str, Any]:
    """A document of one publish point ``x`` (``/a/x``: ``x.v``, ``x.w``) whose two upper
    bounds (``v_max``, ``w_max``: 1.0) are checked under ``alarms`` (``None``: no rule)."""
    doc: dict[str, Any] = {
        "topics": {"/a/x": {"type": "T", "variables": [var("x.v", "v"), var("x.w", "w")]}},
        "points": {
            "x": {
                "kind": "publish",
                "trigger": "/a/x",
                "variables": [var("x.v", "v"), var("x.w", "w")],
            }
        },
        "invariants": [
            point_inv("v_max", "x", "bounds", "upper", ["x.v"], max=1.0),
            point_inv("w_max", "x", "bounds", "upper", ["x.w"], max=1.0),
        ],
    }
    if alarms is not None:
        doc["alarms"] = alarms
    return doc
