"""``rosbag play`` of a training bag into the generated ROS 1 monitor (issue 18): the player
(``/play_<time>``) publishes what the bag recorded on behalf of the nodes that published it
then, so the monitor counts it as them and raises no architecture alarm, unregisters no one,
and keeps checking the values. A ``rosbag record`` (``/record_<time>``) subscribed meanwhile
is a recording tool, not an intruder: no subscriber alarm either."""

from __future__ import annotations

import json
import time
from pathlib import Path

import pytest
from click.testing import CliRunner

from imrosc.cli import main
from imrosc.detect import run_detect
from imrosc.invariants import dumps
from tests.live.harness import HERE, ROSBAG, Ros, live_config, record_nominal, wait_until

pytestmark = pytest.mark.live

GRAPH = HERE / "landing_live.graph.yaml"
POSE = "/a/car_pose"


def test_a_played_training_bag_raises_no_architecture_alarm(ros: Ros, tmp_path: Path) -> None:
    config = live_config(tmp_path)
    system = ros.start_system()
    bags = record_nominal(ros, tmp_path / "bags" / "nominal")
    # the system's own subscribers of the pose (not the rosbag records recording it), as
    # imrosc record would learn them: rosbag record's bags tell no subscriber
    listeners = sorted(n for n in ros.subscribers(POSE) if not n.startswith("/record_"))
    assert listeners, "nobody subscribes to " + POSE
    ros.stop(system)
    detected = run_detect(config, workers=1)
    assert detected.ok and detected.document is not None
    document = {k: v for k, v in detected.document.items() if k != "alarms"}  # all alarm
    pubs = [i for i in document["invariants"] if i["kind"] in ("max_pubs", "min_pubs")]
    assert pubs, "the recording taught no publisher invariant: the test would prove nothing"
    (pose,) = [i for i in pubs if i["kind"] == "max_pubs" and i["params"]["resource"] == POSE]
    document["invariants"].append(
        {
            **pose,
            "id": "isubscribers1",
            "kind": "max_subs",
            "variables": [f"subs({POSE})"],
            "params": {"resource": POSE, "nodes": listeners},
            "text": f"max_subs({POSE}) = {{{', '.join(listeners)}}}",
        }
    )
    (tmp_path / "landing_live.inv").write_text(dumps(document), encoding="utf-8")
    out = tmp_path / "build"
    built = CliRunner().invoke(
        main, ["build", str(config), "--backend", "ros1", "-o", str(out), "--graph", str(GRAPH)]
    )
    assert built.exit_code == 0, built.output
    (package,) = [p for p in out.iterdir() if (p / "package.xml").exists()]
    spec = json.loads((package / "scripts/imrosc_monitor/spec.json").read_text())
    monitor_launch = package / "launch" / f"{package.name}.launch"
    assert monitor_launch.exists(), sorted(p.name for p in (package / "launch").iterdir())
    ros.add_package_path(out)
    # the player advertises at once and publishes after --delay: the monitor starts while
    # it is there, as it would on a robot playing a recording into its monitor
    (whole,) = [b for b in bags if b.name == "nominal.bag"]
    player = ros.spawn("rosbag-play", [str(ROSBAG), "play", "--quiet", "-d", "8", str(whole)])
    started = time.monotonic()
    players = ros.wait_publisher(POSE, None, 30, (player,))
    assert all(node.startswith("/play_") for node in players), players
    recorder = ros.spawn("rosbag-record", [str(ROSBAG), "record", "-a", "-O", str(tmp_path / "r")])

    def recording() -> set[str]:
        return {node for node in ros.subscribers(POSE) if node.startswith("/record_")}

    wait_until(recording, "rosbag record to subscribe", 30, (recorder,))
    monitor = ros.launch(monitor_launch)
    ros.wait_subscriber(POSE, "/" + spec["node"], 30, (monitor,))
    # the monitor's log, not /m/broken_inv: a report published before a subscriber has
    # connected is lost, and the first poll comes at once
    wait_until(lambda: "checking" in monitor.tail(200), "the monitor to start", 30, (monitor,))
    playing = started + 8.0 + 2.0  # two seconds into the bag's 4 s
    time.sleep(max(0.0, playing - time.monotonic()))
    assert player.alive, "the bag ended before the check: slow machine?"
    during = monitor.tail(400)
    assert recording(), "rosbag record left before the check"
    assert "_pubs(" not in during, during  # no intruder, nobody missing while it played
    assert "max_subs(" not in during, during  # the recorder is no intruder
    wait_until(lambda: not player.alive, "rosbag play to finish", 60, (monitor,))
    time.sleep(1.0)
    log = monitor.tail(400)
    assert "max_pubs(" not in log and "unregistered unknown publisher" not in log, log
    assert "checking failed" not in log and monitor.alive, log
    ros.stop(recorder)
