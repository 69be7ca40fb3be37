"""NaN and infinity are values the invariants speak about: a variable never NaN nor infinite
in training gets ``finite`` in its bounds, and a NaN (which compares false with any bound)
or an infinite value then breaks them in replay (issue 18)."""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

from imrosc.detect import run_detect
from imrosc.replay import replay
from tests.translate import msg, write_bag

CONFIG = """<imROS project="f">
  <scope><publish id="t">/t</publish></scope>
  <detect inv="f.inv" budget="0"><bag>train.bag</bag></detect>
</imROS>
"""
FLOAT = "std_msgs/msg/Float64"
WAVE = [1.0 + math.sin(k / 5) for k in range(200)]


def _learn(folder: Path, values: list[float]) -> dict[str, Any]:
    folder.mkdir(parents=True, exist_ok=True)
    write_bag(
        folder / "train.bag", [msg("/t", k / 10, FLOAT, data=v) for k, v in enumerate(values)]
    )
    (folder / "f.xml").write_text(CONFIG)
    result = run_detect(folder / "f.xml", workers=1)
    assert result.document is not None
    return result.document


def _bounds(document: dict[str, Any]) -> dict[str, Any]:
    (found,) = [i for i in document["invariants"] if i["family"] == "bounds"]
    return dict(found["params"])


def test_finite_training_values_make_finite_bounds(tmp_path: Path) -> None:
    document = _learn(tmp_path, WAVE)
    bounds = _bounds(document)
    assert bounds["finite"] is True and set(bounds) == {"min", "max", "finite"}


def test_nan_or_inf_in_training_make_no_finiteness(tmp_path: Path) -> None:
    values = WAVE
    with_nan = _learn(tmp_path / "nan", [*values[:100], math.nan, *values[100:]])
    assert "finite" not in _bounds(with_nan)
    with_inf = _learn(tmp_path / "inf", [*values, math.inf])
    assert all("finite" not in i["params"] for i in with_inf["invariants"])


def test_a_field_nan_in_every_message_breaks_its_bounds(tmp_path: Path) -> None:
    document = _learn(tmp_path, WAVE)
    nan = write_bag(
        tmp_path / "nan.bag", [msg("/t", k / 10, FLOAT, data=math.nan) for k in range(20)]
    )
    (result,) = replay(document, [nan])
    assert len(result.violations) == 20 and result.alarms
    first = result.violations[0]
    assert first.family == "bounds" and math.isnan(first.observed)
    assert first.expected == "a finite value (never NaN nor infinite in training)"
    inf = write_bag(tmp_path / "inf.bag", [msg("/t", 0.0, FLOAT, data=math.inf)])
    (result,) = replay(document, [inf])
    assert len(result.violations) == 1  # the bound's own violation, not a second one
    good = write_bag(tmp_path / "good.bag", [msg("/t", 0.0, FLOAT, data=1.0)])
    assert replay(document, [good])[0].violations == []
