"""Backend ``ros1``: the catkin package it renders, its flatteners, its adapter's decisions,
and the guarantee that nothing from a configuration or an invariants file becomes code."""

from __future__ import annotations

import json
import math
import os
import py_compile
import stat
import subprocess
import sys
from collections.abc import Mapping
from pathlib import Path
from types import SimpleNamespace
from typing import Any

import numpy as np
import pytest
from click.testing import CliRunner
from lxml import etree
from rosbags.interfaces import Nodetype

from imrosc.backends.registry import GENERATED_MARK, Executable
from imrosc.cli import main
from imrosc.onboard import monitor
from imrosc.replay import Replayer
from imrosc.runtime.flatten import make_flattener
from imrosc.sim import Scenario, write_runs
from tests.backends.monitor_support import (
    ROOT,
    STORE,
    add_battery_cells,
    build_ros1,
    config_text,
    import_adapter,
    invariants_document,
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
from tests.backends.support import (
    HOSTILE,
    assert_carried_unchanged,
    assert_every_file_names_its_source,
    vendored_sources,
)

PACKAGE = "landing_sim_monitor"
RUNTIME = ROOT / "imrosc" / "runtime"
ADAPTER = ROOT / "imrosc" / "onboard" / "monitor_ros1"
CARRIED = ("runtime", "onboard", "onboard/monitor_ros1")
"""The imrosc packages a ROS 1 monitor package carries (under ``scripts/imrosc_monitor/imrosc``)."""
ROS_PYTHON = Path("/usr/bin/python3")


def landing_files(folder: Path) -> dict[str, bytes]:
    result = build_ros1(folder / "landing_sim.xml", [folder / "landing_sim.graph.yaml"])
    assert result.ok, [d.as_text() for d in result.diagnostics]
    return result.files


@pytest.fixture(scope="module")
def landing_package(landing_sim: Path) -> dict[str, bytes]:
    return landing_files(landing_sim)


def python_files(files: Mapping[str, bytes]) -> dict[str, bytes]:
    return {
        name: content
        for name, content in files.items()
        if name.endswith(".py") or isinstance(content, Executable)
    }


# -- the package ----------------------------------------------------------------------------


def test_the_package_has_every_file(landing_package: dict[str, bytes]) -> None:
    expected = {
        "package.xml",
        "CMakeLists.txt",
        "config/invariants.json",
        f"launch/{PACKAGE}.launch",
        f"scripts/{PACKAGE}",
        f"scripts/{PACKAGE}_watchdog",
        "scripts/imrosc_monitor/__init__.py",
        "scripts/imrosc_monitor/flatteners.py",
        "scripts/imrosc_monitor/spec.json",
        *vendored_sources("scripts/imrosc_monitor", CARRIED),
    }
    assert set(landing_package) == {f"{PACKAGE}/{name}" for name in expected}
    for name in (f"scripts/{PACKAGE}", f"scripts/{PACKAGE}_watchdog"):
        script = landing_package[f"{PACKAGE}/{name}"]
        assert isinstance(script, Executable)
        assert script.startswith(b"#!/usr/bin/env python3\n")


def test_the_runtime_the_onboard_logic_and_the_adapter_are_carried_unchanged(
    landing_package: dict[str, bytes],
) -> None:
    sources = vendored_sources(f"{PACKAGE}/scripts/imrosc_monitor", CARRIED)
    assert_carried_unchanged(landing_package, sources)


def test_every_file_names_generator_version_and_its_source(
    landing_package: dict[str, bytes],
    landing_sim: Path,
) -> None:
    assert_every_file_names_its_source(landing_package, landing_sim / "landing_sim.xml", "ros1")


def test_package_xml_is_format_2_with_its_dependencies(landing_package: dict[str, bytes]) -> None:
    root = etree.fromstring(landing_package[f"{PACKAGE}/package.xml"])
    assert root.tag == "package" and root.get("format") == "2"
    assert root.findtext("name") == PACKAGE
    depends = {e.text for e in root.iter("exec_depend")}
    assert {"rospy", "std_msgs", "geometry_msgs", "sensor_msgs", "python3-numpy"} <= depends
    assert "python3-numba" in depends  # the compiled checks, where rosdep installs them
    assert root.findtext("buildtool_depend") == "catkin"
    cmake = landing_package[f"{PACKAGE}/CMakeLists.txt"].decode()
    assert f"project({PACKAGE})" in cmake
    assert (
        f"catkin_install_python(\n  PROGRAMS scripts/{PACKAGE} scripts/{PACKAGE}_watchdog" in cmake
    )


def test_the_monitor_launch_file_starts_the_node_with_its_parameters(
    landing_package: dict[str, bytes],
) -> None:
    root = etree.fromstring(landing_package[f"{PACKAGE}/launch/{PACKAGE}.launch"])
    node, watchdog = root.iter("node")
    assert (node.get("pkg"), node.get("type"), node.get("name")) == (PACKAGE, PACKAGE, PACKAGE)
    params = {p.get("name"): p.get("value") for p in node.iter("param")}
    assert params["invariants"] == "$(arg invariants)"
    assert params["namespace"] == "/m"
    args = {a.get("name"): a.get("default") for a in root.iter("arg")}
    assert args["invariants"] == f"$(find {PACKAGE})/config/invariants.json"
    assert args["period"] == "0.5" and args["fail_open"] == "false"
    assert params["warm"] == "$(arg warm)" and args["warm"] == repr(monitor.WARM)
    assert watchdog.get("if") == "$(arg fail_open)"


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
            sys.executable,
            "-m",
            "ruff",
            "check",
            "--no-cache",
            "--config",
            str(RUNTIME / "ruff.toml"),  # the project's rules, target Python 3.8
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


def test_two_builds_give_identical_bytes(landing_sim: Path) -> None:
    assert landing_files(landing_sim) == landing_files(landing_sim)


def test_the_invariants_copy_is_the_same_document(
    landing_package: dict[str, bytes],
    landing_sim: Path,
) -> None:
    original = json.loads((landing_sim / "landing_sim.inv").read_text())
    copy = json.loads(landing_package[f"{PACKAGE}/config/invariants.json"])
    assert GENERATED_MARK in copy.pop("$comment")
    original.pop("$comment")
    assert copy == original


def test_build_writes_an_executable_package_and_keeps_foreign_files(
    landing_sim: Path,
    tmp_path: Path,
) -> None:
    out = tmp_path / "out"
    args = [
        "build",
        str(landing_sim / "landing_sim.xml"),
        "--backend",
        "ros1",
        "-o",
        str(out),
        "--graph",
        str(landing_sim / "landing_sim.graph.yaml"),
    ]
    runner = CliRunner()
    first = runner.invoke(main, args)
    assert first.exit_code == 0, first.output
    script = out / PACKAGE / "scripts" / PACKAGE
    assert script.stat().st_mode & stat.S_IXUSR
    assert os.access(out / PACKAGE / "scripts" / f"{PACKAGE}_watchdog", os.X_OK)
    assert not os.access(out / PACKAGE / "package.xml", os.X_OK)
    again = runner.invoke(main, args)  # its own files: overwritten quietly
    assert again.exit_code == 0, again.output
    foreign = out / PACKAGE / "CMakeLists.txt"
    foreign.write_text("# my own build\n")
    refused = runner.invoke(main, args)
    assert refused.exit_code == 2
    assert "not generated by imrosc; use --force" in refused.output
    assert "Traceback" not in refused.output
    assert foreign.read_text() == "# my own build\n"
    forced = runner.invoke(main, [*args, "--force"])
    assert forced.exit_code == 0
    assert GENERATED_MARK in foreign.read_text()


def test_bad_input_exits_non_zero_with_a_diagnostic_and_no_traceback(tmp_path: Path) -> None:
    config = write_case(tmp_path, config_text(monitor=""), None)
    result = CliRunner().invoke(main, ["build", str(config), "--backend", "ros1"])
    assert result.exit_code == 1
    assert f"{config}:1:1: error:" in result.output and "[monitor-missing]" in result.output
    assert "Traceback" not in result.output


# -- the flatteners -------------------------------------------------------------------------

_DTYPES = {"byte": "uint8", "char": "uint8"}


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
    """A message of a rosbags type with random values (NaN, inf, empty arrays included)."""
    fields: Any = STORE.fielddefs[msgtype][1]
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
                dtype = _DTYPES.get(element_detail[0], element_detail[0])
                items = [_scalar(element_detail[0], rng) for _ in range(count)]
                values[name] = np.array(items, dtype=dtype)
            else:
                values[name] = [make_message(element_detail, rng) for _ in range(count)]
    return STORE.types[msgtype](**values)


FLAT_TYPES = {
    "/pose": "geometry_msgs/msg/PoseStamped",
    "/imu": "sensor_msgs/msg/Imu",
    "/scan": "sensor_msgs/msg/LaserScan",
    "/text": "std_msgs/msg/String",
    "/level": "std_msgs/msg/UInt8",
    "/battery": "sensor_msgs/msg/BatteryState",
}


def flattener_document() -> dict[str, Any]:
    document = invariants_document(FLAT_TYPES)
    battery = document["topics"]["/battery"]["variables"]
    add_battery_cells(battery)
    return document


@pytest.fixture(scope="module")
def flat_package(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, dict[str, Any]]:
    folder = tmp_path_factory.mktemp("flat")
    document = flattener_document()
    scope = "\n    ".join(
        f'<publish id="{ident}">{topic}</publish>'
        for ident, topic in zip("abcdef", sorted(FLAT_TYPES), strict=True)
    )
    config = write_case(folder, config_text(scope=scope), document)
    result = build_ros1(config)
    assert result.ok, [d.as_text() for d in result.diagnostics]
    return write_package(result.files, folder / "out"), document


def test_generated_flatteners_equal_make_flattener(
    flat_package: tuple[Path, dict[str, Any]],
) -> None:
    package, document = flat_package
    flatteners = import_adapter(package).FLATTENERS
    assert set(flatteners) == set(FLAT_TYPES)
    rng = np.random.default_rng(3)
    with np.errstate(all="ignore"):
        for topic, msgtype in FLAT_TYPES.items():
            reference = make_flattener(document["topics"][topic]["variables"])
            for _ in range(25):
                message = make_message(msgtype, rng)
                assert_same_values(flatteners[topic](message), reference(message))


def test_generated_flatteners_read_broken_messages_like_make_flattener(
    flat_package: tuple[Path, dict[str, Any]],
) -> None:
    package, document = flat_package
    flatteners = import_adapter(package).FLATTENERS
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


def test_replaying_with_generated_flatteners_finds_the_same_violations(
    landing_package: dict[str, bytes],
    landing_sim: Path,
    tmp_path: Path,
) -> None:
    package = write_package(landing_package, tmp_path)
    flatteners = import_adapter(package).FLATTENERS
    (bag,) = write_runs(
        tmp_path / "fail", runs=1, seed=7, fmt="ros1", duration=8.0, scenario=Scenario("slowed")
    )
    document = json.loads((landing_sim / "landing_sim.inv").read_text())
    reference = Replayer(document).run(bag)
    generated = Replayer(document)
    assert set(generated.flatteners) == set(flatteners)
    generated.flatteners = dict(flatteners)
    mine = generated.run(bag)
    assert reference.violations, "the faulty run should break invariants"
    assert [v.as_json() for v in mine.violations] == [v.as_json() for v in reference.violations]


_FILL = r"""
def fill(message):
    for name, kind in zip(message.__slots__, message._slot_types):
        current = getattr(message, name)
        if hasattr(current, "__slots__"):
            fill(current)
        elif kind in ("uint8[]", "char[]"):
            setattr(message, name, bytes(random.randrange(256) for _ in range(3)))
        elif kind.startswith("float") and kind.endswith("[]"):
            setattr(message, name, [random.gauss(0, 1) for _ in range(random.randrange(5))])
        elif kind.startswith("float") and "[" in kind:
            setattr(message, name, tuple(random.gauss(0, 1) for _ in current))
        elif kind.startswith("float"):
            setattr(message, name, random.choice([random.gauss(0, 1), float("nan")]))
        elif kind == "string":
            setattr(message, name, random.choice(["map", "odom"]))
        elif kind == "bool":
            setattr(message, name, random.random() < 0.5)
        elif "int" in kind and "[" not in kind:
            setattr(message, name, random.randrange(100))
    return message
"""
"""Fills a rospy message with random values (both rospy checks use it)."""

_ROSPY_CHECK = (
    r"""
import json, math, random, sys
sys.path.insert(0, sys.argv[1])
import roslib.message
from imrosc_monitor import flatteners
from imrosc_monitor.imrosc.runtime.flatten import make_flattener

random.seed(5)

"""
    + _FILL
    + r"""
document = json.load(open(sys.argv[2]))
for topic, info in document["topics"].items():
    kind = info["type"].replace("/msg/", "/")
    message_class = roslib.message.get_message_class(kind)
    reference = make_flattener(info["variables"])
    for _ in range(20):
        message = fill(message_class())
        got, expected = flatteners.FLATTENERS[topic](message), reference(message)
        same = all(
            (isinstance(a, float) and math.isnan(a) and math.isnan(b)) or a == b
            for a, b in zip(got, expected)
        )
        assert same and len(got) == len(expected), (topic, got, expected)
print("ok")
"""
)


def _run_ros_python(script: str, package: Path) -> subprocess.CompletedProcess[str]:
    """``script`` under Debian's python, given the package's scripts folder and its
    invariants file."""
    return subprocess.run(
        [
            str(ROS_PYTHON),
            "-c",
            script,
            str(package / "scripts"),
            str(package / "config" / "invariants.json"),
        ],
        capture_output=True,
        text=True,
        check=False,
        timeout=120,
    )


def _has_rospy() -> bool:
    if not ROS_PYTHON.exists():
        return False
    done = subprocess.run(
        [str(ROS_PYTHON), "-c", "import rospy, numpy, roslib, sensor_msgs.msg"],
        capture_output=True,
        check=False,
    )
    return done.returncode == 0


@pytest.mark.skipif(not _has_rospy(), reason="needs Debian's python3 with rospy and numpy")
def test_generated_flatteners_equal_make_flattener_on_rospy_messages(
    flat_package: tuple[Path, dict[str, Any]],
) -> None:
    package, _ = flat_package
    done = _run_ros_python(_ROSPY_CHECK, package)
    assert done.returncode == 0 and done.stdout.strip() == "ok", done.stdout + done.stderr


_WIRE_CHECK = (
    r"""
import io, json, math, random, struct, sys
sys.path.insert(0, sys.argv[1])
import roslib.message
from imrosc_monitor import flatteners
from imrosc_monitor.imrosc.onboard.monitor_ros1 import wire
"""
    + _FILL
    + r"""

def same(got, expected):
    return len(got) == len(expected) and all(
        (isinstance(a, float) and math.isnan(a) and math.isnan(b)) or a == b
        for a, b in zip(got, expected)
    )

random.seed(11)
document = json.load(open(sys.argv[2]))
readers = 0
for topic, info in document["topics"].items():
    message_class = roslib.message.get_message_class(info["type"].replace("/msg/", "/"))
    read = wire.reader(message_class, info["variables"], roslib.message.get_message_class)
    if read is None:
        print("no reader", topic)
        continue
    readers += 1
    raw_class = wire.raw_class(message_class)
    assert (raw_class._type, raw_class._md5sum) == (message_class._type, message_class._md5sum)
    for _ in range(30):
        message = fill(message_class())
        buff = io.BytesIO()
        message.serialize(buff)
        data = buff.getvalue()
        decoded = message_class().deserialize(data)
        expected = flatteners.FLATTENERS[topic](decoded)
        got = read(data)
        assert same(got, expected), (topic, got, expected)
        relayed = raw_class().deserialize(data)  # as rospy hands it over, then publishes it
        out = io.BytesIO()
        relayed.serialize(out)
        assert out.getvalue() == data
        try:  # bytes the plan cannot read raise: the node then decodes them as rospy would
            read(data[:0])
        except (struct.error, IndexError, ValueError):
            continue
        raise AssertionError(f"{topic}: empty bytes read without an error")
twist = roslib.message.get_message_class("geometry_msgs/Twist")
names = [f"{part}.{axis}" for part in ("linear", "angular") for axis in "xyz"]
layouts = {
    "all, in order": [{"path": n, "type": "float", "derived": None} for n in names],
    "some, reordered": [{"path": n, "type": "float", "derived": None} for n in names[::-2]],
}
for label, layout in layouts.items():
    read = wire.reader(twist, layout, roslib.message.get_message_class)
    for _ in range(10):
        message = fill(twist())
        buff = io.BytesIO()
        message.serialize(buff)
        expected = [float(getattr(getattr(message, v["path"].split(".")[0]), v["path"][-1]))
                    for v in layout]
        got = read(buff.getvalue())
        assert same(got, expected), label
        # six float64 in a row: the values are a read-only array over the bytes themselves
        assert (type(got).__name__ == "ndarray") == (label == "all, in order"), label
header = roslib.message.get_message_class("std_msgs/Header")
time_value = [{"path": "stamp", "type": "time", "derived": None}]
assert wire.reader(header, time_value, roslib.message.get_message_class) is None
assert wire.reader(twist, [{"path": "linear.w", "type": "float", "derived": None}],
                   roslib.message.get_message_class) is None
print("ok", readers)
"""
)


@pytest.mark.skipif(not _has_rospy(), reason="needs Debian's python3 with rospy and numpy")
def test_blocked_topics_read_from_the_bytes_give_the_flatteners_values(
    flat_package: tuple[Path, dict[str, Any]],
) -> None:
    """wire.py's plan, on the bytes genpy writes, gives what the generated flattener gives
    on the decoded message, for every layout of the flattener test (headers, strings,
    fixed and variable arrays, elements, statistics); the relay writes the bytes back."""
    package, _ = flat_package
    done = _run_ros_python(_WIRE_CHECK, package)
    assert done.returncode == 0, done.stdout + done.stderr
    assert done.stdout.strip().splitlines()[-1] == f"ok {len(FLAT_TYPES)}", done.stdout


# -- nothing from the inputs becomes code ---------------------------------------------------


def test_no_string_from_the_inputs_reaches_generated_code_unquoted(tmp_path: Path) -> None:
    config = hostile_case(tmp_path)
    result = build_ros1(config, [tmp_path / "graph.yaml"])
    assert result.ok, [d.as_text() for d in result.diagnostics]
    files = result.files
    code = python_files(files)
    for name, content in code.items():
        text = content.decode("utf-8")
        compile(text, name, "exec")
        assert_markers_only_quoted(name, text)
    rendered = "".join(c.decode() for c in code.values())
    assert all(marker in rendered for marker in ("zqsrc", "zqproj", "zqtopic"))  # not vacuous
    assert "zqproj_monitor/launch/system_monitored.launch" in files
    spec = json.loads(files["zqproj_monitor/scripts/imrosc_monitor/spec.json"])
    assert spec["actions"]["f"]["value"] == {"data": HOSTILE, "frame": "zqframe"}
    assert json.loads(files["zqproj_monitor/config/invariants.json"])["source"] == HOSTILE
    for name, content in files.items():
        if name.endswith((".xml", ".launch")):
            etree.fromstring(content)  # the banner's hostile path stays inside its comment
    assert HOSTILE not in "".join(c.decode() for c in python_files(files).values())


@pytest.mark.parametrize("block", ["/a');import(os)", "/a;__import__('os')", "~private", "/{x}"])
def test_names_that_try_to_inject_are_refused_before_rendering(tmp_path: Path, block: str) -> None:
    document = invariants_document({"/cmd": "std_msgs/msg/UInt8"})
    monitor = f'<monitor inv="demo.inv"><block>/cmd, {_xml(block)}</block></monitor>'
    config = write_case(tmp_path, config_text(monitor=monitor), document)
    result = build_ros1(config)
    assert not result.ok and result.files == {}
    assert "bad-name" in {d.code for d in result.diagnostics}


def test_topic_names_in_the_invariants_file_that_try_to_inject_are_refused(
    tmp_path: Path,
) -> None:
    document = invariants_document({"/cmd": "std_msgs/msg/UInt8"})
    document["topics"]["/x': 1}; import os #"] = document["topics"]["/cmd"]
    config = write_case(tmp_path, config_text(), document)
    result = build_ros1(config)
    assert result.files == {}
    assert [d.code for d in result.diagnostics] == ["bad-name"]


# -- the adapter -------------------------------------------------------------------------


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
