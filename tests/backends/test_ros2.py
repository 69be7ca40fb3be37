"""Backend ``ros2``: the ament_python package it renders, its flatteners, its rclpy adapter's
decisions, and the same violations as ROS 1 on a ROS 2 bag of the same run.

ROS 2 cannot be installed here (README, "ROS 1 and ROS 2"): what the package is made of is
checked by compiling, linting and parsing it, installing it the way colcon installs an
ament_python package, and running its logic (the generated flatteners, the adapter's plain
functions and the shared engine) on ROS 2 bags (sqlite3 and MCAP) read with rosbags.
"""

from __future__ import annotations

import ast
import configparser
import json
import math
import os
import py_compile
import subprocess
import sys
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from pathlib import Path
from types import ModuleType, SimpleNamespace
from typing import Any

import numpy as np
import pytest
from click.testing import CliRunner
from lxml import etree
from rosbags.highlevel import AnyReader
from rosbags.interfaces import Nodetype

from imrosc import __version__, records
from imrosc.backends.registry import GENERATED_MARK
from imrosc.cli import main
from imrosc.onboard import monitor as common
from imrosc.onboard.monitor_ros1 import messages as ros1_messages
from imrosc.onboard.monitor_ros2 import logic
from imrosc.runtime import Engine, Violation
from imrosc.runtime.flatten import make_flattener
from imrosc.sim import FAMILIES, Scenario, ScenarioKind, write_run
from imrosc.sim.recording import START_NS
from tests.backends.monitor_support import (
    ROOT,
    build_ros1,
    config_text,
    import_adapter,
    write_case,
    write_package,
)
from tests.backends.ros1_support import (
    _xml,
    assert_markers_only_quoted,
    assert_same_values,
    hostile_case,
    python38,
)
from tests.backends.ros2_build import (
    PACKAGE,
    STORE2,
    build_ros2,
    import_package,
    python_files,
    ros2_document,
    setup_arguments,
)
from tests.backends.ros2_support import parameter_value
from tests.backends.support import (
    HOSTILE,
    assert_carried_unchanged,
    assert_every_file_names_its_source,
    vendored_sources,
)

RUNTIME = ROOT / "imrosc" / "runtime"
ADAPTER = ROOT / "imrosc" / "onboard" / "monitor_ros2"
CARRIED = ("runtime", "onboard", "onboard/monitor_ros2", "onboard/record_ros2")
"""The imrosc packages a ROS 2 monitor package with its recorder carries (under
``<package>/imrosc``)."""
OWN = frozenset({f"/{PACKAGE}", f"/{PACKAGE}_watchdog"})


def landing_files(folder: Path) -> dict[str, bytes]:
    result = build_ros2(folder / "landing_sim.xml", [folder / "landing_sim.graph.yaml"])
    assert result.ok, [d.as_text() for d in result.diagnostics]
    return result.files


@pytest.fixture(scope="module")
def landing_package(landing_ros2: Path) -> dict[str, bytes]:
    return landing_files(landing_ros2)


# -- the package ----------------------------------------------------------------------------


def test_the_package_has_every_file(landing_package: dict[str, bytes]) -> None:
    expected = {
        "package.xml",
        "setup.py",
        "setup.cfg",
        f"resource/{PACKAGE}",
        "config/invariants.json",
        f"launch/{PACKAGE}.launch.xml",
        f"{PACKAGE}/__init__.py",
        f"{PACKAGE}/main.py",
        f"{PACKAGE}/flatteners.py",
        f"{PACKAGE}/spec.json",
        *vendored_sources(PACKAGE, CARRIED),
        # the recorder node (tests/backends/test_ros2_recorder.py)
        f"{PACKAGE}/recorder.py",
        f"{PACKAGE}/recorder.json",
        f"launch/{PACKAGE}_recorder.launch.xml",
    }
    assert set(landing_package) == {f"{PACKAGE}/{name}" for name in expected}


def test_the_runtime_the_onboard_logic_and_the_adapters_are_carried_unchanged(
    landing_package: dict[str, bytes],
) -> None:
    assert_carried_unchanged(landing_package, vendored_sources(f"{PACKAGE}/{PACKAGE}", CARRIED))
    # the ROS 1 adapter stays behind
    assert not [name for name in landing_package if "/monitor_ros1/" in name]


def test_every_file_names_generator_version_and_its_source(
    landing_package: dict[str, bytes], landing_ros2: Path
) -> None:
    assert_every_file_names_its_source(landing_package, landing_ros2 / "landing_sim.xml", "ros2")


def test_package_xml_is_format_3_for_ament_python(landing_package: dict[str, bytes]) -> None:
    root = etree.fromstring(landing_package[f"{PACKAGE}/package.xml"])
    assert root.tag == "package" and root.get("format") == "3"
    assert root.findtext("name") == PACKAGE
    assert root.findtext("version") == __version__
    assert (root.findtext("description") or "").startswith("Monitor of the invariants of")
    (maintainer,) = root.iter("maintainer")
    assert maintainer.text and maintainer.get("email")
    assert root.findtext("license") == "Apache-2.0"
    assert [e.text for e in root.iter("buildtool_depend")] == ["ament_python"]
    depends = [e.text or "" for e in root.iter("exec_depend")]
    assert depends == sorted(set(depends))
    assert {
        "rclpy",
        "std_msgs",
        "rcl_interfaces",
        "builtin_interfaces",
        "python3-numpy",
        "geometry_msgs",
        "sensor_msgs",
    } <= set(depends)
    assert "python3-numba" not in depends  # its rosdep key has no Humble or Jazzy Ubuntu
    assert root.findtext("export/build_type") == "ament_python"
    # REP 149's order: the elements format 3 requires come first, export last
    tags = [child.tag for child in root if isinstance(child.tag, str)]
    assert tags[:5] == ["name", "version", "description", "maintainer", "license"]
    assert tags[-1] == "export"


def test_setup_py_and_setup_cfg_describe_an_ament_python_package(
    landing_package: dict[str, bytes], tmp_path: Path
) -> None:
    package = write_package(landing_package, tmp_path)
    tree = ast.parse((package / "setup.py").read_text())
    assert any(isinstance(n, ast.ImportFrom) and n.module == "setuptools" for n in tree.body)
    arguments = setup_arguments(package)
    assert arguments["name"] == PACKAGE and arguments["version"] == __version__
    for dotted in arguments["packages"]:
        assert (package / dotted.replace(".", "/") / "__init__.py").is_file(), dotted
    assert arguments["package_data"] == {PACKAGE: ["spec.json", "recorder.json"]}
    data = dict(arguments["data_files"])
    assert data["share/ament_index/resource_index/packages"] == [f"resource/{PACKAGE}"]
    assert data[f"share/{PACKAGE}"] == ["package.xml"]
    assert data[f"share/{PACKAGE}/config"] == ["config/invariants.json"]
    assert data[f"share/{PACKAGE}/launch"] == [
        f"launch/{PACKAGE}.launch.xml",
        f"launch/{PACKAGE}_recorder.launch.xml",
    ]
    for paths in data.values():
        assert all((package / path).is_file() for path in paths)
    scripts = arguments["entry_points"]["console_scripts"]
    assert scripts == [
        f"{PACKAGE} = {PACKAGE}.main:monitor",
        f"{PACKAGE}_watchdog = {PACKAGE}.main:watchdog",
        f"{PACKAGE}_recorder = {PACKAGE}.recorder:main",
    ]
    main_tree = ast.parse((package / PACKAGE / "main.py").read_text())
    functions = {n.name for n in main_tree.body if isinstance(n, ast.FunctionDef)}
    assert {"monitor", "watchdog"} <= functions
    config = configparser.ConfigParser()
    config.read_string((package / "setup.cfg").read_text())
    assert config["develop"]["script_dir"] == f"$base/lib/{PACKAGE}"
    assert config["install"]["install_scripts"] == f"$base/lib/{PACKAGE}"


def test_colcon_style_install_puts_scripts_data_and_modules_in_place(
    landing_package: dict[str, bytes], tmp_path: Path
) -> None:
    """``colcon build`` runs ``setup.py egg_info build install`` for an ament_python package;
    the same command puts the executables in ``lib/<pkg>`` (``ros2 run``), the launch
    and config files in ``share/<pkg>``, the ament index marker and the modules with
    ``spec.json``; the installed executable starts and, without rclpy, says so."""
    package = write_package(landing_package, tmp_path / "src")
    prefix, work = tmp_path / "install", tmp_path / "work"
    (work / "egg").mkdir(parents=True)
    done = subprocess.run(
        [
            sys.executable,
            "setup.py",
            "-q",
            "egg_info",
            "--egg-base",
            str(work / "egg"),
            "build",
            "--build-base",
            str(work / "build"),
            "install",
            "--prefix",
            str(prefix),
            "--record",
            str(work / "installed.txt"),
            "--single-version-externally-managed",
        ],
        cwd=package,
        capture_output=True,
        text=True,
        check=False,
        timeout=300,
    )
    assert done.returncode == 0, done.stdout + done.stderr
    for name in (PACKAGE, f"{PACKAGE}_watchdog"):
        assert os.access(prefix / "lib" / PACKAGE / name, os.X_OK)
    share = prefix / "share" / PACKAGE
    assert (share / "launch" / f"{PACKAGE}.launch.xml").is_file()
    assert (share / "config" / "invariants.json").is_file()
    assert (share / "package.xml").is_file()
    assert (prefix / "share/ament_index/resource_index/packages" / PACKAGE).is_file()
    (site,) = prefix.glob("lib/python3*/site-packages")
    assert (site / PACKAGE / "spec.json").is_file()
    assert (site / PACKAGE / "imrosc" / "runtime" / "engine.py").is_file()
    assert sorted(p.name for p in package.iterdir()) == sorted(
        ["config", "launch", "package.xml", "resource", "setup.cfg", "setup.py", PACKAGE]
    )  # the source package stays clean
    started = subprocess.run(
        [sys.executable, str(prefix / "lib" / PACKAGE / PACKAGE)],
        capture_output=True,
        text=True,
        check=False,
        env={**os.environ, "PYTHONPATH": str(site)},
        timeout=120,
    )
    assert started.returncode == 1
    assert "rclpy is not importable" in started.stderr


def test_the_monitor_launch_file_starts_the_node_with_its_parameters(
    landing_package: dict[str, bytes],
) -> None:
    root = etree.fromstring(landing_package[f"{PACKAGE}/launch/{PACKAGE}.launch.xml"])
    assert root.tag == "launch"
    node, watchdog = root.iter("node")
    assert (node.get("pkg"), node.get("exec"), node.get("name")) == (PACKAGE, PACKAGE, PACKAGE)
    params = {p.get("name"): p.get("value") for p in node.iter("param")}
    assert params == {
        "invariants": "$(var invariants)",
        "period": "$(var period)",
        "namespace": "/m",
        "watchdog": f"{PACKAGE}_watchdog",
        "service_timeout": "$(var service_timeout)",
        "warm": "$(var warm)",
    }
    args = {a.get("name"): a.get("default") for a in root.iter("arg")}
    assert args["invariants"] == f"$(find-pkg-share {PACKAGE})/config/invariants.json"
    assert args["period"] == "0.5" and args["fail_open"] == "false"
    assert args["warm"] == "0.002"
    assert all(a.get("description") for a in root.iter("arg"))
    assert watchdog.get("if") == "$(var fail_open)"
    assert watchdog.get("exec") == f"{PACKAGE}_watchdog"


def test_python_compiles_and_passes_ruff_for_python_38(
    landing_package: dict[str, bytes], tmp_path: Path
) -> None:
    package = write_package(landing_package, tmp_path)
    scripts = []
    for name in python_files(landing_package):
        path = tmp_path / name
        py_compile.compile(str(path), doraise=True, cfile=str(tmp_path / "compiled.pyc"))
        scripts.append(str(path))
    done = subprocess.run(
        [
            *(sys.executable, "-m", "ruff", "check", "--no-cache"),
            *("--config", str(RUNTIME / "ruff.toml")),  # the project's rules, Python 3.8
            *scripts,
        ],
        capture_output=True,
        text=True,
        check=False,
        cwd=package,
    )
    assert done.returncode == 0, done.stdout + done.stderr


def test_python_3_8_compiles_every_generated_file(
    landing_package: dict[str, bytes], tmp_path: Path
) -> None:
    interpreter = python38()
    if interpreter is None:
        pytest.skip("no working python3.8")
    write_package(landing_package, tmp_path)
    script = (
        "import ast, sys\n"
        "for path in sys.argv[1:]:\n"
        "    ast.parse(open(path, encoding='utf-8').read(), path, feature_version=(3, 8))\n"
        "    compile(open(path, encoding='utf-8').read(), path, 'exec')\n"
    )
    paths = [str(tmp_path / name) for name in python_files(landing_package)]
    done = subprocess.run(
        [interpreter, "-I", "-c", script, *paths],
        capture_output=True,
        text=True,
        check=False,
        timeout=120,
    )
    assert done.returncode == 0, done.stderr


def test_two_builds_give_identical_bytes(landing_ros2: Path) -> None:
    assert landing_files(landing_ros2) == landing_files(landing_ros2)


def test_the_invariants_copy_and_the_spec_are_data(
    landing_package: dict[str, bytes], landing_ros2: Path
) -> None:
    original = json.loads((landing_ros2 / "landing_sim.inv").read_text())
    copy = json.loads(landing_package[f"{PACKAGE}/config/invariants.json"])
    assert GENERATED_MARK in copy.pop("$comment")
    original.pop("$comment")
    assert copy == original
    spec = json.loads(landing_package[f"{PACKAGE}/{PACKAGE}/spec.json"])
    topics = {t["name"]: t for t in spec["topics"]}
    assert topics["/a/car_pose"]["ros2_type"] == "geometry_msgs/msg/PoseStamped"
    assert topics["/a/task_waypose"]["relay"] == "/m/a/task_waypose"
    assert spec["actions"]["f"]["ros2_type"] == "std_msgs/msg/UInt8"


def test_the_resource_marker_is_the_banner_only(landing_package: dict[str, bytes]) -> None:
    marker = landing_package[f"{PACKAGE}/resource/{PACKAGE}"].decode()
    assert marker.count("\n") == 1 and marker.startswith(GENERATED_MARK)


def test_build_writes_the_package_and_keeps_foreign_files(
    landing_ros2: Path, tmp_path: Path
) -> None:
    out = tmp_path / "out"
    args = [
        *("build", str(landing_ros2 / "landing_sim.xml"), "--backend", "ros2"),
        *("-o", str(out), "--graph", str(landing_ros2 / "landing_sim.graph.yaml")),
    ]
    runner = CliRunner()
    first = runner.invoke(main, args)
    assert first.exit_code == 0, first.output
    assert (out / PACKAGE / "setup.py").is_file()
    again = runner.invoke(main, args)  # its own files, the marker included: overwritten
    assert again.exit_code == 0, again.output
    foreign = out / PACKAGE / "setup.cfg"
    foreign.write_text("[develop]\n")
    refused = runner.invoke(main, args)
    assert refused.exit_code == 2 and "not generated by imrosc; use --force" in refused.output
    assert foreign.read_text() == "[develop]\n"


def test_bad_input_exits_non_zero_with_a_diagnostic_and_no_traceback(tmp_path: Path) -> None:
    config = write_case(tmp_path, config_text(monitor=""), None)
    result = CliRunner().invoke(main, ["build", str(config), "--backend", "ros2"])
    assert result.exit_code == 1
    assert f"{config}:1:1: error:" in result.output and "[monitor-missing]" in result.output
    assert "Traceback" not in result.output


# -- the flatteners -------------------------------------------------------------------------

FLAT_TYPES = {
    "/pose": "geometry_msgs/msg/PoseStamped",
    "/imu": "sensor_msgs/msg/Imu",
    "/scan": "sensor_msgs/msg/LaserScan",
    "/text": "std_msgs/msg/String",
    "/level": "std_msgs/msg/UInt8",
    "/battery": "sensor_msgs/msg/BatteryState",
}


def _scalar(kind: str, rng: np.random.Generator) -> Any:
    if kind == "string":
        return f"frame{int(rng.integers(3))}"
    if kind == "bool":
        return bool(rng.random() < 0.5)
    if kind.startswith("float"):
        draw = rng.random()
        return math.nan if draw < 0.1 else math.inf if draw < 0.15 else float(rng.normal())
    return int(rng.integers(0, 100))


def make_message(msgtype: str, rng: np.random.Generator) -> Any:
    """A rosbags ROS 2 message with random values (NaN, inf, empty arrays included)."""
    fields: Any = STORE2.fielddefs[msgtype][1]
    values: dict[str, Any] = {}
    for name, (nodetype, detail) in fields:
        if nodetype == Nodetype.BASE:
            values[name] = _scalar(detail[0], rng)
        elif nodetype == Nodetype.NAME:
            values[name] = make_message(detail, rng)
        else:
            (element, element_detail), size = detail
            count = size or int(rng.integers(0, 6))
            if element == Nodetype.BASE and element_detail[0] == "string":
                values[name] = [_scalar("string", rng) for _ in range(count)]
            elif element == Nodetype.BASE:
                dtype = {"byte": "uint8", "char": "uint8"}.get(element_detail[0], element_detail[0])
                items = [_scalar(element_detail[0], rng) for _ in range(count)]
                values[name] = np.array(items, dtype=dtype)
            else:
                values[name] = [make_message(element_detail, rng) for _ in range(count)]
    return STORE2.types[msgtype](**values)


@pytest.fixture(scope="module")
def flat_package(tmp_path_factory: pytest.TempPathFactory) -> tuple[ModuleType, dict[str, Any]]:
    folder = tmp_path_factory.mktemp("flat2")
    document = ros2_document(FLAT_TYPES)
    scope = "\n    ".join(
        f'<publish id="{ident}">{topic}</publish>'
        for ident, topic in zip("abcdef", sorted(FLAT_TYPES), strict=True)
    )
    config = write_case(folder, config_text(scope=scope), document)
    result = build_ros2(config)
    assert result.ok, [d.as_text() for d in result.diagnostics]
    package = write_package(result.files, folder / "out")
    return import_package(package), document


def test_generated_flatteners_equal_make_flattener_on_ros2_messages(
    flat_package: tuple[ModuleType, dict[str, Any]],
) -> None:
    main_module, document = flat_package
    flatteners = main_module.flatteners.FLATTENERS
    assert set(flatteners) == set(FLAT_TYPES)
    rng = np.random.default_rng(3)
    with np.errstate(all="ignore"):
        for topic, msgtype in FLAT_TYPES.items():
            reference = make_flattener(document["topics"][topic]["variables"])
            for _ in range(25):
                message = make_message(msgtype, rng)
                assert_same_values(flatteners[topic](message), reference(message))


def test_generated_flatteners_read_broken_messages_like_make_flattener(
    flat_package: tuple[ModuleType, dict[str, Any]],
) -> None:
    main_module, document = flat_package
    flatteners = main_module.flatteners.FLATTENERS
    broken = [
        SimpleNamespace(),
        SimpleNamespace(header=None, data="7", cell_voltage=[1.5], ranges="ab", pose=None),
        SimpleNamespace(data=None, cell_voltage=None, ranges=[], intensities=[1, "x"]),
        SimpleNamespace(data=float("nan"), cell_voltage=(2.0, 3.0), ranges=[1.0, 2.0]),
    ]
    for topic in FLAT_TYPES:
        reference = make_flattener(document["topics"][topic]["variables"])
        for message in broken:
            assert_same_values(flatteners[topic](message), reference(message))


# -- the same run as a ROS 1 and a ROS 2 bag: the same violations ---------------------------


def ros1_message(value: Any) -> Any:
    """JSON data as rospy-like messages (``__slots__``), for the ROS 1 adapter's logic."""
    if not isinstance(value, dict):
        return [ros1_message(v) for v in value] if isinstance(value, list) else value
    kind = type("Ros1Message", (), {"__slots__": tuple(value)})
    message = kind()
    for key, item in value.items():
        setattr(message, key, ros1_message(item))
    return message


def ros2_message(value: Any) -> Any:
    """JSON data as rclpy-like messages (``get_fields_and_field_types``)."""
    if not isinstance(value, dict):
        return [ros2_message(v) for v in value] if isinstance(value, list) else value
    fields = {key: "unknown" for key in value}
    message = SimpleNamespace(**{key: ros2_message(item) for key, item in value.items()})
    message.get_fields_and_field_types = lambda: fields
    return message


@dataclass
class Flavour:
    """How one middleware's node turns what happens into the engine's input."""

    flatteners: Mapping[str, Callable[[Any], list[Any]]]
    graph: Callable[[records.ArchSnapshot], Any]
    params: Callable[[Mapping[str, Any]], dict[str, Any]]
    call: Callable[[records.ServiceCall], dict[str, Any]]


def ros1_flavour(
    flatteners: Mapping[str, Callable[[Any], list[Any]]], spec: Mapping[str, Any]
) -> Flavour:
    relays = {t["name"]: t["relay"] for t in spec["topics"] if t["relay"]}
    services = {s["name"]: s["relay"] for s in spec["services"]}

    def graph(arch: records.ArchSnapshot) -> Any:
        state = [
            [[t, sorted(ends.pubs)] for t, ends in sorted(arch.topics.items())],
            [[t, sorted(ends.subs)] for t, ends in sorted(arch.topics.items())],
            [[s, sorted(nodes)] for s, nodes in sorted(arch.services.items())],
        ]  # the master's getSystemState
        return common.logical_graph(state, OWN, relays, services)

    def params(server: Mapping[str, Any]) -> dict[str, Any]:
        return common.param_values(server.__getitem__, spec["params"])  # rospy.get_param

    def call(record: records.ServiceCall) -> dict[str, Any]:
        request, response = ros1_message(record.request), ros1_message(record.response)
        return common.call_values(ros1_messages.message_data, request, response, record.delay)

    return Flavour(flatteners, graph, params, call)


def ros2_flavour(
    flatteners: Mapping[str, Callable[[Any], list[Any]]],
    spec: Mapping[str, Any],
    offered: Mapping[str, Any],
) -> Flavour:
    relays = {t["name"]: t["relay"] for t in spec["topics"] if t["relay"]}
    services = {s["name"]: s["relay"] for s in spec["services"]}

    def view(arch: records.ArchSnapshot) -> logic.GraphView:
        """What rclpy's graph API answers for this graph (QoS as the bag recorded it)."""
        topics = {t: (sorted(e.pubs), sorted(e.subs)) for t, e in arch.topics.items()}
        qos = {
            t: [(node, logic.endpoint_qos(offered.get(t))) for node in sorted(e.pubs)]
            for t, e in arch.topics.items()
        }
        nodes = {n for e in arch.topics.values() for n in e.pubs | e.subs}
        nodes |= {n for served in arch.services.values() for n in served}
        served = {s: sorted(n) for s, n in arch.services.items()}
        return logic.GraphView(topics, {}, qos, served, {}, sorted(nodes))

    latest: dict[str, logic.GraphView] = {}

    def graph(arch: records.ArchSnapshot) -> Any:
        latest["view"] = view(arch)
        return logic.snapshot(latest["view"], OWN, relays, services)

    def params(server: Mapping[str, Any]) -> dict[str, Any]:
        nodes = latest["view"].nodes if latest else ()
        answers: dict[str, Any] = {}
        for owner, asked in logic.parameter_requests(spec["params"], nodes).items():
            values = [  # GetParameters on <owner>/get_parameters
                parameter_value(server.get(owner.rstrip("/") + "/" + name.replace(".", "/")))
                for _, name in asked
            ]
            answered, _ = logic.parameter_answers(asked, values)
            answers.update(answered)
        return logic.param_values(answers, spec["params"])

    def call(record: records.ServiceCall) -> dict[str, Any]:
        request, response = ros2_message(record.request), ros2_message(record.response)
        return common.call_values(logic.message_data, request, response, record.delay)

    return Flavour(flatteners, graph, params, call)


def feed_like_a_node(
    bag: Path, document: Mapping[str, Any], flavour: Flavour, period: float
) -> list[Violation]:
    """Feed a bag to the engine as a monitor node's callbacks do: each message of a watched
    topic flattened (after advancing the clock), each relayed service call as it ends, and
    a poll every ``period`` (from the first message on) that advances the clock and feeds
    the graph and the parameters in force when they changed."""
    engine = Engine(document)
    found: list[Violation] = []
    world: dict[str, Any] = {}
    seen: dict[str, Any] = {}

    def poll(now: float) -> list[Violation]:
        out = engine.advance(now)
        if "graph" in world:
            graph = flavour.graph(world["graph"])
            if graph != seen.get("graph"):
                seen["graph"] = graph
                out += engine.graph(now, graph)
        if "params" in world:
            params = flavour.params(world["params"])
            if params != seen.get("params"):
                seen["params"] = params
                out += engine.params(now, params)
        return out

    next_poll: float | None = None
    with AnyReader([bag]) as reader, np.errstate(all="ignore"):
        for connection, stamp, raw in reader.messages():
            now = stamp / 1e9
            next_poll = now if next_poll is None else next_poll
            while next_poll <= now:
                found += poll(next_poll)
                next_poll += period
            message: Any = reader.deserialize(raw, connection.msgtype)
            topic = connection.topic
            if topic == records.ARCH_TOPIC:
                world["graph"] = records.decode_arch(message.data)
            elif topic == records.PARAMS_TOPIC:
                world["params"] = records.decode_params(message.data).params
            elif topic == records.SRVS_TOPIC:
                call = records.decode_call(message.data)
                found += engine.advance(now)
                found += engine.call(call.service, now, flavour.call(call))
            elif topic in flavour.flatteners:
                found += engine.advance(now)
                found += engine.message(topic, now, flavour.flatteners[topic](message))
    return found


def offered_qos(bag: Path) -> dict[str, Any]:
    with AnyReader([bag]) as reader:
        extensions: dict[str, Any] = {c.topic: c.ext for c in reader.connections}
    return {topic: ext.offered_qos_profiles[0] for topic, ext in extensions.items()}


@pytest.fixture(scope="module")
def both_packages(
    landing_ros2: Path, landing_package: dict[str, bytes], tmp_path_factory: pytest.TempPathFactory
) -> tuple[Any, Any, dict[str, Any]]:
    """The ROS 1 and the ROS 2 package of the same config and invariants: their generated
    flatteners and the ROS 2 spec."""
    folder = tmp_path_factory.mktemp("both")
    ros1 = build_ros1(landing_ros2 / "landing_sim.xml", [landing_ros2 / "landing_sim.graph.yaml"])
    assert ros1.ok, [d.as_text() for d in ros1.diagnostics]
    flatteners1 = import_adapter(write_package(ros1.files, folder / "ros1")).FLATTENERS
    main2 = import_package(write_package(landing_package, folder / "ros2"))
    spec = json.loads(landing_package[f"{PACKAGE}/{PACKAGE}/spec.json"])
    return flatteners1, main2.flatteners.FLATTENERS, spec


@pytest.mark.parametrize("kind", ["spoofed", "tilt", "extra_publisher"])
def test_a_ros2_bag_breaks_the_same_invariants_as_the_ros1_bag_of_the_same_run(
    kind: ScenarioKind,
    landing_ros2: Path,
    both_packages: tuple[Any, Any, dict[str, Any]],
    tmp_path: Path,
) -> None:
    flatteners1, flatteners2, spec = both_packages
    document = json.loads((landing_ros2 / "landing_sim.inv").read_text())
    scenario = Scenario(kind, start=4.0)
    bags = {  # the twin of a training run: only the fault breaks invariants
        fmt: write_run(
            tmp_path / ("run.bag" if fmt == "ros1" else f"run_{fmt}"),
            seed=0,
            fmt=fmt,
            duration=8.0,
            scenario=scenario,
        )
        for fmt in ("ros1", "sqlite3", "mcap")
    }
    period = float(spec["period"])
    ros1 = feed_like_a_node(bags["ros1"], document, ros1_flavour(flatteners1, spec), period)
    found = {"ros1": [v.as_json() for v in ros1]}
    for fmt in ("sqlite3", "mcap"):
        flavour = ros2_flavour(flatteners2, spec, offered_qos(bags[fmt]))
        found[fmt] = [v.as_json() for v in feed_like_a_node(bags[fmt], document, flavour, period)]
    assert found["ros1"], f"the {kind} run should break invariants"
    assert found["sqlite3"] == found["ros1"]
    assert found["mcap"] == found["ros1"]
    families = {v.family for v in ros1}
    assert families & set(FAMILIES[kind]), (kind, families)
    assert min(v.time for v in ros1) >= START_NS / 1e9 + scenario.start
    if kind == "extra_publisher":  # ROS 2 can only warn, and says so
        (broken,) = [v for v in ros1 if v.kind == "max_pubs"]
        assert broken.observed == ["/a/car2"]
        warning = json.loads(logic.warning(broken, ["f"]))
        assert warning["note"] == logic.NO_MASTER
        assert warning["invariant"] == broken.invariant and warning["actions"] == ["f"]


def test_both_nodes_see_the_same_graph_parameters_and_calls(
    landing_ros2: Path, both_packages: tuple[Any, Any, dict[str, Any]]
) -> None:
    flatteners1, flatteners2, spec = both_packages
    (bag,) = sorted((landing_ros2 / "bags" / "nominal").iterdir())[:1]
    ros1 = ros1_flavour(flatteners1, spec)
    ros2 = ros2_flavour(flatteners2, spec, offered_qos(bag))
    seen: dict[str, Any] = {}
    with AnyReader([bag]) as reader:
        for connection, _, raw in reader.messages():
            if connection.topic in records.RECORD_TOPICS and connection.topic not in seen:
                record: Any = reader.deserialize(raw, connection.msgtype)
                seen[connection.topic] = record.data
    arch = records.decode_arch(seen[records.ARCH_TOPIC])
    graph = ros2.graph(arch)
    assert graph == ros1.graph(arch) and graph["sub"] and graph["srv"]
    server = records.decode_params(seen[records.PARAMS_TOPIC]).params
    params = ros2.params(server)
    assert params == ros1.params(server)
    assert set(params) == set(spec["params"])
    call = records.decode_call(seen[records.SRVS_TOPIC])
    assert ros2.call(call) == ros1.call(call)
    assert set(ros2.call(call)) == {"delay", "response.state", "response.status"}


def test_a_nominal_ros2_run_breaks_nothing(
    landing_ros2: Path, both_packages: tuple[Any, Any, dict[str, Any]]
) -> None:
    _, flatteners2, spec = both_packages
    document = json.loads((landing_ros2 / "landing_sim.inv").read_text())
    (bag,) = sorted((landing_ros2 / "bags" / "nominal").iterdir())[:1]
    flavour = ros2_flavour(flatteners2, spec, offered_qos(bag))
    found = feed_like_a_node(bag, document, flavour, float(spec["period"]))
    assert [v.as_json() for v in found] == []


# -- nothing from the inputs becomes code ---------------------------------------------------

ROS2_SYSTEM = (
    '<launch>\n  <node pkg="zqproj" exec="motor" name="motor" namespace="zqtopic"/>\n</launch>\n'
)


def hostile_ros2_case(folder: Path) -> Path:
    config = hostile_case(folder)
    config.write_text(
        config.read_text().replace('launch="system.launch"', 'launch="system.launch.xml"')
    )
    (folder / "system.launch.xml").write_text(ROS2_SYSTEM)
    return config


def test_no_string_from_the_inputs_reaches_generated_code_unquoted(tmp_path: Path) -> None:
    config = hostile_ros2_case(tmp_path)
    result = build_ros2(config, [tmp_path / "graph.yaml"])
    assert result.ok, [d.as_text() for d in result.diagnostics]
    files = result.files
    code = python_files(files)
    for name, content in code.items():
        text = content.decode("utf-8")
        compile(text, name, "exec")
        assert_markers_only_quoted(name, text)
    rendered = "".join(c.decode() for c in code.values())
    assert all(marker in rendered for marker in ("zqsrc", "zqproj", "zqtopic"))  # not vacuous
    assert HOSTILE not in rendered
    assert "zqproj_monitor/launch/system_monitored.launch.xml" in files
    spec = json.loads(files["zqproj_monitor/zqproj_monitor/spec.json"])
    assert spec["actions"]["f"]["value"] == {"data": HOSTILE, "frame": "zqframe"}
    assert json.loads(files["zqproj_monitor/config/invariants.json"])["source"] == HOSTILE
    for name, content in files.items():
        if name.endswith(".xml"):
            etree.fromstring(content)  # the banner's hostile path stays inside its comment
    parsed = configparser.ConfigParser()
    parsed.read_string(files["zqproj_monitor/setup.cfg"].decode())  # the banner is a comment
    assert set(parsed.sections()) == {"develop", "install"}
    assert files["zqproj_monitor/resource/zqproj_monitor"].count(b"\n") == 1


@pytest.mark.parametrize("block", ["/a');import(os)", "/a;__import__('os')", "~private", "/{x}"])
def test_names_that_try_to_inject_are_refused_before_rendering(tmp_path: Path, block: str) -> None:
    document = ros2_document({"/cmd": "std_msgs/msg/UInt8"})
    monitor = f'<monitor inv="demo.inv"><block>/cmd, {_xml(block)}</block></monitor>'
    config = write_case(tmp_path, config_text(monitor=monitor), document)
    result = build_ros2(config)
    assert not result.ok and result.files == {}
    assert "bad-name" in {d.code for d in result.diagnostics}


def test_a_python_launch_file_is_not_rewritten(tmp_path: Path) -> None:
    document = ros2_document({"/cmd": "std_msgs/msg/UInt8"})
    monitor = '<monitor inv="demo.inv" launch="system.launch.py"/>'
    config = write_case(tmp_path, config_text(monitor=monitor), document)
    (tmp_path / "system.launch.py").write_text("import os\n")
    result = build_ros2(config)
    assert result.files == {}
    (diagnostic,) = result.diagnostics
    assert diagnostic.code == "launch-error" and "ROS 2 launch XML" in diagnostic.message


def test_the_backend_is_registered_with_its_own_launch_dialect() -> None:
    from imrosc.backends.launch import ROS2_LAUNCH, ROSLAUNCH
    from imrosc.backends.monitor_backend import MonitorBackend
    from imrosc.backends.registry import available

    backends = available()
    ros1, ros2 = backends["ros1"], backends["ros2"]
    assert isinstance(ros1, MonitorBackend) and isinstance(ros2, MonitorBackend)
    assert ros1.launch_dialect is ROSLAUNCH and ros2.launch_dialect is ROS2_LAUNCH


def test_the_adapter_keeps_python_3_8_syntax() -> None:
    done = subprocess.run(
        [
            sys.executable,
            "-c",
            "import sys, vermin; sys.argv[0] = 'vermin'; sys.exit(vermin.main())",
            "-t=3.8-",
            "--no-tips",
            "--violations",
            "--eval-annotations",
            str(ADAPTER),
        ],
        capture_output=True,
        text=True,
        check=False,
        timeout=120,
    )
    assert done.returncode == 0, done.stdout + done.stderr
