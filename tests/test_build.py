"""``imrosc build``: architecture records in ``--bags`` drive relative grouping and bags give
types; ``--inv`` deploys another invariants file."""

from __future__ import annotations

import json
from pathlib import Path

from click.testing import CliRunner

from imrosc.cli import main
from tests.graph import SECOND, Message, arch, arch_message, write_ros1_bag
from tests.translate import good_run

CONFIG = """<imROS project="recorded">
  <scope>
    <publish id="a" relative="1">/cmd</publish>
  </scope>
</imROS>
"""


def recorded_bag(path: Path) -> Path:
    snapshot = arch({"/cmd": (["/ctrl"], ["/motor"]), "/pose": (["/loc"], ["/ctrl"])})
    messages = [arch_message(0.5, snapshot)]
    for i in range(3):
        time = (i + 1) * SECOND
        messages.append(Message("/pose", time, "xx", "/loc", "std_msgs/msg/Int32"))
        messages.append(Message("/cmd", time + 1000, "xyz", "/ctrl", "std_msgs/msg/Float64"))
    return write_ros1_bag(path, messages)


def test_records_in_bags_group_relative_topics_and_types_fill_the_plan(tmp_path: Path) -> None:
    config = tmp_path / "recorded.xml"
    config.write_text(CONFIG)
    bag = recorded_bag(tmp_path / "run.bag")
    out = tmp_path / "out"
    result = CliRunner().invoke(main, ["build", str(config), "--bags", str(bag), "-o", str(out)])
    assert result.exit_code == 0, result.output
    plan = json.loads((out / "plan.json").read_text())
    assert plan["topics"]["/cmd"] == {"type": "std_msgs/msg/Float64"}
    assert plan["topics"]["/pose"] == {"type": "std_msgs/msg/Int32"}
    (point,) = plan["points"]
    assert point["inputs"] == [{"topic": "/pose", "hops": 1, "explicit": False}]
    assert point["variables"]["/cmd"] == [
        {"path": "data", "type": "float", "array": None, "length": None}
    ]
    assert point["variables"]["/pose"][0]["type"] == "int"
    job = json.loads((out / "job.json").read_text())
    assert job["bags"] == [str(bag)]


def test_a_bad_bag_is_reported_by_name(tmp_path: Path) -> None:
    config = tmp_path / "recorded.xml"
    config.write_text(CONFIG)
    broken = tmp_path / "broken.bag"
    broken.write_bytes(b"#ROSBAG V2.0\n" + b"\0" * 10)
    result = CliRunner().invoke(main, ["build", str(config), "--bags", str(broken)])
    assert result.exit_code == 2  # no bag could be read: an input error (README)
    assert f"{broken}:1:1: error:" in result.output
    assert "[bag-error]" in result.output
    assert "[relative-without-graph]" not in result.output  # the bag was the graph source
    graph = tmp_path / "empty.yaml"
    graph.write_text("version: 1\nnodes: {}\n")
    args = ["build", str(config), "--bags", str(broken), "--graph", str(graph)]
    result = CliRunner().invoke(main, args)
    assert result.exit_code == 1  # the graph file given knows no publisher of /cmd: a finding
    assert "[unknown-topic]" in result.output


MONITORED = """<imROS project="p">
  <scope>
    <publish id="a"><topic>/out</topic><topic>/in</topic></publish>
  </scope>
  <detect inv="p.inv" budget="0"><bag>bags</bag></detect>
  <monitor inv="p.inv"/>
</imROS>
"""


def test_inv_deploys_another_invariants_file_than_the_monitors(tmp_path: Path) -> None:
    (tmp_path / "p.xml").write_text(MONITORED)
    (tmp_path / "bags").mkdir()
    good_run(tmp_path / "bags" / "r1.bag", 0.0)
    good_run(tmp_path / "bags" / "r2.bag", 10.0)
    runner = CliRunner()
    done = runner.invoke(main, ["infer", str(tmp_path / "p.xml"), "-q", "-j", "1"])
    assert done.exit_code == 0, done.output
    learnt = json.loads((tmp_path / "p.inv").read_text())
    kept = {**learnt, "invariants": learnt["invariants"][:1]}
    (tmp_path / "kept.inv").write_text(json.dumps(kept))
    args = ["build", str(tmp_path / "p.xml"), "--backend", "ros1", "-q"]
    for inv, out, expected in ((None, "all", learnt), ("kept.inv", "kept", kept)):
        extra = ["--inv", str(tmp_path / inv)] if inv else []
        done = runner.invoke(main, [*args, *extra, "-o", str(tmp_path / out)])
        assert done.exit_code == 0, done.output
        deployed = tmp_path / out / "p_monitor" / "config" / "invariants.json"
        assert json.loads(deployed.read_text())["invariants"] == expected["invariants"]
    assert f'copied from {tmp_path / "kept.inv"}"' in deployed.read_text()
    plan = runner.invoke(main, ["build", str(tmp_path / "p.xml"), "--inv", "kept.inv"])
    assert plan.exit_code == 2 and "backend plan renders none" in plan.output
    onto = ["--inv", str(tmp_path / "kept.inv"), "-o", str(tmp_path / "kept"), "--force"]
    assert runner.invoke(main, [*args, *onto]).exit_code == 0  # its own outputs, again


def test_build_reads_the_bags_given_with_bags_not_the_detect_bags(tmp_path: Path) -> None:
    """The graph of a relative point comes from --bags (or --graph); <detect> bags are not
    read, and the error and --help say where to give them."""
    config = tmp_path / "recorded.xml"
    detect = '  <detect inv="r.inv"><bag>run.bag</bag></detect>\n</imROS>'
    config.write_text(CONFIG.replace("</imROS>", detect))
    bag = recorded_bag(tmp_path / "run.bag")
    result = CliRunner().invoke(main, ["build", str(config), "-o", str(tmp_path / "a")])
    assert result.exit_code == 1 and "[relative-without-graph]" in result.output
    assert "(build reads those bags with --bags)" in result.output
    args = ["build", str(config), "--bags", str(bag), "-o", str(tmp_path / "b")]
    assert CliRunner().invoke(main, args).exit_code == 0
    usage = CliRunner().invoke(main, ["build", "--help"]).output
    assert "the <detect> bags are not read" in " ".join(usage.split())
