"""Smoke test of the closed-loop case study (issue 19, ``bench/casestudy.py``): one short
trial of one fault scenario through the landing system's own launch file, and the same
trial through the launch file ``imrosc build --backend ros1`` rewrote to put the generated
monitor in; both outcomes asserted.

The monitor checks ``casestudy/landing.refined.inv``: the refined invariants the bench's
pipeline wrote (recorded runs, ``imrosc infer``, ``imrosc classify``; no invariant written
by hand). ``casestudy/README.md`` says how it was made and how to make it again. Building
and the two trials take about a minute here.
"""

from __future__ import annotations

from pathlib import Path

import pytest
from click.testing import CliRunner

from bench.casestudy import GRAPH, alarms, configuration
from imrosc.cli import main
from tests.live.harness import HERE, Ros
from tests.live.landing_system import LAUNCH, prepare, trial

pytestmark = pytest.mark.live

INVARIANTS = HERE / "casestudy" / "landing.refined.inv"
SCENARIO, SEED = "false_airport", 0
TIMEOUT = 40.0
"""Simulated seconds: the UAV is on the floor for good after about 23 s without a monitor."""
SPEED = 0.0
"""No cap: the lockstep sets the pace."""


@pytest.fixture(scope="module")
def monitored_launch(ros: Ros, tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The monitor package built from the example's configuration and the recorded
    invariants, on the graph's package path; its rewritten launch file."""
    prepare(ros)
    work = tmp_path_factory.mktemp("casestudy")
    config = configuration(work)
    package = work / "build"
    result = CliRunner().invoke(
        main,
        [
            "build",
            str(config),
            "--backend",
            "ros1",
            "--graph",
            str(work / GRAPH.name),
            "--inv",
            str(INVARIANTS),
            "-o",
            str(package),
        ],
    )
    assert result.exit_code == 0, result.output
    ros.add_package_path(package)
    return next(package.glob("*/launch/system_monitored.launch"))


def test_the_monitor_keeps_the_uav_from_landing_at_a_false_airport(
    ros: Ros, monitored_launch: Path
) -> None:
    without = trial(ros, SCENARIO, SEED, launch=LAUNCH, speed=SPEED, timeout=TIMEOUT)
    assert without.outcome == "landed_elsewhere" and not without.success, without
    assert "floor" in without.detail, without

    before = sum(alarms(ros).values())
    with_monitor = trial(ros, SCENARIO, SEED, launch=monitored_launch, speed=SPEED, timeout=TIMEOUT)
    assert with_monitor.outcome == "timeout" and with_monitor.success, with_monitor
    assert sum(alarms(ros).values()) > before  # the monitor's alarms kept it up
