"""The lockstep's balance of channels (``examples/landing_system/lockstep``), without ROS: a
channel whose subscriber closed the connection no longer holds the clock."""

from __future__ import annotations

import importlib.util
from pathlib import Path
from typing import Any

LOCKSTEP = Path(__file__).resolve().parents[2] / "examples" / "landing_system" / "lockstep"


def _module() -> Any:
    spec = importlib.util.spec_from_file_location("rospy_lockstep", LOCKSTEP / "rospy_lockstep.py")
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def _coordinator() -> Any:
    """A coordinator with no ROS behind it: its bookkeeping only."""
    coordinator = object.__new__(_module().Coordinator)
    coordinator.name = "/vicon"
    coordinator.reports = {"/a/thief": {}, "/monitor": {}}
    coordinator.sent, coordinator.received, coordinator.services = {}, {}, {}
    coordinator.unbalanced, coordinator.closed = set(), set()
    return coordinator


def _report(**counts: Any) -> dict[str, Any]:
    return {"sent": {}, "received": {}, "calls": {}, "served": {}, **counts}


def test_a_message_lost_with_a_closed_connection_does_not_hold_the_clock() -> None:
    coordinator = _coordinator()
    # the thief wrote its first pose to the monitor, which dropped it as an unknown
    # publisher before reading it: sent 1, received 0 on that channel
    coordinator.apply("/a/thief", _report(sent={"/a/car_pose>/monitor": 1}))
    coordinator.apply("/monitor", _report())
    assert coordinator.unbalanced == {("/a/car_pose", "/a/thief", "/monitor")}
    coordinator.apply("/monitor", _report(closed=["/a/car_pose</a/thief"]))
    assert coordinator.unbalanced == set()
    coordinator.recheck()  # (a node joining rechecks every channel)
    assert coordinator.unbalanced == set()


def test_an_open_channel_still_balances() -> None:
    coordinator = _coordinator()
    coordinator.apply("/a/thief", _report(sent={"/a/car_pose>/monitor": 2}))
    coordinator.apply("/monitor", _report(received={"/a/car_pose</a/thief": 1}))
    assert coordinator.unbalanced == {("/a/car_pose", "/a/thief", "/monitor")}
    coordinator.apply("/monitor", _report(received={"/a/car_pose</a/thief": 2}))
    assert coordinator.unbalanced == set()
