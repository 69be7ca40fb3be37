"""The landing system's pure core (``examples/landing_system/nodes/landing_core.py``), imported
by path: the nodes' folder is a ROS package, not a Python package."""

from __future__ import annotations

import importlib.util
import sys
from pathlib import Path

NODES = Path(__file__).resolve().parents[2] / "examples" / "landing_system" / "nodes"


def _load() -> object:
    spec = importlib.util.spec_from_file_location("landing_core", NODES / "landing_core.py")
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    sys.modules["landing_core"] = module
    spec.loader.exec_module(module)
    return module


landing_core = sys.modules.get("landing_core") or _load()
