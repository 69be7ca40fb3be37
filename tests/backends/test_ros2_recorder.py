"""The ROS 2 recorder in the ``ros2`` package: its files (compiled, linted for Python 3.8,
installed by ``setup.py``, launched by XML), and its plain logic: records that the
translator's readers (:mod:`imrosc.records`) accept, change detection, and service calls
paired from synthetic introspection events.

The live half (the rendered recorder node on a ROS 2 graph with service introspection)
runs with an rclpy interpreter (``IMROSC_ROS2_PYTHON``; ``tests/backends/ros2_support.py``).
"""

from __future__ import annotations

import json
import py_compile
import subprocess
import sys
import textwrap
import time
from collections.abc import Iterator
from pathlib import Path

import pytest
from lxml import etree

import imrosc.backends.ros2 as ros2_backend
from imrosc import records
from imrosc.backends.registry import GENERATED_MARK
from imrosc.backends.vendor import NOT_COPIED
from imrosc.onboard.record_ros2 import logic
from tests.backends.monitor_support import ROOT, write_package
from tests.backends.ros1_support import python38
from tests.backends.ros2_build import (
    PACKAGE,
    VENDOR,
    build_ros2,
    python_files,
    setup_arguments,
)
from tests.backends.ros2_support import require_ros2, ros2_environment
from tests.backends.support import assert_carried_unchanged, vendored_sources

RECORDER = ROOT / "imrosc" / "onboard" / "record_ros2"


@pytest.fixture(scope="module")
def recorder_package(landing_ros2: Path) -> Iterator[dict[str, bytes]]:
    """The landing example's ros2 package, built with the recorder."""
    with pytest.MonkeyPatch.context() as patch:
        patch.setattr(ros2_backend, "RENDER_RECORDER", True)
        result = build_ros2(
            landing_ros2 / "landing_sim.xml", [landing_ros2 / "landing_sim.graph.yaml"]
        )
    assert result.ok, [d.as_text() for d in result.diagnostics]
    yield result.files


# -- the package ----------------------------------------------------------------------------


def _without_recorder(landing_ros2: Path) -> dict[str, bytes]:
    with pytest.MonkeyPatch.context() as patch:
        patch.setattr(ros2_backend, "RENDER_RECORDER", False)
        result = build_ros2(
            landing_ros2 / "landing_sim.xml", [landing_ros2 / "landing_sim.graph.yaml"]
        )
    assert result.ok
    return result.files


def test_the_ros2_package_carries_the_recorder_by_default() -> None:
    assert ros2_backend.RENDER_RECORDER is True


def test_without_the_switch_the_package_has_no_recorder(landing_ros2: Path) -> None:
    files = _without_recorder(landing_ros2)
    assert not [name for name in files if "recorder" in name or "record_ros2" in name]


def test_the_recorder_adds_its_files_and_leaves_the_monitor_alone(
    recorder_package: dict[str, bytes], landing_ros2: Path
) -> None:
    plain_files = _without_recorder(landing_ros2)
    added = set(recorder_package) - set(plain_files)
    copies = {
        f"{PACKAGE}/{VENDOR}/onboard/record_ros2/{p.name}"
        for p in RECORDER.glob("*.py")
        if f"onboard/record_ros2/{p.name}" not in NOT_COPIED  # the tap and imrosc record's entry
    }
    assert len(copies) == 3  # __init__, logic, node
    assert added == {
        f"{PACKAGE}/{PACKAGE}/recorder.py",
        f"{PACKAGE}/{PACKAGE}/recorder.json",
        f"{PACKAGE}/launch/{PACKAGE}_recorder.launch.xml",
        *copies,
    }
    changed = {n for n in plain_files if plain_files[n] != recorder_package[n]}
    assert changed == {f"{PACKAGE}/setup.py"}
    assert_carried_unchanged(
        recorder_package, vendored_sources(f"{PACKAGE}/{PACKAGE}", ("onboard/record_ros2",))
    )


def test_the_recorder_spec_is_the_scope(recorder_package: dict[str, bytes]) -> None:
    spec = logic.check_spec(json.loads(recorder_package[f"{PACKAGE}/{PACKAGE}/recorder.json"]))
    assert spec["services"] == ["/a/execute_task", "/a/poll_status"]
    assert "/a/car_ctrl/landing_radius" in spec["params"]
    assert spec["params"] == sorted(spec["params"])
    assert spec["period"] > 0
    assert GENERATED_MARK in spec["$comment"]


def test_setup_py_installs_the_recorder(recorder_package: dict[str, bytes], tmp_path: Path) -> None:
    package = write_package(recorder_package, tmp_path)
    arguments = setup_arguments(package)
    scripts = arguments["entry_points"]["console_scripts"]
    assert f"{PACKAGE}_recorder = {PACKAGE}.recorder:main" in scripts
    assert f"{PACKAGE} = {PACKAGE}.main:monitor" in scripts
    assert f"{PACKAGE}.{VENDOR.split('/')[1]}.onboard.record_ros2" in arguments["packages"]
    for dotted in arguments["packages"]:
        assert (package / dotted.replace(".", "/") / "__init__.py").is_file(), dotted
    assert arguments["package_data"] == {PACKAGE: ["spec.json", "recorder.json"]}
    data = dict(arguments["data_files"])
    assert f"launch/{PACKAGE}_recorder.launch.xml" in data[f"share/{PACKAGE}/launch"]
    for paths in data.values():
        assert all((package / path).is_file() for path in paths)


def test_the_recorder_launch_file_starts_the_node(recorder_package: dict[str, bytes]) -> None:
    root = etree.fromstring(recorder_package[f"{PACKAGE}/launch/{PACKAGE}_recorder.launch.xml"])
    assert root.tag == "launch"
    (node,) = root.iter("node")
    name = f"{PACKAGE}_recorder"
    assert (node.get("pkg"), node.get("exec"), node.get("name")) == (PACKAGE, name, name)
    params = {p.get("name"): p.get("value") for p in node.iter("param")}
    assert params == {"period": "$(var period)", "call_timeout": "$(var call_timeout)"}
    args = {a.get("name"): a.get("default") for a in root.iter("arg")}
    assert float(args["period"] or "") > 0 and float(args["call_timeout"] or "") > 0
    assert all(a.get("description") for a in root.iter("arg"))


def test_the_recorder_compiles_and_passes_ruff_for_python_38(
    recorder_package: dict[str, bytes], tmp_path: Path
) -> None:
    package = write_package(recorder_package, tmp_path)
    scripts = []
    for name in python_files(recorder_package):
        path = tmp_path / name
        py_compile.compile(str(path), doraise=True, cfile=str(tmp_path / "compiled.pyc"))
        scripts.append(str(path))
    done = subprocess.run(
        [
            *(sys.executable, "-m", "ruff", "check", "--no-cache"),
            *("--config", str(ROOT / "imrosc" / "runtime" / "ruff.toml")),  # the rules, Python 3.8
            *scripts,
        ],
        capture_output=True,
        text=True,
        check=False,
        cwd=package,
    )
    assert done.returncode == 0, done.stdout + done.stderr
    interpreter = python38()
    if interpreter is None:
        return
    script = (
        "import ast, sys\n"
        "for path in sys.argv[1:]:\n"
        "    ast.parse(open(path, encoding='utf-8').read(), path, feature_version=(3, 8))\n"
    )
    checked = subprocess.run(
        [interpreter, "-I", "-c", script, *scripts], capture_output=True, text=True, check=False
    )
    assert checked.returncode == 0, checked.stderr


def test_the_rendered_recorder_imports_and_says_when_rclpy_is_missing(
    recorder_package: dict[str, bytes], tmp_path: Path
) -> None:
    package = write_package(recorder_package, tmp_path)
    probe = subprocess.run(
        [sys.executable, "-c", "import rclpy"],
        capture_output=True,
        check=False,
    )
    if probe.returncode == 0:
        pytest.skip("rclpy is importable here")
    done = subprocess.run(
        [sys.executable, "-c", f"from {PACKAGE}.recorder import main; main()"],
        capture_output=True,
        text=True,
        check=False,
        cwd=package,
        timeout=120,
    )
    assert done.returncode == 1
    assert "rclpy is not importable" in done.stderr


# -- live: the rendered recorder on a ROS 2 graph -------------------------------------------


DRIVER = textwrap.dedent(
    """
    import json, sys, time
    import rclpy
    from rclpy.node import Node
    from rclpy.qos import QoSProfile, DurabilityPolicy, ReliabilityPolicy
    from rclpy.service_introspection import ServiceIntrospectionState
    from std_msgs.msg import String
    from std_srvs.srv import SetBool

    rclpy.init()
    car = Node("car", namespace="/a", parameter_overrides=[])
    car_ctrl = Node("car_ctrl", namespace="/a")
    car_ctrl.declare_parameter("landing_radius", 2.5)
    CONTENTS = ServiceIntrospectionState.CONTENTS

    def serve(request, response):
        response.success, response.message = request.data, "done"
        return response

    server = car.create_service(SetBool, "/a/execute_task", serve)
    server.configure_introspection(car.get_clock(), QoSProfile(depth=10), CONTENTS)
    ctrl = Node("ctrl", namespace="/a")
    client = ctrl.create_client(SetBool, "/a/execute_task")
    client.configure_introspection(ctrl.get_clock(), QoSProfile(depth=10), CONTENTS)
    listener = Node("listener")
    seen = {"/imrosc/arch": [], "/imrosc/params": [], "/imrosc/srvs": []}
    qos = QoSProfile(
        depth=100,
        reliability=ReliabilityPolicy.RELIABLE,
        durability=DurabilityPolicy.TRANSIENT_LOCAL,
    )
    for topic in seen:
        listener.create_subscription(String, topic, lambda m, t=topic: seen[t].append(m.data), qos)
    executor = rclpy.executors.MultiThreadedExecutor()
    for node in (car, car_ctrl, ctrl, listener):
        executor.add_node(node)
    deadline = time.monotonic() + 40
    calls = 0
    while time.monotonic() < deadline:
        executor.spin_once(timeout_sec=0.1)
        if client.service_is_ready() and calls < 2 and time.monotonic() > deadline - 35:
            future = client.call_async(SetBool.Request(data=True))
            executor.spin_until_future_complete(future, timeout_sec=5)
            calls += 1
        served = any("/a/execute_task" in a for a in seen["/imrosc/arch"])
        radius = any("landing_radius" in p for p in seen["/imrosc/params"])
        if served and radius and len(seen["/imrosc/srvs"]) >= 2:
            break
    print(json.dumps(seen))
    """
)


@pytest.mark.live
def test_live_the_recorder_publishes_graph_parameters_and_calls(
    recorder_package: dict[str, bytes], tmp_path: Path
) -> None:
    python = require_ros2()
    package = write_package(recorder_package, tmp_path)
    env = ros2_environment(tmp_path, PYTHONPATH=str(package))
    recorder = subprocess.Popen(
        [
            python,
            "-c",
            f"from {PACKAGE}.recorder import main; main(['--ros-args', '-p', 'period:=0.3'])",
        ],
        env=env,
        stdout=subprocess.PIPE,
        stderr=subprocess.STDOUT,
        text=True,
    )
    try:
        time.sleep(1.0)
        driver = subprocess.run(
            [python, "-c", DRIVER],
            env=env,
            capture_output=True,
            text=True,
            timeout=120,
            check=False,
        )
    finally:
        recorder.terminate()
        try:
            output, _ = recorder.communicate(timeout=30)
        except subprocess.TimeoutExpired:
            recorder.kill()
            output, _ = recorder.communicate()
    assert driver.returncode == 0, driver.stderr + output
    seen = json.loads(driver.stdout.strip().splitlines()[-1])
    archs = [records.decode_arch(text) for text in seen["/imrosc/arch"]]
    assert any(a.services.get("/a/execute_task") == frozenset({"/a/car"}) for a in archs), output
    params = [records.decode_params(text) for text in seen["/imrosc/params"]]
    assert params[-1].params.get("/a/car_ctrl/landing_radius") == 2.5, (seen, output)
    calls = [records.decode_call(text) for text in seen["/imrosc/srvs"]]
    assert len(calls) >= 2, output
    for call in calls:
        assert call.service == "/a/execute_task" and call.ok
        assert call.request == {"data": True}
        assert call.response == {"success": True, "message": "done"}
        assert (call.client, call.server) == ("/a/ctrl", "/a/car"), output
        assert 0 <= call.delay < 5
