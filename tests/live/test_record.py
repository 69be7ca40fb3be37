"""``imrosc record`` on a real ROS 1 graph, then ``imrosc infer`` on what it recorded.

The system (``record_support.py``): ``/sys/server`` serves ``/sys/scale`` (remapped to
``/rec/sys/scale``, as the recorder needs) and publishes ``/sys/level``; ``/sys/client`` calls
the service at 10 Hz and publishes ``/sys/cmd``; ``/sys/extra`` listens to ``/sys/level`` and
publishes ``/sys/beat`` until the test kills it (SIGKILL: it cannot unregister) in the middle
of the recording. Parameters ``/sys/limit``, ``/sys/mode`` and ``/sys/server/gain`` are set.
The recording is stopped with SIGINT, as Ctrl-C does.

A second, short recording (``--duration``) uses ``--launch``: the server is started by
roslaunch from the rewritten copy of a launch file, after the recording has started.
"""

from __future__ import annotations

import json
import os
import shutil
import signal
import subprocess
import sys
import time
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any, cast

import pytest

from imrosc import records
from imrosc.bags import open_bag
from imrosc.detect import run_detect
from tests.live.harness import ROS_PYTHON, Proc, Ros, token_pids, wait_until
from tests.live.record_support import SCRIPT, XS, expected_y, generate_service_type

pytestmark = pytest.mark.live

ROOT = Path(__file__).resolve().parent.parent.parent

CONFIG = """<imROS project="recsys">
  <scope>
    <publish id="a" relative="1">/sys/cmd</publish>
    <publish id="b">
      <topic>/sys/beat</topic>
      <param>/sys/server/gain</param>
      <param>/sys/mode</param>
    </publish>
    <call id="c"><service>/sys/scale</service><param>/sys/limit</param></call>
    <param id="p">/sys/server/gain</param>
    <arch id="d"/>
  </scope>
  <detect inv="recsys.inv" confidence="0.5" budget="0"><bag>rec</bag></detect>
</imROS>
"""

LAUNCH_CONFIG = """<imROS project="launched">
  <scope>
    <call id="c">/launched/scale</call>
    <arch id="d">srv</arch>
  </scope>
</imROS>
"""

LAUNCH = """<launch>
  <group ns="launched">
    <node pkg="imrosc_rec_sys" type="record_support.py" name="server"
          args="server --service /launched/scale --level /launched/level"/>
    <node pkg="imrosc_rec_sys" type="record_support.py" name="client"
          args="client --service /launched/scale --level /launched/level --cmd /launched/cmd"/>
  </group>
</launch>
"""


@dataclass
class Run:
    """A finished ``imrosc record``: its status and output, and its bag."""

    status: int
    stdout: str
    stderr: str
    bag: Path
    config: Path


def node(ros: Ros, role: str, *args: str) -> Proc:
    return ros.spawn(f"sys-{role}", [str(ROS_PYTHON), str(SCRIPT), role, *args])


def imrosc_record(ros: Ros, folder: Path, *args: str) -> subprocess.Popen[str]:
    """``imrosc record`` as a user runs it (its own process, the graph's environment)."""
    return subprocess.Popen(
        [sys.executable, "-m", "imrosc", "record", *args],
        cwd=ROOT,
        env=ros.env,
        stdout=(folder / "record.out").open("w"),
        stderr=(folder / "record.err").open("w"),
        text=True,
    )


def output(folder: Path) -> tuple[str, str]:
    return (folder / "record.out").read_text(), (folder / "record.err").read_text()


def wait_recording(ros: Ros, folder: Path, process: subprocess.Popen[str], line: str) -> None:
    def started() -> bool:
        if process.poll() is not None:
            raise AssertionError(f"imrosc record exited ({process.returncode}): {output(folder)}")
        return line in output(folder)[0]

    wait_until(started, f"imrosc record to print {line!r}", 40)


@pytest.fixture(scope="module")
def service_type(ros: Ros) -> None:
    """``imrosc_rec_test/Scale`` generated once and on every node's PYTHONPATH."""
    ros.env["PYTHONPATH"] = str(generate_service_type(ros.home / "srv"))


@pytest.fixture(scope="module")
def system(ros: Ros, service_type: None) -> Iterator[dict[str, Proc]]:
    ros.set_param("/sys/limit", 5.0)
    ros.set_param("/sys/mode", "auto")
    procs = {
        "server": node(ros, "server", "__name:=server", "__ns:=/sys", "/sys/scale:=/rec/sys/scale"),
        "client": node(ros, "client", "__name:=client", "__ns:=/sys"),
        "extra": node(ros, "extra", "__name:=extra", "__ns:=/sys"),
    }
    watch = tuple(procs.values())
    ros.wait_publisher("/sys/level", "/sys/server", 30, watch)
    ros.wait_publisher("/sys/cmd", "/sys/client", 30, watch)
    ros.wait_publisher("/sys/beat", "/sys/extra", 30, watch)
    ros.wait_subscriber("/sys/level", "/sys/extra", 30, watch)
    wait_until(lambda: "/rec/sys/scale" in ros.system_state().services, "the server", 30, watch)
    yield procs


@pytest.fixture(scope="module")
def run(ros: Ros, system: dict[str, Proc], tmp_path_factory: pytest.TempPathFactory) -> Run:
    folder = tmp_path_factory.mktemp("record")
    config = folder / "recsys.xml"
    config.write_text(CONFIG, encoding="utf-8")
    out = folder / "rec"
    process = imrosc_record(ros, folder, str(config), "-o", str(out))
    try:
        wait_recording(ros, folder, process, "recording ")
        time.sleep(2.5)
        os.kill(system["extra"].popen.pid, signal.SIGKILL)  # no chance to unregister
        system["extra"].popen.wait(10)
        time.sleep(2.5)
        process.send_signal(signal.SIGINT)  # Ctrl-C
        status = process.wait(60)
    finally:
        if process.poll() is None:
            process.kill()
            process.wait()
    stdout, stderr = output(folder)
    return Run(status, stdout, stderr, out / "recsys.bag", config)


def record_messages(bag: Path) -> list[tuple[str, float, str]]:
    """``(topic, receive time, text)`` of every record in the bag."""
    found = []
    with open_bag(bag) as reader:
        wanted = [c for c in reader.connections if c.topic in records.RECORD_TOPICS]
        for connection, stamp, raw in reader.messages(connections=wanted):
            text = cast(Any, reader.deserialize(raw, connection.msgtype)).data
            found.append((connection.topic, stamp / 1e9, text))
    return found


def test_the_recording_stops_cleanly_on_ctrl_c(ros: Ros, run: Run) -> None:
    assert run.status == 0, run.stderr
    assert "Traceback" not in run.stderr
    assert "relaying /sys/scale (imrosc_rec_test/Scale) to /rec/sys/scale" in run.stdout
    assert f"wrote {run.bag}:" in run.stdout
    assert run.bag.is_file()
    assert not run.bag.with_name(run.bag.name + ".active").exists()
    assert sorted(p.name for p in run.bag.parent.iterdir()) == [".imrosc", "recsys.bag"]
    leftovers = []
    for pid in token_pids(ros.token):
        try:
            command = Path(f"/proc/{pid}/cmdline").read_bytes()
        except OSError:
            continue
        if b"imrosc.onboard.record_ros1.node" in command or b"rosbag/record" in command:
            leftovers.append(command.replace(b"\0", b" ").decode())
    assert leftovers == []
    assert "not in the bag" not in run.stderr  # every record the node published was stored


def test_every_record_decodes_and_the_calls_are_the_system_s(run: Run) -> None:
    found = record_messages(run.bag)
    kinds = {topic for topic, _, _ in found}
    assert kinds == set(records.RECORD_TOPICS)
    calls = []
    for topic, time_, text in found:
        if topic == records.ARCH_TOPIC:
            snapshot = records.decode_arch(text)
            nodes = {n for e in snapshot.topics.values() for n in e.pubs | e.subs}
            nodes |= {n for servers in snapshot.services.values() for n in servers}
            assert not any(n.startswith("/imrosc_") for n in nodes), text
            assert not any(s.startswith("/rec/") for s in snapshot.services)
            assert snapshot.services["/sys/scale"] == {"/sys/server"}
        elif topic == records.PARAMS_TOPIC:
            assert records.decode_params(text).params == {
                "/sys/limit": 5.0,
                "/sys/mode": "auto",
                "/sys/server/gain": 2.0,
            }
        else:
            call = records.decode_call(text)
            assert text == records.encode(call)
            assert call.stamp <= time_
            calls.append(call)
    assert len(calls) >= 30  # 10 Hz for over 5 s
    for call in calls:
        assert (call.service, call.client, call.server, call.ok) == (
            "/sys/scale",
            "/sys/client",
            "/sys/server",
            True,
        )
        assert call.response is not None
        request = call.request
        assert call.response == {"y": expected_y(request["x"], request["k"]), "note": "ok"}  # type: ignore[arg-type]
        assert 0.01 <= call.delay < 1.0  # the server takes 10 ms
    summary = next(line for line in run.stdout.splitlines() if line.startswith("wrote "))
    assert f"{len(calls)} service calls" in summary


def test_the_killed_node_leaves_the_architecture(run: Run) -> None:
    snapshots = [
        records.decode_arch(text)
        for topic, _, text in record_messages(run.bag)
        if topic == records.ARCH_TOPIC
    ]
    first, last = snapshots[0], snapshots[-1]
    assert first.topics["/sys/beat"].pubs == {"/sys/extra"}
    assert first.topics["/sys/level"].subs == {"/sys/client", "/sys/extra"}
    assert "/sys/beat" not in last.topics
    assert last.topics["/sys/level"].subs == {"/sys/client"}
    assert "/sys/extra/get_loggers" not in last.services


@pytest.fixture(scope="module")
def inferred(run: Run) -> dict[str, Any]:
    result = run_detect(run.config, workers=1)
    assert result.document is not None, result.diagnostics
    return result.document


def find(document: dict[str, Any], point: str, text: str) -> dict[str, Any]:
    for invariant in document["invariants"]:
        if invariant["point"] == point and invariant["text"] == text:
            found: dict[str, Any] = invariant
            return found
    shown = "\n".join(i["text"] for i in document["invariants"] if i["point"] == point)
    raise AssertionError(f"no {text!r} at {point}; there are:\n{shown}")


def invariant(document: dict[str, Any], point: str, family: str, variable: str) -> dict[str, Any]:
    for found in document["invariants"]:
        if (found["point"], found["family"], found["variables"]) == (point, family, [variable]):
            result: dict[str, Any] = found
            return result
    raise AssertionError(f"no {family} invariant of {variable} at {point}")


def bounds(document: dict[str, Any], point: str, variable: str) -> dict[str, float]:
    """The bounds learnt for a variable (``min``, ``max`` or both: a bound that changed
    near the end of the run is not justified)."""
    found: dict[str, float] = {}
    for item in document["invariants"]:
        if (item["point"], item["family"], item["variables"]) == (point, "bounds", [variable]):
            found.update({k: v for k, v in item["params"].items() if k in ("min", "max")})
    return found


def test_service_invariants_match_the_server(inferred: dict[str, Any]) -> None:
    delay = bounds(inferred, "c", "scale.delay")
    assert delay, "no bounds of the call delay"
    assert delay.get("min", 0.01) >= 0.01  # the server takes 10 ms
    assert delay.get("max", 0.0) < 1.0
    assert bounds(inferred, "c", "scale.request.x") == {"min": min(XS), "max": max(XS)}
    assert bounds(inferred, "c", "scale.response.y") == {"min": 0.0, "max": expected_y(max(XS), 3)}
    assert invariant(inferred, "c", "one-of", "scale.request.k")["params"]["values"] == [1, 2, 3]
    find(inferred, "c", 'scale.response.note == "ok"')


def test_parameter_values_are_in_the_samples(inferred: dict[str, Any]) -> None:
    find(inferred, "c", "/sys/limit == 5")
    find(inferred, "b", "/sys/server/gain == 2")
    find(inferred, "b", '/sys/mode == "auto"')
    # the parameter never changes: the value in force once a second of the > 5 s recording
    assert inferred["points"]["p"]["support"]["samples"] >= 5


def test_relative_inputs_came_from_the_live_graph(inferred: dict[str, Any]) -> None:
    variables = {v["name"] for v in inferred["points"]["a"]["variables"]}
    assert "level.data" in variables


def test_architecture_sets_match_the_system(inferred: dict[str, Any]) -> None:
    find(inferred, "d", "max_pubs(/sys/beat) = {/sys/extra}")
    find(inferred, "d", "max_subs(/sys/level) = {/sys/client, /sys/extra}")
    find(inferred, "d", "min_subs(/sys/level) = {/sys/client}")  # /sys/extra was killed
    find(inferred, "d", "min_pubs(/sys/level) = {/sys/server}")
    find(inferred, "d", "max_pubs(/sys/level) = {/sys/server}")
    find(inferred, "d", "min_pubs(/sys/cmd) = {/sys/client}")
    find(inferred, "d", "min_srvs(/sys/scale) = {/sys/server}")
    find(inferred, "d", "max_srvs(/sys/scale) = {/sys/server}")
    text = json.dumps(inferred["invariants"])
    assert "imrosc_" not in text
    assert "/rec/" not in text


def test_duration_and_a_launch_file_with_the_server_remapped(
    ros: Ros, service_type: None, tmp_path: Path
) -> None:
    package = tmp_path / "packages" / "imrosc_rec_sys"
    package.mkdir(parents=True)
    (package / "package.xml").write_text(
        '<?xml version="1.0"?>\n<package format="2"><name>imrosc_rec_sys</name>'
        "<version>0.0.0</version><description>test</description>"
        '<maintainer email="imrosc@localhost">imrosc</maintainer><license>Apache-2.0</license>'
        "</package>\n"
    )
    script = package / "record_support.py"
    shutil.copyfile(SCRIPT, script)
    script.chmod(0o755)
    ros.add_package_path(package.parent)
    launch = tmp_path / "system.launch"
    launch.write_text(LAUNCH)
    config = tmp_path / "launched.xml"
    config.write_text(LAUNCH_CONFIG)
    args = (
        "--duration",
        "7",
        "--launch",
        str(launch),
        "--server",
        "/launched/scale=/launched/server",
    )
    process = imrosc_record(ros, tmp_path, str(config), "-o", str(tmp_path / "out"), *args)
    system = None
    try:
        wait_recording(ros, tmp_path, process, "recording ")
        copy = tmp_path / "system.record.launch"
        assert f"roslaunch {copy}" in output(tmp_path)[0]
        assert launch.read_text() == LAUNCH
        system = ros.launch(copy)
        status = process.wait(60)  # --duration
    finally:
        if process.poll() is None:
            process.kill()
            process.wait()
        if system is not None:
            ros.stop(system)
    stdout, stderr = output(tmp_path)
    assert status == 0, stderr
    assert "relaying /launched/scale (imrosc_rec_test/Scale) to /rec/launched/scale" in stdout
    bag = tmp_path / "out" / "launched.bag"
    calls = [
        records.decode_call(text)
        for topic, _, text in record_messages(bag)
        if topic == records.SRVS_TOPIC
    ]
    assert calls, stdout + stderr
    assert {(c.client, c.server) for c in calls} == {("/launched/client", "/launched/server")}
