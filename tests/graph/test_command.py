"""``imrosc graph``: output, diagnostics on stderr, and the three exit statuses."""

from __future__ import annotations

from pathlib import Path

import pytest
from click.testing import CliRunner, Result

from imrosc.graph.command import graph_command, is_graph_file
from imrosc.graph.file import parse_graph_text
from tests.graph import SECOND, Message, arch, arch_message, write_ros1_bag, write_ros2_bag

REAL_BAG = Path("/work/shared/data/real/crazyflie/sine_1.bag")

GRAPH_FILE = """\
version: 1
nodes:
  /listener:
    subscribes: [/chatter]
"""


def run(*args: str | Path) -> Result:
    return CliRunner().invoke(graph_command, [str(a) for a in args])


def bag(tmp_path: Path) -> Path:
    messages = [
        Message("/chatter", SECOND, "hi", "/talker"),
        arch_message(2.0, arch({"/cmd": (["/ctrl"], ["/base"])}, {"/reset": ["/base"]})),
    ]
    return write_ros1_bag(tmp_path / "a.bag", messages)


@pytest.mark.skipif(not REAL_BAG.is_file(), reason="the shared real bags are missing")
def test_the_real_crazyflie_bag() -> None:
    result = run(REAL_BAG)
    assert result.exit_code == 0, result.stderr
    assert result.stderr == ""
    lines = result.stdout.splitlines()
    assert lines[0] == "# sources: callerid; subscriptions unknown"
    server = lines.index("/crazyflie_server")
    assert "  publishes /cf1/imu" in lines[server:]
    assert "/tf_broadcaster" in lines
    yaml = run(REAL_BAG, "--format", "yaml")
    graph, problems = parse_graph_text(yaml.stdout, "out.yaml")
    assert problems == []
    assert graph is not None
    assert graph.publishers("/cf1/imu") == ("/crazyflie_server",)
    assert "/tf_broadcaster" in graph.publishers("/array_recording")


def test_bags_and_a_graph_file_are_merged_in_source_order(tmp_path: Path) -> None:
    graph_file = tmp_path / "extra.yml"
    graph_file.write_text(GRAPH_FILE, encoding="utf-8")
    result = run(bag(tmp_path), graph_file)
    assert result.exit_code == 0, result.stderr
    assert result.stdout == (
        "# sources: records, callerid, file\n"
        "/base\n"
        "  subscribes /cmd\n"
        "  serves /reset\n"
        "/ctrl\n"
        "  publishes /cmd\n"
        "/listener\n"
        "  subscribes /chatter\n"
        "/talker\n"
        "  publishes /chatter\n"
    )


def test_yaml_output_is_a_graph_file_and_deterministic(tmp_path: Path) -> None:
    path = bag(tmp_path)
    first = run(path, "--format", "yaml")
    assert first.exit_code == 0
    assert run(path, "--format", "yaml").stdout == first.stdout
    graph, problems = parse_graph_text(first.stdout, "out.yaml")
    assert problems == []
    assert graph is not None
    assert graph.servers("/reset") == ("/base",)


def test_errors_exit_1_and_the_good_inputs_are_still_printed(tmp_path: Path) -> None:
    good = bag(tmp_path)
    bad_file = tmp_path / "bad.yaml"
    bad_file.write_text("version: 1\nnodes:\n  /x: {publishes: [/a//b]}\n", encoding="utf-8")
    missing = tmp_path / "missing.bag"
    result = run(good, bad_file, missing)
    assert result.exit_code == 1
    assert "/talker\n  publishes /chatter\n" in result.stdout
    assert result.stderr.splitlines() == [
        f"{bad_file}:3:23: error: topic name '/a//b' has an empty token [bad-name]",
        f"{missing}:1:1: error: no such file or directory [bag-error]",
    ]


def test_warnings_alone_exit_0(tmp_path: Path) -> None:
    path = tmp_path / "rel.yaml"
    path.write_text("version: 1\nnodes:\n  talker: {}\n", encoding="utf-8")
    result = run(path)
    assert result.exit_code == 0
    assert "[relative-name]" in result.stderr
    assert "/talker" in result.stdout


def test_nothing_readable_exits_2_and_prints_nothing(tmp_path: Path) -> None:
    truncated = bag(tmp_path)
    truncated.write_bytes(truncated.read_bytes()[:100])
    syntax = tmp_path / "g.yaml"
    syntax.write_text("version: [\n", encoding="utf-8")
    result = run(truncated, syntax, tmp_path / "nope")
    assert result.exit_code == 2
    assert result.stdout == ""
    codes = [line.rsplit(" ", 1)[-1] for line in result.stderr.splitlines()]
    assert codes == ["[bag-error]", "[graph-syntax]", "[bag-error]"]
    assert "Traceback" not in result.output


def test_a_ros2_bag_and_its_metadata_file(tmp_path: Path) -> None:
    r2 = write_ros2_bag(tmp_path / "r2", [arch_message(1.0, arch({"/t": (["/p"], ["/s"])}))])
    for argument in (r2, r2 / "metadata.yaml"):
        result = run(argument)
        assert result.exit_code == 0, result.stderr
        assert result.stdout.startswith("# sources: records\n")
        assert "/s\n  subscribes /t\n" in result.stdout


def test_which_arguments_are_graph_files() -> None:
    assert is_graph_file(Path("g.yaml"))
    assert is_graph_file(Path("dir/g.yml"))
    assert not is_graph_file(Path("bag/metadata.yaml"))
    assert not is_graph_file(Path("run.bag"))
    assert not is_graph_file(Path("bags"))


def test_usage_errors_exit_2() -> None:
    result = run()
    assert result.exit_code == 2
    assert "BAG_OR_FILE" in result.output
    assert run("x.bag", "--format", "json").exit_code == 2
