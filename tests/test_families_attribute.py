"""``<publish families="...">`` chooses the template families inference instantiates at a
point (issue 22: a point with many variables can leave out its pairwise polygons)."""

from __future__ import annotations

import json
import math
from pathlib import Path

import pytest
from click.testing import CliRunner

from imrosc.cli import main
from imrosc.ir import PublishPoint
from imrosc.lower import lower
from imrosc.runtime.families import in_group
from imrosc.schema.loader import load_config
from tests.translate import msg, write_bag

CONFIG = """<imROS project="p">
  <scope>
    <publish id="a" {families}><topic>/out</topic><topic>/in</topic></publish>
  </scope>
  <detect inv="p.inv" budget="0"><bag>bags</bag></detect>
</imROS>
"""


def project(folder: Path, families: str) -> Path:
    config = folder / "p.xml"
    config.write_text(CONFIG.format(families=families))
    return config


@pytest.mark.parametrize(
    ("families", "chosen"),
    [
        ("", ()),
        ('families="default time-related"', (*in_group("default"), *in_group("time-related"))),
        ('families="polygon, bounds"', ("bounds", "polygon")),
        ('families="rate"', ("rate",)),
    ],
)
def test_the_attribute_selects_families_in_catalog_order(
    families: str, chosen: tuple[str, ...], tmp_path: Path
) -> None:
    config, problems = load_config(project(tmp_path, families))
    assert config is not None and problems == []
    (point,) = lower(config).points
    assert isinstance(point, PublishPoint) and point.families == chosen


@pytest.mark.parametrize(
    ("families", "column", "word"),
    [('families="default polygons"', 39, "polygons"), ('families="order, arch"', 38, "arch")],
)
def test_an_unknown_family_is_an_error_at_its_column(
    families: str, column: int, word: str, tmp_path: Path
) -> None:
    config = project(tmp_path, families)
    result = CliRunner().invoke(main, ["check", str(config)])
    assert result.exit_code == 1
    assert f"p.xml:3:{column}: error: '{word}' is no invariant family" in result.output
    assert "[unknown-family]" in result.output


def test_empty_families_are_an_error(tmp_path: Path) -> None:
    result = CliRunner().invoke(main, ["check", str(project(tmp_path, 'families=" , "'))])
    assert result.exit_code == 1 and "families names no family" in result.output


def test_inference_instantiates_only_the_chosen_families(tmp_path: Path) -> None:
    (tmp_path / "bags").mkdir()
    messages = []
    for i in range(400):  # (/in, /out) go round a circle four times: a polygon of the two
        angle = (i % 100) * 0.05
        messages.append(msg("/in", i * 0.1, "std_msgs/msg/Float64", "/src", data=math.cos(angle)))
        out = math.sin(angle)
        messages.append(msg("/out", i * 0.1 + 0.01, "std_msgs/msg/Float64", "/ctl", data=out))
    write_bag(tmp_path / "bags" / "r1.bag", messages)
    runner = CliRunner()
    found = {}
    for families in ("", 'families="default time-related"'):
        config = project(tmp_path, families)
        done = runner.invoke(main, ["infer", str(config), "-q", "-j", "1", "--force"])
        assert done.exit_code == 0, done.output
        document = json.loads((tmp_path / "p.inv").read_text())
        found[families] = {inv["family"] for inv in document["invariants"]}
    assert "polygon" in found[""]
    assert "polygon" not in found['families="default time-related"']
    assert found[""] - {"polygon"} == found['families="default time-related"']
