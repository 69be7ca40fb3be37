"""The generated ROS 1 monitor on real ROS 1 (thesis 4.3).

The module records the nominal test system, learns its invariants, builds the monitor package
with ``imrosc build --backend ros1``, puts it on ``ROS_PACKAGE_PATH`` and starts the system
through the package's rewritten launch file (``launch/system_monitored.launch``: the state
machine hears ``/m/a/cmd_subject_ctrl_state``, the monitor's relay of the blocked command
topic). Then it injects faults into the running system, one test each, and watches
``/m/broken_inv``, the relay, the action and the master.

The invariants file carries no alarm rule (``alarms``), so every violation is an alarm: each
blocks and acts, as the thesis' monitor does. The last test restarts the system with the rule
``{"persist": 3}`` in the package's copy of the file: the monitor acts, and blocks, from the
third violating message on.

The car's poses (point v) break their rate invariants now and then in nominal operation
(window ends jitter by a few ms); every check here names the invariant it expects, and the
command topic (point a: a constant at 5 Hz) breaks nothing nominal.
"""

from __future__ import annotations

import json
import time
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import pytest
from click.testing import CliRunner

from imrosc.cli import main
from imrosc.detect import run_detect
from imrosc.invariants import dumps
from tests.live.harness import HERE, Listener, Proc, Ros, live_config, record_nominal, wait_until

pytestmark = pytest.mark.live

GRAPH = HERE / "landing_live.graph.yaml"
POSE, COMMAND = "/a/car_pose", "/a/cmd_subject_ctrl_state"
RELAY = "/m/a/cmd_subject_ctrl_state"
BROKEN, CLEAR = "/m/broken_inv", "/m/clear_inv"
ROSOUT = "/rosout"
"""Where rospy nodes log (the monitor's warnings among them)."""
Z_BOUNDS = "0.1 <= car_pose.pose.position.z <= 0.18"
COMMAND_IS_3 = "cmd_subject_ctrl_state.data == 3"


@dataclass
class Monitored:
    """The monitored system and what the tests watch it with."""

    ros: Ros
    system: Proc
    monitor: str
    invariants: dict[str, dict[str, Any]]
    commands: Path
    watch: Listener
    package: Path
    launch: Path

    def reports(self, since: float = 0.0) -> list[dict[str, Any]]:
        """The violations published on /m/broken_inv (received after ``since``)."""
        found = []
        for record in self.watch.messages(BROKEN):
            if record["t"] >= since:
                report: dict[str, Any] = json.loads(record["msg"]["data"])
                report["received"] = record["t"]
                found.append(report)
        return found

    def wait_report(self, text: str, since: float, timeout: float = 10.0) -> dict[str, Any]:
        """The first report of the invariant printed ``text`` received after ``since``."""

        def seen() -> dict[str, Any] | None:
            return next((r for r in self.reports(since) if r["text"] == text), None)

        return wait_until(seen, f"{text!r} on {BROKEN}", timeout, (self.system, self.watch.proc))

    def received(self, since: float = 0.0) -> list[dict[str, Any]]:
        """The commands the state machine received (after ``since``)."""
        lines = self.commands.read_text(encoding="utf-8").splitlines()
        return [r for r in map(json.loads, lines) if r["t"] >= since]

    def id_of(self, text: str) -> str:
        (ident,) = [i for i, inv in self.invariants.items() if inv["text"] == text]
        return ident


@pytest.fixture(scope="module")
def monitored(ros: Ros, tmp_path_factory: pytest.TempPathFactory) -> Iterator[Monitored]:
    folder = tmp_path_factory.mktemp("monitor")
    config = live_config(folder)
    nominal = ros.start_system()
    record_nominal(ros, folder / "bags" / "nominal")
    ros.stop(nominal)

    detected = run_detect(config, workers=1)
    assert detected.ok and detected.document is not None, [str(d) for d in detected.diagnostics]
    # every violation an alarm here (a calibrated rule would hold back single bad messages)
    document = {k: v for k, v in detected.document.items() if k != "alarms"}
    (folder / "landing_live.inv").write_text(dumps(document), encoding="utf-8")
    out = folder / "build"
    built = CliRunner().invoke(
        main, ["build", str(config), "--backend", "ros1", "-o", str(out), "--graph", str(GRAPH)]
    )
    assert built.exit_code == 0, built.output
    (package,) = [p for p in out.iterdir() if (p / "package.xml").exists()]
    spec = json.loads((package / "scripts/imrosc_monitor/spec.json").read_text())
    launch = package / "launch" / "system_monitored.launch"
    assert launch.exists(), built.output

    ros.add_package_path(out)
    commands = folder / "commands.jsonl"
    watch = ros.listen(BROKEN, POSE, ROSOUT)
    monitor = "/" + spec["node"]
    invariants = {i["id"]: i for i in document["invariants"]}
    system = ros.start_system(launch, log=commands)
    graph = Monitored(ros, system, monitor, invariants, commands, watch, package, launch)
    wait_monitored(graph, 0.0)
    yield graph


def wait_monitored(monitored: Monitored, since: float) -> None:
    """Wait until the monitor of a (re)started system watches both topics and relays the
    commands (one relayed received after ``since``)."""
    ros, system, monitor = monitored.ros, monitored.system, monitored.monitor
    for topic in (POSE, COMMAND):
        ros.wait_subscriber(topic, monitor, 30, (system,))
    ros.wait_subscriber(RELAY, "/a/ctrl_state_machine", 30, (system,))
    commands = monitored.commands
    wait_until(
        lambda: (
            commands.exists() and any(r["callerid"] == monitor for r in monitored.received(since))
        ),
        "a command relayed by the monitor",
        20,
        (system,),
    )


def test_the_system_runs_through_the_monitor(monitored: Monitored) -> None:
    ros = monitored.ros
    assert ros.publishers(RELAY) == {monitored.monitor}
    assert ros.subscribers(COMMAND) == {monitored.monitor}  # the state machine moved away
    time.sleep(1.0)
    received = monitored.received()
    assert {r["callerid"] for r in received} == {monitored.monitor}
    assert {r["data"] for r in received} == {3}
    assert not [r for r in monitored.reports() if r["point"] == "a"]


def test_the_monitor_asks_for_tcp_nodelay_on_the_topics_it_relays(monitored: Monitored) -> None:
    """A relay must not add Nagle's delay: the monitor's connection to the publisher of the
    blocked topic has TCP_NODELAY; a topic it only watches keeps rospy's default."""
    ros = monitored.ros
    connections = {node: ros.connections(node) for node in ("/a/car_ctrl", "/a/car")}
    assert f"{COMMAND} {monitored.monitor} 1" in connections["/a/car_ctrl"], connections
    assert f"{POSE} {monitored.monitor} 0" in connections["/a/car"], connections


def test_an_out_of_range_value_is_reported(monitored: Monitored) -> None:
    since = time.time()
    monitored.ros.inject("/a/car", "out_of_range:1")
    report = monitored.wait_report(Z_BOUNDS, since)
    assert report["observed"] == 50.0
    assert report["point"] == "v"
    assert report["family"] == "bounds"
    assert report["invariant"] == monitored.id_of(Z_BOUNDS)
    assert (report["alarm"], report["rule"]) == (True, "persist")  # no rule: each alarms
    assert report["actions"] == []  # v takes no action
    time.sleep(0.3)
    z_reports = [r for r in monitored.reports() if r["text"] == Z_BOUNDS]
    assert z_reports == [report]  # one bad message, one report; the good ones broke nothing


def test_a_bad_command_is_blocked_and_the_action_fires(monitored: Monitored) -> None:
    since = time.time()
    monitored.ros.inject("/a/car_ctrl", "out_of_range:1")
    report = monitored.wait_report(COMMAND_IS_3, since)
    assert report["observed"] == 9.0
    assert (report["alarm"], report["rule"], report["actions"]) == (True, "persist", ["f"])
    wait_until(
        lambda: [r["data"] for r in monitored.received(report["received"])].count(3) >= 3,
        "good commands after the bad one",
    )
    received = monitored.received(since)
    values = [r["data"] for r in received]
    assert 9 not in values  # blocked
    assert values.count(2) == 1  # the action: state 2 on the relay, once
    assert {r["callerid"] for r in received} == {monitored.monitor}
    action = next(r for r in received if r["data"] == 2)
    assert action["t"] - report["received"] < 1.0
    # one report on a: the good commands around the bad one break nothing
    assert [r["text"] for r in monitored.reports(since) if r["point"] == "a"] == [COMMAND_IS_3]
    # and the node's log says it blocked it
    blocked = f"imrosc: blocked a message on {COMMAND} (alarm of {report['invariant']})"
    monitored.watch.wait(
        lambda logs: any(r["msg"]["msg"] == blocked for r in logs), blocked, topic=ROSOUT
    )


def test_a_silent_publisher_breaks_its_frequency_by_timer(monitored: Monitored) -> None:
    (frequency,) = [
        inv
        for inv in monitored.invariants.values()
        if inv["family"] == "frequency" and inv["point"] == "v"
    ]
    since = time.time()
    monitored.ros.inject("/a/car", "silent")
    try:
        report = monitored.wait_report(frequency["text"], since, timeout=5.0)
        time.sleep(0.2)
        poses = monitored.watch.messages(POSE)
    finally:
        monitored.ros.delete_param("/a/car/fault")
    assert report["observed"] < frequency["params"]["min"]
    assert (report["alarm"], report["rule"]) == (True, "event")  # found by the timer
    last = max(p["t"] for p in poses if p["t"] <= report["received"])
    assert last >= since - 0.1  # the car published until it fell silent
    assert report["received"] - last >= 0.09  # two periods without a pose: no pose woke it
    assert report["received"] - since < 2.0  # the monitor's period is 0.5 s
    assert [p for p in poses if p["t"] > last] == []  # silent until resumed
    monitored.watch.wait(
        lambda found: any(p["t"] > report["received"] for p in found),
        "the car to resume",
        5,
        POSE,
    )


def test_an_extra_publisher_is_reported_and_unregistered(monitored: Monitored) -> None:
    """The master forgets the intruder: it tells the subscribers (roscpp ones drop their
    connection to it; rospy ones keep what they have) and no later subscriber hears it. The
    topic is watched, not blocked: the system's rospy subscribers still hear the intruder, so
    the monitor keeps its own connection, and each message the intruder sends breaks
    ``max_pubs`` (in the alarm its first raised) and no other invariant: its values are not
    the system's data (``Engine.intruder``)."""
    ros = monitored.ros
    since = time.time()
    intruder = ros.node("car.py", name="intruder", namespace="/a")
    try:
        report = monitored.wait_report("max_pubs(/a/car_pose) = {/a/car}", since)
        assert report["observed"] == ["/a/intruder"]
        assert report["family"] == "architecture"
        assert (report["alarm"], report["rule"]) == (True, "event")
        wait_until(lambda: ros.publishers(POSE) == {"/a/car"}, "the master to drop /a/intruder")
        assert intruder.alive  # still running and publishing, but unknown to the master
        late = ros.listen(POSE)
        assert {m["callerid"] for m in late.wait_count(10)} == {"/a/car"}
        since = time.time()
        ros.inject("/a/intruder", "out_of_range:1")
        monitored.wait_report("max_pubs(/a/car_pose) = {/a/car}", since)
        time.sleep(1.0)
        reports = monitored.reports(since)
        intruding = [r for r in reports if r["text"] == "max_pubs(/a/car_pose) = {/a/car}"]
        assert len(intruding) >= 5  # the intruder publishes at 20 Hz: every message
        assert all(r["observed"] == ["/a/intruder"] and r["alarm"] for r in intruding)
        assert all(r["rule"] is None for r in intruding)  # no new alarm, no new action
        assert Z_BOUNDS not in {r["text"] for r in reports}  # its 50 m poses are not data
    finally:
        ros.stop(intruder)


def test_clear_inv_stops_a_report(monitored: Monitored) -> None:
    ros = monitored.ros
    ident = monitored.id_of(Z_BOUNDS)
    since = time.time()
    ros.inject("/a/car", "out_of_range:1")
    monitored.wait_report(Z_BOUNDS, since)

    message = json.dumps({"data": ident})
    clear = ros.node(
        "pub.py", CLEAR, "std_msgs/String", message, "--count", "1", "--wait-subscribers", "1"
    )
    try:
        wait_until(
            lambda: f"invariant {ident} cleared" in monitored.system.tail(400),
            f"the monitor to clear {ident}",
            10,
            (clear, monitored.system),
        )
    finally:
        ros.stop(clear)
    since = time.time()
    ros.inject("/a/car", "out_of_range:1")
    others = wait_until(
        lambda: [
            r for r in monitored.reports(since) if "position.z" in r["text"] and r["point"] == "v"
        ],
        "the other invariants of z to break",
    )
    time.sleep(0.5)
    reports = monitored.reports(since)
    assert others and Z_BOUNDS not in {r["text"] for r in reports}
    assert ident not in {r["invariant"] for r in reports}


def test_a_persistence_rule_acts_on_the_third_violating_message(monitored: Monitored) -> None:
    """With ``{"persist": 3}`` in the invariants file, three bad commands in a row give two
    violations alone (``"alarm": false``, relayed, no action) and then an alarm: the third
    is withheld and the action fires, once. Restarts the system, so it runs last."""
    ros = monitored.ros
    copy = monitored.package / "config" / "invariants.json"
    document = json.loads(copy.read_text(encoding="utf-8"))
    document["alarms"] = {"persist": 3}
    copy.write_text(json.dumps(document), encoding="utf-8")
    ros.stop(monitored.system)
    restarted = time.time()
    monitored.system = ros.start_system(monitored.launch, log=monitored.commands)
    wait_monitored(monitored, restarted)

    since = time.time()
    ros.inject("/a/car_ctrl", "out_of_range:3")

    def three() -> list[dict[str, Any]] | None:
        found = [r for r in monitored.reports(since) if r["text"] == COMMAND_IS_3]
        return found if len(found) >= 3 else None

    reports = wait_until(three, f"three reports of {COMMAND_IS_3!r}", 10, (monitored.system,))
    assert [(r["alarm"], r["rule"], r["actions"]) for r in reports] == [
        (False, None, []),
        (False, None, []),
        (True, "persist", ["f"]),
    ]
    wait_until(
        lambda: [r["data"] for r in monitored.received(reports[-1]["received"])].count(3) >= 3,
        "good commands after the bad ones",
    )
    time.sleep(0.3)
    values = [r["data"] for r in monitored.received(since)]
    assert values.count(9) == 2  # the two violations alone were relayed, the alarm withheld
    assert values.count(2) == 1  # the action, once
    assert values.index(2) > max(k for k, v in enumerate(values) if v == 9)
    assert len(three() or ()) == 3  # the good commands after them broke nothing
