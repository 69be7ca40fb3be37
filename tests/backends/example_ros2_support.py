"""The embedded ROS 2 example (configuration, graph, package) its tests share."""

from __future__ import annotations

import shutil
from pathlib import Path

import pytest

from imrosc.detect import run_detect
from imrosc.invariants import dumps
from imrosc.sim import write_runs

ROOT = Path(__file__).resolve().parents[2]


EXAMPLES = ROOT / "examples"


CONFIG = "uav_landing.xml"


GRAPH = "uav_landing.graph.yaml"


ROS1_LAUNCH = "launch/landing.launch"


ROS2_LAUNCH = "launch/landing.launch.xml"


PACKAGE = "uav_landing_monitor"


def copy_example(folder: Path) -> Path:
    """The example's configuration, graph and both launch files copied into ``folder``."""
    folder.mkdir(parents=True, exist_ok=True)
    for name in (CONFIG, GRAPH, ROS1_LAUNCH, ROS2_LAUNCH):
        (folder / name).parent.mkdir(parents=True, exist_ok=True)
        shutil.copy(EXAMPLES / name, folder / name)
    return folder / CONFIG


@pytest.fixture(scope="session")
def landing_example(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A folder with the example (see :func:`copy_example`) and ``landing.inv`` inferred
    with it from two short simulated nominal runs (the system ``imrosc.sim`` simulates has
    the example's topics, types and graph)."""
    folder = tmp_path_factory.mktemp("uav_landing")
    config = copy_example(folder)
    write_runs(folder / "bags" / "nominal", runs=2, seed=0, fmt="ros1", duration=8.0)
    result = run_detect(config, workers=1, graph_files=[folder / GRAPH])
    assert result.document is not None, [d.as_text() for d in result.diagnostics]
    (folder / "landing.inv").write_text(dumps(result.document), encoding="utf-8")
    return folder
