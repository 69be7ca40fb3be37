"""The landing system in lockstep (``examples/landing_system/lockstep``): a trial's every
step (the command the simulator applies, the UAV it moves) is the same whether the machine
is idle or two busy processes compete for its cores, because ``/clock`` advances only once
every node has reacted to the last step."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

from tests.live.harness import ROS_PYTHON, Ros, _clean_environment
from tests.live.landing_system import LOCKSTEP, prepare, trial

pytestmark = pytest.mark.live

TIMEOUT = 8.0
"""Simulated seconds: take-off, climb and the pursuit's first turns."""


def busy_loops(count: int) -> list[subprocess.Popen[bytes]]:
    return [subprocess.Popen([sys.executable, "-c", "while 1: pass"]) for _ in range(count)]


def test_a_trial_is_the_same_on_a_loaded_machine(ros: Ros, tmp_path: Path) -> None:
    prepare(ros)
    quiet, loaded = tmp_path / "quiet.trace", tmp_path / "loaded.trace"
    first = trial(ros, "wind", 3, speed=0.0, timeout=TIMEOUT, trace=str(quiet))
    loops = busy_loops(2)
    try:
        second = trial(ros, "wind", 3, speed=0.0, timeout=TIMEOUT, trace=str(loaded))
    finally:
        for loop in loops:
            loop.kill()
            loop.wait()
    assert (first.outcome, first.time, first.stalls) == (second.outcome, second.time, 0)
    steps = quiet.read_text().splitlines()
    assert len(steps) >= TIMEOUT * 100 - 1
    assert loaded.read_text().splitlines() == steps


PUBLISHER_UPDATES = """
import threading
import rospy
from rospy.impl.registration import RegManager
manager = RegManager.__new__(RegManager)
manager.cond, manager.updates = threading.Condition(), []
RegManager.publisher_update(manager, "/a/cmd_attitude", ["http://127.0.0.1:1/"])
RegManager.publisher_update(manager, "/a/cmd_attitude", [])
print(manager.updates[-1][1])
"""
"""The master's update naming a publisher, then the (older) reply to the subscription, which
named none, queued after it: rospy's registration thread connects to the last list only."""


@pytest.mark.parametrize("lockstep", [False, True])
def test_a_subscriber_connects_to_a_publisher_whatever_order_the_master_tells_it_in(
    lockstep: bool,
) -> None:
    env = {**_clean_environment(), "PYTHONPATH": str(LOCKSTEP)}
    if lockstep:
        env["LANDING_LOCKSTEP"] = "1"
    done = subprocess.run(
        [str(ROS_PYTHON), "-c", PUBLISHER_UPDATES],
        env=env,
        capture_output=True,
        text=True,
        check=True,
        timeout=60,
    )
    # without the lockstep's patch rospy never connects to that publisher
    expected = "['http://127.0.0.1:1/']" if lockstep else "[]"
    assert done.stdout.strip() == expected, done.stderr
