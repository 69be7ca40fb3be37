"""``imrosc build --bags``: architecture records drive relative grouping, bags give types."""

from __future__ import annotations

import json
from pathlib import Path

from click.testing import CliRunner

from imrosc.cli import main
from tests.graph import SECOND, Message, arch, arch_message, write_ros1_bag

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
    assert result.exit_code == 1
    assert f"{broken}:1:1: error:" in result.output
    assert "[bag-error]" in result.output
    assert "[relative-without-graph]" in result.output
