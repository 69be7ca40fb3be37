"""The closed-loop landing system (thesis case study 1) on a live ROS 1 graph: real roscore,
rospy nodes on simulated time, faster than real time. Without a monitor a normal run takes
off, pursues the platform and touches down on it (landing, or, as in the thesis, now and
then crashing when the platform turns under it: the graph's timing decides, so both count
here; ``tests/casestudy`` checks the landing itself offline), and a false airport (a platform
pose with no vehicle there) lands the UAV on the floor."""

from __future__ import annotations

import pytest

from tests.live.harness import Ros
from tests.live.landing_system import prepare, trial

pytestmark = pytest.mark.live


@pytest.fixture(scope="module")
def system(ros: Ros) -> Ros:
    prepare(ros)
    return ros


def test_a_normal_run_touches_down_on_the_moving_platform(system: Ros) -> None:
    outcome = trial(system, "normal", 0)
    assert outcome.outcome in ("landed", "crashed"), outcome
    assert "platform" in outcome.detail, outcome
    assert outcome.success == (outcome.outcome == "landed")
    assert outcome.wall < outcome.time  # faster than real time


def test_a_false_airport_lands_the_uav_where_no_vehicle_is(system: Ros) -> None:
    outcome = trial(system, "false_airport", 0)
    assert outcome.outcome == "landed_elsewhere" and not outcome.success, outcome
    assert "floor" in outcome.detail
