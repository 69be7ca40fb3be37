"""The closed-loop landing system (thesis case study 1) on a live ROS 1 graph: real roscore,
rospy nodes on simulated time, in lockstep with the simulator. Without a monitor a normal
run takes off, pursues the platform and touches down on it (a landing, or, as in the thesis,
now and then a crash when the platform turns under it; seed 0 lands), and a false airport
(a platform pose with no vehicle there) lands the UAV on the floor."""

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
    outcome = trial(system, "normal", 0, speed=0.0)
    assert outcome.outcome == "landed" and outcome.success, outcome
    assert "platform" in outcome.detail, outcome
    assert outcome.stalls == 0  # every step waited for the whole graph


def test_a_false_airport_lands_the_uav_where_no_vehicle_is(system: Ros) -> None:
    outcome = trial(system, "false_airport", 0, speed=0.0)
    assert outcome.outcome == "landed_elsewhere" and not outcome.success, outcome
    assert "floor" in outcome.detail
