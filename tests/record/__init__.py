"""Tests of ``imrosc record`` that need no ROS (the live ones are tests/live/test_record.py)."""

from __future__ import annotations

import importlib.util
from functools import cache
from types import ModuleType

from imrosc.record.session import RECORDER_SCRIPT


@cache
def recorder_node() -> ModuleType:
    """The recording node's script as a module (it imports rospy only when it runs)."""
    spec = importlib.util.spec_from_file_location("imrosc_recorder_under_test", RECORDER_SCRIPT)
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module
