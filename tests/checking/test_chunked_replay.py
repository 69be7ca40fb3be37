"""The chunked replay (``imrosc.checking``) against the per-message engine: the same runs.

A document is inferred once from a bag covering every family the catalog names (publish
points alone, paired with inputs, with a declared condition, with a parameter; service
calls, parameters, architecture, a temporal point with a pattern and ordered pairs; a learnt
detector added by hand). Each case then edits it at random (bounds tightened, sets cut,
polygons shrunk, relations' tolerances cut, frequencies raised, conditions on a sample's
own values added, an invariant cleared, another alarm rule), picks a bag (the training
one; one with other values, NaN and infinities, a silent topic and no architecture
records; one cut short) and a chunk size, and replays it both ways: the reports' runs, the
violations with their times and values, the alarms and the samples a trace sees are equal.
The value violations of a chunk's flagged samples, worded at once (``RowChecks``), are also
held equal to the engine's check of each sample on values at the invariants' very ends.
"""

from __future__ import annotations

import copy
import json
import math
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from click.testing import CliRunner
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from imrosc import records
from imrosc.checking import points
from imrosc.checking import run as chunked_run
from imrosc.checking.words import RowChecks
from imrosc.classify import Sampler
from imrosc.cli import main
from imrosc.replay import Replayer, RunReplayer, RunResult
from imrosc.runtime import Engine
from imrosc.runtime.alarms import alarms_json
from imrosc.runtime.families import DETECTOR, NAMES
from tests.runtime.support import alarm_document
from tests.translate import Msg, msg, write_bag

INT, FLOAT, POINT = "std_msgs/msg/Int32", "std_msgs/msg/Float64", "geometry_msgs/msg/Point"
QUAT, STRING = "geometry_msgs/msg/Quaternion", "std_msgs/msg/String"
FLOATS, IMU = "std_msgs/msg/Float32MultiArray", "sensor_msgs/msg/Imu"

CONFIG = """<imROS project="eq">
  <scope>
    <condition id="1"><topic>/in</topic><value>data == 1</value></condition>
    <publish id="a">/out</publish>
    <publish id="b"><topic>/pos</topic><topic>/out</topic></publish>
    <publish id="c" conds="1">/pos</publish>
    <publish id="d">/fn</publish>
    <publish id="e">/label</publish>
    <publish id="l">/lin</publish>
    <publish id="o">/count</publish>
    <publish id="f">/scan</publish>
    <publish id="g">/imu</publish>
    <publish id="h"><topic>/in</topic><param>/gain</param></publish>
    <call id="k">/srv</call>
    <param id="m">/gain</param>
    <arch id="n">pub,sub,srv</arch>
    <temporal id="t" events="a,b" max_interval="2.0"><pattern>(AB)*</pattern></temporal>
  </scope>
  <detect inv="eq.inv" budget="0"><bag>train.bag</bag></detect>
</imROS>
"""


def _record(topic: str, time: float, value: Any) -> Msg:
    return msg(topic, time, STRING, "/imrosc_record", data=records.encode(value))


def _messages(offset: float, scale: float, odd: bool) -> list[Msg]:
    """Eight seconds of a small system at 10 Hz; ``odd``: other values, NaN and infinities,
    /out silent for three seconds, no architecture records."""
    rng = np.random.default_rng(int(offset) + 3)
    found: list[Msg] = []
    for i in range(80):
        t = offset + i * 0.1
        value = scale * math.sin(i / 4)
        if odd and i % 9 == 4:
            value = [math.nan, math.inf, -math.inf][i % 3]
        found.append(msg("/in", t, INT, "/src", data=i % 3 if not odd else i % 4))
        if not (odd and 30 <= i < 60):
            found.append(msg("/out", t + 0.01, FLOAT, "/ctl", data=value))
        x, y = math.cos(i / 5), scale * i / 80
        found.append(msg("/pos", t + 0.02, POINT, "/loc", x=x, y=y, z=2 * x + 3 * y + 1))
        a, b = rng.normal(size=2) * scale
        fn = {"x": a, "y": b, "z": max(a, b), "w": abs(a) if not (odd and i == 50) else 0.5}
        found.append(msg("/fn", t + 0.03, QUAT, "/fn", **fn))
        u = float(rng.normal()) * scale
        side = float(rng.choice([-1.0, 1.0]) * rng.uniform(1.0, 2.0))
        lin = {"x": u, "y": 3 * u - 2 if not (odd and i == 70) else 0.0, "z": side}
        found.append(msg("/lin", t + 0.035, POINT, "/lin", **lin))
        count = int(rng.integers(1, 5)) * int(rng.choice([-1, 1]))
        found.append(
            msg("/count", t + 0.036, INT, "/lin", data=count if not (odd and i == 66) else 0)
        )
        if i % 2:
            words = ["go", "stop", "wait"] if odd else ["go", "stop"]
            found.append(msg("/label", t + 0.04, STRING, "/lab", data=words[i % len(words)]))
        if i % 4 == 0:
            length = 1 + i % 3 if odd else 3
            values = np.array([value] * length, dtype=np.float32)
            found.append(msg("/scan", t + 0.05, FLOATS, "/scanner", data=values))
        cov = rng.uniform(0, scale, 9)
        found.append(
            msg(
                "/imu",
                t + 0.06,
                IMU,
                "/imu",
                orientation_covariance=cov,
                angular_velocity_covariance=cov[::-1].copy(),
                linear_acceleration_covariance=np.zeros(9),
            )
        )
        if i % 10 == 5:
            call = records.ServiceCall(
                "/srv", "/ctl", "/server", {"task_id": i % 3}, {"ok": True}, True, t, 0.02 * scale
            )
            found.append(_record(records.SRVS_TOPIC, t + 0.07, call))
        if i % 20 == 0:
            gain = 2.5 if not (odd and i > 40) else 9.0
            found.append(
                _record(records.PARAMS_TOPIC, t + 0.08, records.ParamSnapshot({"/gain": gain}))
            )
        if i % 25 == 0 and not odd:
            ends = records.TopicEnds(frozenset({"/ctl"}), frozenset({"/loc"}))
            snapshot = records.ArchSnapshot({"/out": ends}, {"/srv": frozenset({"/server"})})
            found.append(_record(records.ARCH_TOPIC, t + 0.09, snapshot))
    return found


@pytest.fixture(scope="module")
def inferred(tmp_path_factory: pytest.TempPathFactory) -> tuple[dict[str, Any], dict[str, Path]]:
    folder = tmp_path_factory.mktemp("chunked")
    bags = {
        "train": write_bag(folder / "train.bag", _messages(0.0, 1.0, False)),
        "odd": write_bag(folder / "odd.bag", _messages(20.0, 2.0, True)),
    }
    whole = write_bag(folder / "whole.bag", _messages(40.0, 1.0, False)).read_bytes()
    bags["cut"] = folder / "cut.bag"
    bags["cut"].write_bytes(whole[: len(whole) * 2 // 3])
    (folder / "eq.xml").write_text(CONFIG)
    result = CliRunner().invoke(main, ["infer", str(folder / "eq.xml"), "-j", "1", "-q"])
    assert result.exit_code == 0, result.output
    document = json.loads((folder / "eq.inv").read_text())
    document["invariants"].append(
        {
            "id": "idet",
            "point": "a",
            "family": DETECTOR,
            "kind": "logistic",
            "variables": ["out.data"],
            "text": "detector score of 1 variables of a <= 1.2",
            "params": {
                "window": 1.0,
                "center": [0.0, 0.0, 0.0],
                "scale": [1.0, 1.0, 1.0],
                "weights": [0.0, 0.5, 1.0],
                "bias": -1.0,
                "threshold": 1.2,
            },
        }
    )
    return document, bags


def test_the_document_holds_every_family(
    inferred: tuple[dict[str, Any], dict[str, Path]],
) -> None:
    families = {inv["family"] for inv in inferred[0]["invariants"]}
    assert families == set(NAMES)


def _number(value: Any) -> float | None:
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        return None
    return float(value) if math.isfinite(value) else None


@st.composite
def _edited(draw: st.DrawFn, base: dict[str, Any]) -> dict[str, Any]:
    """``base`` with some invariants tightened, conditions added, the alarm rule replaced."""
    document = copy.deepcopy(base)
    for inv in document["invariants"]:
        if not draw(st.booleans()):
            continue
        params = inv["params"]
        low, high = _number(params.get("min")), _number(params.get("max"))
        cut = draw(st.sampled_from([0.0, 0.1, 0.3, 0.5]))
        if low is not None and high is not None:
            params["min"], params["max"] = low + cut * (high - low), high - cut * (high - low)
        elif high is not None:
            params["max"] = high - cut * abs(high)
        if isinstance(params.get("values"), list) and len(params["values"]) > 1:
            params["values"] = params["values"][1:]
        if "tolerance" in params:
            params["tolerance"] = params["tolerance"] * cut
        if isinstance(params.get("b"), list):
            params["b"] = [c - cut * abs(c) for c in params["b"]]
        if "max_time" in params:
            params["max_time"] = float(params["max_time"]) * (1 - cut)
    points = document["points"]
    for key in draw(st.lists(st.sampled_from(sorted(points)), max_size=2, unique=True)):
        variables = points[key]["variables"]
        if not variables or points[key]["kind"] != "publish":
            continue
        variable = draw(st.sampled_from(variables))
        value: Any = draw(st.sampled_from([0, 1, 1.0, 2, "go", True]))
        points[key].setdefault("filter", []).append({"variable": variable["name"], "value": value})
    if draw(st.booleans()):
        document["alarms"] = {
            "persist": draw(st.integers(1, 4)),
            "seconds": draw(st.sampled_from([None, 0.0, 0.3])),
            "distinct": draw(st.integers(0, 3)),
            "window": draw(st.sampled_from([0.2, 1.0])),
        }
    return document


def _run(result: RunResult, run: dict[str, Any]) -> str:
    violations = [list(v) for v in result.violations]
    fields = [violations, alarms_json(result.alarms), run, result.checked, result.unchecked]
    return json.dumps(fields, default=repr, sort_keys=True)


@given(data=st.data())
@settings(
    max_examples=12,
    deadline=None,
    suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow],
)
def test_chunked_replay_equals_the_engine(
    inferred: tuple[dict[str, Any], dict[str, Path]],
    data: st.DataObject,
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    base, bags = inferred
    document = data.draw(_edited(base))
    bag = bags[data.draw(st.sampled_from(sorted(bags)))]
    monkeypatch.setattr(chunked_run, "CHUNK_MESSAGES", data.draw(st.sampled_from([2, 7, 64, 8192])))
    cleared = data.draw(st.sampled_from([None, *sorted(i["id"] for i in document["invariants"])]))

    chunked = RunReplayer(document, plots=True)
    by_message = RunReplayer(document, plots=True)
    by_message.replayer.chunked = False
    runs = []
    for replay in (chunked, by_message):
        if cleared is not None:
            replay.replayer.engine.clear(cleared)
        runs.append(_run(*replay(bag)))
    assert runs[0] == runs[1]

    samples = []
    for chunks in (True, False):
        sampler = Sampler(document)
        replayer = Replayer(document, Engine(document, trace=sampler.trace), chunked=chunks)
        result = replayer.run(bag)
        taken = {k: (v.times.tolist(), v.rows.tolist()) for k, v in sampler.take().items()}
        samples.append(
            json.dumps([taken, [list(v) for v in result.violations]], default=repr, sort_keys=True)
        )
    assert samples[0] == samples[1]


@pytest.mark.parametrize("chunk", [3, 8192])
def test_silences_alarms_and_the_engine_s_points_agree(
    inferred: tuple[dict[str, Any], dict[str, Path]],
    chunk: int,
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """The odd run: /out silent for three seconds (the timer reports it), NaN and
    infinities, a parameter and service calls the engine checks, alarms of every rule."""
    document, bags = inferred
    monkeypatch.setattr(chunked_run, "CHUNK_MESSAGES", chunk)
    results = []
    for chunks in (True, False):
        replay = RunReplayer(document, plots=True)
        replay.replayer.chunked = chunks
        results.append(replay(bags["odd"]))
    (chunked, run), (by_message, message_run) = results
    assert _run(chunked, run) == _run(by_message, message_run)
    assert any(v.expected.startswith("at least") for v in chunked.violations)  # a silence
    assert {v.point for v in chunked.violations} >= {"a", "h", "k", "m", "n", "t"}
    assert {a.rule for a in chunked.alarms} == {"persist", "event"}


def test_a_recording_tracker_keeps_the_engine_s_order(
    inferred: tuple[dict[str, Any], dict[str, Path]],
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """Calibration records every violating sample (``alarms.fed``) in the engine's order."""
    document, bags = inferred
    monkeypatch.setattr(chunked_run, "CHUNK_MESSAGES", 5)
    kept = []
    for chunks in (True, False):
        engine = Engine(document)
        engine.alarms.record = True
        Replayer(document, engine, chunked=chunks).run(bags["odd"])
        kept.append(list(engine.alarms.fed))
    assert kept[0] == kept[1] and len({f[1] for f in kept[0]}) > 3


def _ends(invariants: list[dict[str, Any]]) -> list[float]:
    """Every finite number the invariants state (bounds, sets, edges, vertices)."""
    found: set[float] = set()
    stack: list[Any] = [inv["params"] for inv in invariants]
    while stack:
        item = stack.pop()
        if isinstance(item, dict):
            stack += item.values()
        elif isinstance(item, list):
            stack += item
        elif _number(item) is not None:
            found.add(float(item))
    return sorted(found)


@given(data=st.data())
@settings(
    max_examples=50,
    deadline=None,
    suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow],
)
def test_row_checks_word_what_the_engine_s_check_words(
    inferred: tuple[dict[str, Any], dict[str, Path]], data: st.DataObject
) -> None:
    """Samples at the invariants' ends, NaN, infinities and signed zeros: the violations
    ``RowChecks`` words for a matrix of samples are ``Checks.check``'s of each sample, but
    for the samples near a relation's tolerance (the engine checks those itself)."""
    document = data.draw(_edited(inferred[0]))
    engine = Engine(document, compile=False)
    cleared = data.draw(st.sampled_from([None, *sorted(i["id"] for i in document["invariants"])]))
    if cleared is not None:
        engine.clear(cleared)
    for key, point in engine.points.items():
        checks = point.checks
        if point.kind != "publish" or not checks.size:
            continue
        width = len(checks.index)
        ends = _ends([inv for inv in document["invariants"] if inv["point"] == key])
        number = st.one_of(
            st.sampled_from([*ends, 0.0, -0.0, 1.0, math.nan, math.inf, -math.inf]),
            st.floats(-1e3, 1e3),
        )
        rows = data.draw(st.lists(st.lists(number, min_size=width, max_size=width), max_size=6))
        values = np.array(rows, dtype=np.float64).reshape(len(rows), width)
        word = st.sampled_from(["go", "stop", "wait", ""])
        texts = [
            np.array(data.draw(st.lists(word, min_size=len(rows), max_size=len(rows))), object)
            for _ in point.string_names
        ]
        times = [0.5 * k for k in range(len(rows))]
        words = RowChecks(checks)
        with np.errstate(all="ignore"):  # as a replay runs both
            mine = np.flatnonzero(~words.may_relate(values))
            found = words.violations(
                [times[k] for k in mine], key, values[mine], [t[mine] for t in texts]
            )
            for k, worded in zip(mine.tolist(), found, strict=True):
                strings = [t[k] for t in texts]
                expected = checks.check(times[k], key, values[k].copy(), strings)
                assert json.dumps(worded, default=repr) == json.dumps(expected, default=repr)


def test_a_family_the_vectorised_pass_does_not_know_is_left_to_the_engine(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """A point holding a value family :data:`points.VECTORISED` does not name is checked by
    the engine, per message, rather than by a pass that would not flag its samples."""
    engine = Engine(alarm_document(None))
    point = engine.points["x"]
    assert point.checks.families == {"bounds"} and points.vectorisable(engine, point)
    monkeypatch.setattr(points, "VECTORISED", points.VECTORISED - {"bounds"})
    assert not points.vectorisable(engine, point)
