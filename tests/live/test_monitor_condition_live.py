"""The generated ROS 1 monitor keeps checking a point with a topic-operand condition (issue 18).

``<value>/a/subject_ctrl_state == 3</value>`` is a documented condition form (a topic operand
standing for the condition topic's only field). The monitor used to raise ``KeyError: 'op'``
in every callback of the condition's point and went on running unchecked; here it learns the
point's conditional invariants, checks them live, reports a bad pose on the conditional point
(``v?1``) twice, seconds apart, and never reports a failure. Then a check made to raise
stops the monitor, as its fail policy says.
"""

from __future__ import annotations

import json
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import pytest
from click.testing import CliRunner

from imrosc.cli import main
from imrosc.detect import run_detect
from imrosc.invariants import dumps
from tests.live.harness import (
    HERE,
    Listener,
    Proc,
    Ros,
    live_config,
    record_nominal,
    wait_until,
)

pytestmark = pytest.mark.live

GRAPH = HERE / "landing_live.graph.yaml"
BROKEN, POSE, RELAY = "/m/broken_inv", "/a/car_pose", "/m/a/cmd_subject_ctrl_state"
STATE = "/a/subject_ctrl_state"
CONDITION = """    <publish id="v" conds="1">/a/car_pose</publish>
    <condition id="1">
      <topic>/a/subject_ctrl_state</topic>
      <value>/a/subject_ctrl_state == 3</value>
    </condition>"""


@dataclass
class Built:
    """The test system's monitor package, built with a topic-operand condition on v."""

    package: Path
    monitor: str
    watchdog: str


@pytest.fixture(scope="module")
def built(ros: Ros, tmp_path_factory: pytest.TempPathFactory) -> Built:
    folder = tmp_path_factory.mktemp("condition")
    config = live_config(folder)
    text = config.read_text(encoding="utf-8")
    assert '<publish id="v">/a/car_pose</publish>' in text
    config.write_text(text.replace('<publish id="v">/a/car_pose</publish>', CONDITION))
    checked = CliRunner().invoke(main, ["check", str(config)])
    assert checked.exit_code == 0, checked.output

    nominal = ros.start_system()
    record_nominal(ros, folder / "bags" / "nominal")
    ros.stop(nominal)
    detected = run_detect(config, workers=1)
    assert detected.ok and detected.document is not None, [str(d) for d in detected.diagnostics]
    document = {k: v for k, v in detected.document.items() if k != "alarms"}
    conditional = [i for i in document["invariants"] if i["point"] == "v?1"]
    assert any(i["family"] == "bounds" for i in conditional), conditional
    (folder / "landing_live.inv").write_text(dumps(document), encoding="utf-8")
    out = folder / "build"
    result = CliRunner().invoke(
        main, ["build", str(config), "--backend", "ros1", "-o", str(out), "--graph", str(GRAPH)]
    )
    assert result.exit_code == 0, result.output
    (package,) = [p for p in out.iterdir() if (p / "package.xml").exists()]
    spec = json.loads((package / "scripts/imrosc_monitor/spec.json").read_text())
    ros.add_package_path(out)
    return Built(package, "/" + spec["node"], "/" + spec["watchdog"])


def reports(watch: Listener, since: float) -> list[dict[str, Any]]:
    """The reports on /m/broken_inv received after ``since``."""
    found = [json.loads(r["msg"]["data"]) | {"t": r["t"]} for r in watch.messages(BROKEN)]
    return [r for r in found if r["t"] >= since]


def test_a_topic_operand_condition_is_checked_live(ros: Ros, built: Built) -> None:
    watch = ros.listen(BROKEN, STATE)
    system = ros.start_system(built.package / "launch" / "system_monitored.launch")
    try:
        ros.wait_subscriber(POSE, built.monitor, 30, (system,))
        start = time.time()
        # the bad pose must come while the state is 3 (the condition), which it is once the
        # controller's command has gone through the monitor's relay to the state machine
        wait_until(
            lambda: [m for m in watch.messages(STATE) if m["msg"]["data"] == 3],
            "the state machine in state 3",
            30,
            (system, watch.proc),
        )
        time.sleep(0.5)  # the monitor hears that state too
        for _ in range(2):  # the monitor checks the conditional point, and goes on checking it
            since = time.time()
            ros.inject("/a/car", "out_of_range:1")
            wait_until(
                lambda since=since: [r for r in reports(watch, since) if r["point"] == "v?1"],  # type: ignore[misc]
                "a violation of the conditional point v?1",
                15,
                (system, watch.proc),
            )
            time.sleep(2.0)
        assert not [r for r in reports(watch, start) if r["kind"] == "failure"]
        assert built.monitor in ros.subscribers(POSE)
    finally:
        ros.stop(system, watch.proc)


def test_a_check_that_raises_stops_the_monitor_and_the_watchdog_fails_open(
    ros: Ros, built: Built
) -> None:
    """A check that raises is reported on /m/broken_inv, the monitor leaves the graph, and
    the watchdog relays the blocked topic: nothing runs unchecked behind a live heartbeat."""
    runtime = built.package / "scripts" / "imrosc_monitor" / "imrosc" / "runtime" / "conditions.py"
    source = runtime.read_text(encoding="utf-8")
    # the check raises once the trigger file exists: after the listener is connected, so
    # that the report cannot be published before anyone hears it
    trigger = built.package.parent / "raise-now"
    trigger.unlink(missing_ok=True)
    broken = source.replace(
        '    """Whether ``expression`` holds',
        f"    if __import__('os').path.exists({str(trigger)!r}):\n"
        '        raise RuntimeError("injected")\n    """Whether ``expression`` holds',
    )
    assert broken != source
    runtime.write_text(broken, encoding="utf-8")
    started: list[Proc] = []
    try:
        watch = ros.listen(BROKEN)
        started.append(watch.proc)
        since = time.time()
        launch = built.package / "launch" / "system_monitored.launch"
        system = ros.start_system(launch, imrosc_fail_open="true")
        started.append(system)
        ros.wait_subscriber(POSE, built.monitor, 30, (system,))
        wait_until(
            lambda: built.monitor in ros.publishers(BROKEN) and ros.subscribers(BROKEN),
            "the listener on /m/broken_inv",
            30,
            (system,),
        )
        time.sleep(1.0)  # the listener's connection to the monitor's publisher
        trigger.write_text("")
        (failure,) = wait_until(
            lambda: [r for r in reports(watch, since) if r["kind"] == "failure"],
            "the monitor's failure report",
            30,
            (system, watch.proc),
        )
        assert failure["error"]["type"] == "RuntimeError", failure
        assert failure["error"]["where"] == f"message on {POSE}", failure
        assert (failure["alarm"], failure["rule"]) == (True, "failure")
        wait_until(
            lambda: built.monitor not in ros.subscribers(POSE),
            "the monitor to leave the graph",
            15,
            (system,),
        )
        wait_until(
            lambda: built.watchdog in ros.publishers(RELAY),
            "the watchdog relaying the blocked topic",
            15,
            (system,),
        )
    finally:
        ros.stop(*started)
        runtime.write_text(source, encoding="utf-8")
        trigger.unlink(missing_ok=True)
