"""``imrosc infer`` on two real Crazyflie flights: every family that applies, and every
invariant holds on the data it came from.

The check is an independent oracle written from the documented meaning of each family (not
the inference code): bounds and sets against every sample, relations row by row, polygons as
half-planes, windows recomputed naively, intervals and pattern DFAs replayed event by event.
"""

from __future__ import annotations

import math
import statistics
from collections import Counter
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from imrosc.detect import DetectResult, prepare, run_detect
from imrosc.translate.stream import BagTranslator

ROOT = Path(__file__).resolve().parent.parent
CONFIG = ROOT / "examples" / "crazyflie.xml"
BAGS = ROOT.parent / "shared" / "data" / "real" / "crazyflie"
pytestmark = pytest.mark.skipif(not (BAGS / "sine_1.bag").exists(), reason="shared data missing")

Runs = list[dict[str, Any]]


@pytest.fixture(scope="module")
def inferred() -> DetectResult:
    result = run_detect(CONFIG, workers=2)
    assert result.document is not None, [d.as_text() for d in result.diagnostics]
    assert not result.diagnostics
    return result


@pytest.fixture(scope="module")
def samples() -> dict[str, Runs]:
    """Per point, per run: the time column and every variable's column."""
    prepared, _ = prepare(CONFIG)
    assert prepared is not None
    out: dict[str, Runs] = {}
    for run, bag in enumerate(prepared.catalog.bags):
        translator = BagTranslator(prepared.specs, prepared.layouts, prepared.catalog.callerids)
        gathered: dict[str, dict[str, list[Any]]] = {}
        for chunk in translator.translate(bag, run):
            point = gathered.setdefault(chunk.point, {"time": []})
            point["time"] += chunk.time.tolist()
            for name, column in chunk.columns.items():
                point.setdefault(name, []).extend(column.tolist())
        for key, columns in gathered.items():
            out.setdefault(key, []).append(columns)
    return out


def test_every_family_that_applies_is_found(inferred: DetectResult) -> None:
    assert inferred.document is not None
    families = Counter(i["family"] for i in inferred.document["invariants"])
    expected = {
        "bounds",
        "one-of",
        "string-one-of",
        "frequency",
        "variance",
        "rate",
        "polygon",
        "architecture",
        "interval",
    }
    assert expected <= set(families), expected - set(families)
    texts = {i["text"] for i in inferred.document["invariants"]}
    assert "max_pubs(/cf1/imu) = {/crazyflie_server}" in texts
    frequencies = {
        i["params"]["topic"] for i in inferred.document["invariants"] if i["family"] == "frequency"
    }
    assert {
        "/cf1/imu",
        "/cf1/log_pos",
        "/cf1/log_rpy",
        "/cf1/log_ranges",
        "/cf1/rssi",
    } <= frequencies


def _values(runs: Runs, name: str) -> list[Any]:
    return [v for run in runs for v in run.get(name, [])]


def _numbers(values: list[Any]) -> list[float]:
    return [float(v) for v in values if not (isinstance(v, float) and math.isnan(v))]


def _window_values(
    run: Mapping[str, list[Any]], name: str | None, window: float
) -> list[tuple[list[float], list[float]]]:
    """The (times, values) of every defined window of a run (naive, as documented)."""
    epsilon = min(1e-6, window / 1000)
    span = window - epsilon
    times = run["time"]
    values = run[name] if name else [0.0] * len(times)
    windows = []
    start = 0
    for i, t in enumerate(times):
        while times[start] <= t - span:  # the messages one window old or older leave
            start += 1
        if times[0] <= t - span:  # defined once the run's first message has left
            windows.append((times[start : i + 1], values[start : i + 1]))
    return windows


def _check_value_family(invariant: Mapping[str, Any], runs: Runs) -> None:
    family, kind, params = invariant["family"], invariant["kind"], invariant["params"]
    names = invariant["variables"]
    if family in ("bounds", "array"):
        values = _numbers(_values(runs, names[0]))
        if "min" in params:
            assert min(values) >= float(params["min"])
        if "max" in params:
            assert max(values) <= float(params["max"])
    elif family in ("one-of", "string-one-of"):
        allowed = set(params["values"])
        seen = _values(runs, names[0])
        assert {v for v in seen if not (isinstance(v, float) and math.isnan(v))} <= allowed
    elif family == "equality":
        columns = [_values(runs, n) for n in names]
        for row in zip(*columns, strict=True):
            kept = [v for v in row if not math.isnan(v)]
            assert len(set(kept)) <= 1
    elif family == "order":
        strict = kind == "<"
        for a, b in zip(_values(runs, names[0]), _values(runs, names[1]), strict=True):
            assert math.isnan(a) or math.isnan(b) or (a < b if strict else a <= b)
    elif family == "linear":
        for y, x in zip(_values(runs, names[0]), _values(runs, names[1]), strict=True):
            if not (math.isnan(x) or math.isnan(y)):
                assert abs(y - (params["a"] * x + params["b"])) <= params["tolerance"] * 1.0001
    elif family == "polygon":
        a, b = np.asarray(params["A"], dtype=float), np.asarray(params["b"], dtype=float)
        xs, ys = np.asarray(_values(runs, names[0])), np.asarray(_values(runs, names[1]))
        keep = ~(np.isnan(xs) | np.isnan(ys))
        points = np.stack([xs[keep], ys[keep]])
        slack = 1e-9 * (1 + np.abs(b))[:, None] + 1e-9 * np.abs(a) @ np.abs(points)
        assert np.all(a @ points <= b[:, None] + slack)
    elif family == "non-zero":
        assert all(v != 0 for v in _numbers(_values(runs, names[0])))
    else:
        raise AssertionError(f"no oracle for {family}")


def _check_time_family(invariant: Mapping[str, Any], runs: Runs) -> None:
    params, family = invariant["params"], invariant["family"]
    window = float(params["window"])
    found: list[float] = []
    for run in runs:
        name = None if family == "frequency" else invariant["variables"][0]
        for times, values in _window_values(run, name, window):
            if family == "frequency":
                found.append(len(times) / window)
            elif family == "variance" and len(values) >= 2:
                found.append(statistics.variance(values))
            elif family == "mean" and len(values) >= 2:
                found.append(statistics.fmean(values))
            elif family == "rate" and len(values) >= 2 and times[-1] > times[0]:
                found.append((values[-1] - values[0]) / (times[-1] - times[0]))
            elif family == "step" and len(values) >= 2:
                found.append(values[-1] - values[-2])
    slack = 1e-9 * max(1.0, *(abs(v) for v in found))
    assert min(found) >= float(params["min"]) - slack
    assert max(found) <= float(params["max"]) + slack


def _check_architecture(invariant: Mapping[str, Any], runs: Runs) -> None:
    nodes = set(invariant["params"]["nodes"])
    for observed in _values(runs, invariant["variables"][0]):
        if observed is None:  # no publisher seen yet: unknown, not checked
            continue
        assert nodes <= observed if invariant["kind"].startswith("min") else observed <= nodes


def _check_interval(invariant: Mapping[str, Any], runs: Runs) -> None:
    params = invariant["params"]
    first, second = params["first"], params["second"]
    for run in runs:
        opened: float | None = None
        between: Counter[str] = Counter()
        for t, event in zip(run["time"], run["event"], strict=True):
            if opened is None:
                if event == first:
                    opened, between = t, Counter()
            elif event == second:
                assert params["min_time"] - 1e-12 <= t - opened <= params["max_time"] + 1e-12
                for name in set(between) | set(params["max_events"]) | set(params["min_events"]):
                    assert params["min_events"].get(name, 0) <= between[name]
                    assert between[name] <= params["max_events"].get(name, 0)
                opened = None
            else:
                between[event] += 1


def test_every_invariant_holds_on_the_data_it_came_from(
    inferred: DetectResult, samples: dict[str, Runs]
) -> None:
    assert inferred.document is not None
    checked: Counter[str] = Counter()
    for invariant in inferred.document["invariants"]:
        key = invariant["point"]
        base, _, condition = key.partition("?")
        runs = samples[key] if key in samples else samples[base]
        if condition and key not in samples:  # a condition found in inference: select its rows
            variable, value = condition.split("==")
            runs = [
                {
                    k: [v for v, c in zip(col, run[variable], strict=True) if c == float(value)]
                    for k, col in run.items()
                }
                for run in runs
            ]
        family = invariant["family"]
        if family in ("frequency", "variance", "rate", "mean", "step"):
            _check_time_family(invariant, runs)
        elif family == "architecture":
            _check_architecture(invariant, runs)
        elif family == "interval":
            _check_interval(invariant, runs)
        elif family == "pattern":
            continue  # none on this data (no pattern in examples/crazyflie.xml)
        else:
            _check_value_family(invariant, runs)
        checked[family] += 1
    assert sum(checked.values()) == len(inferred.document["invariants"])
