"""Building, installing and importing the ROS 2 package of an example, for the ROS 2 backend's
tests."""

from __future__ import annotations

import itertools
import shutil
from collections.abc import Mapping, Sequence
from pathlib import Path
from types import ModuleType
from typing import Any

import pytest
from rosbags.typesys import Stores, get_typestore

from imrosc.build import BuildResult, build
from imrosc.detect import run_detect
from imrosc.invariants import dumps
from imrosc.sim import write_runs
from imrosc.translate.layout import short_names
from tests.backends.monitor_support import (
    EXAMPLES,
    add_battery_cells,
    import_copy,
    invariants_document,
    variables_of,
)

PACKAGE = "landing_sim_monitor"


VENDOR = f"{PACKAGE}/imrosc"


STORE2 = get_typestore(Stores.ROS2_HUMBLE)


_COUNTER = itertools.count()


def build_ros2(config: Path, graph: Sequence[Path] = (), bags: Sequence[Path] = ()) -> BuildResult:
    """``imrosc build --backend ros2`` without writing."""
    return build(config, "ros2", graph_files=graph, bags=bags)


@pytest.fixture(scope="module")
def landing_ros2(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """examples/landing_sim.xml with its graph and invariants inferred from two short
    simulated nominal runs written as ROS 2 (sqlite3) bags."""
    folder = tmp_path_factory.mktemp("landing_ros2")
    for name in ("landing_sim.xml", "landing_sim.graph.yaml"):
        shutil.copy(EXAMPLES / name, folder / name)
    write_runs(folder / "bags" / "nominal", runs=2, seed=0, fmt="sqlite3", duration=8.0)
    result = run_detect(
        folder / "landing_sim.xml",
        workers=1,
        graph_files=[folder / "landing_sim.graph.yaml"],
        budget=0,  # the exact invariants: these tests compare ROS 1 and ROS 2, not calibration
    )
    assert result.document is not None, [d.as_text() for d in result.diagnostics]
    (folder / "landing_sim.inv").write_text(dumps(result.document), encoding="utf-8")
    return folder


def python_files(files: Mapping[str, bytes]) -> dict[str, bytes]:
    return {name: content for name, content in files.items() if name.endswith(".py")}


def import_package(package: Path) -> ModuleType:
    """Import a written package's Python package under a fresh name; its ``main``."""
    return import_copy(package / package.name, package.parent, "ros2_monitor_test_", "main")


def setup_arguments(package: Path) -> dict[str, Any]:
    """What ``setup.py`` passes to ``setuptools.setup`` (run with setup replaced)."""
    captured: dict[str, Any] = {}
    source = (package / "setup.py").read_text()
    namespace: dict[str, Any] = {"__name__": "__main__", "__file__": str(package / "setup.py")}
    code = compile(source.replace("from setuptools import setup", ""), "setup.py", "exec")
    namespace["setup"] = lambda **kwargs: captured.update(kwargs)
    exec(code, namespace)
    return captured


def ros2_document(topics: Mapping[str, str]) -> dict[str, Any]:
    """A small invariants document laid out from ROS 2 message definitions (no
    ``header.seq``), a publish point per topic."""
    shorts = short_names(topics)
    layouts = {
        topic: variables_of(topic, msgtype, shorts[topic], STORE2)
        for topic, msgtype in sorted(topics.items())
    }
    battery = layouts.get("/battery", [])
    add_battery_cells(battery)
    return invariants_document(topics, layouts=layouts)
