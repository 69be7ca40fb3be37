"""``imrosc record`` on the command line, where things go wrong before anything is recorded.

Each error is one line on stderr, exit status 1 (2 for a bad option), and no traceback. A fake
master (an XML-RPC server in a thread) stands in for roscore where the command must get past
the master to fail further on; recording itself is tested live (tests/live/test_record.py).
"""

from __future__ import annotations

import socket
import sys
import threading
from collections.abc import Iterator
from pathlib import Path
from typing import Any
from xmlrpc.server import SimpleXMLRPCServer

import pytest
from click.testing import CliRunner, Result

from imrosc.cli import main
from imrosc.record.session import child_environment
from tests.record.support import CONFIG, one_line_error

LAUNCH = """<launch>
  <node pkg="robot" type="server" name="server" ns="a"/>
  <node pkg="robot" type="client" name="client" ns="a"/>
</launch>
"""


def free_port() -> int:
    with socket.socket() as probe:
        probe.bind(("127.0.0.1", 0))
        port: int = probe.getsockname()[1]
        return port


NO_MASTER = f"http://127.0.0.1:{free_port()}"


class FakeMaster:
    """The few master calls ``imrosc record`` makes before it starts anything."""

    def __init__(self) -> None:
        self.server = SimpleXMLRPCServer(("127.0.0.1", 0), logRequests=False, allow_none=True)
        self.server.register_function(self.get_system_state, "getSystemState")
        self.uri = f"http://127.0.0.1:{self.server.server_address[1]}"
        self.thread = threading.Thread(target=self.server.serve_forever, daemon=True)

    @staticmethod
    def get_system_state(caller: Any) -> Any:
        state = [
            [["/cmd", ["/a/ctrl"]], ["/pose", ["/a/loc"]]],
            [["/pose", ["/a/ctrl"]]],
            [["/task", ["/a/server"]]],
        ]
        return [1, "system state", state]


@pytest.fixture
def master() -> Iterator[FakeMaster]:
    fake = FakeMaster()
    fake.thread.start()
    try:
        yield fake
    finally:
        fake.server.shutdown()
        fake.server.server_close()


@pytest.fixture
def config(tmp_path: Path) -> Path:
    path = tmp_path / "robot.xml"
    path.write_text(CONFIG, encoding="utf-8")
    return path


def record(*args: str, uri: str = NO_MASTER) -> Result:
    env = {"ROS_MASTER_URI": uri, "ROS_VERSION": None}  # ROS 1, whatever the shell sourced
    return CliRunner().invoke(main, ["record", *args], env=env)


def test_no_master_says_so(config: Path, tmp_path: Path) -> None:
    line = one_line_error(record(str(config), "-o", str(tmp_path / "out")))
    assert line.startswith(f"imrosc record: no ROS master at {NO_MASTER} (")
    assert line.endswith("start roscore, or set ROS_MASTER_URI")
    assert not (tmp_path / "out").exists()


def test_a_master_uri_that_is_not_http_is_refused(config: Path, tmp_path: Path) -> None:
    line = one_line_error(record(str(config), "-o", str(tmp_path / "out"), uri="localhost:11311"))
    assert "is not an http:// URI" in line


def test_configuration_errors_are_diagnostics(tmp_path: Path) -> None:
    bad = tmp_path / "bad.xml"
    bad.write_text('<imROS project="p"><scope><call id="Q">/x</call></scope></imROS>')
    result = record(str(bad), "-o", str(tmp_path / "out"))
    assert result.exit_code == 1
    assert f"{bad}:1:" in result.stderr
    assert "Traceback" not in result.output
    missing = record(str(tmp_path / "missing.xml"), "-o", str(tmp_path / "out"))
    assert missing.exit_code == 2  # an input that cannot be read, as in every command
    assert "io-error" in missing.stderr


def test_a_scope_with_nothing_to_record_is_refused(tmp_path: Path) -> None:
    only = tmp_path / "only.xml"
    only.write_text(
        '<imROS project="p"><scope><condition id="1"><topic>/x</topic>'
        "<value>x == 1</value></condition></scope></imROS>"
    )
    result = record(str(only), "-o", str(tmp_path / "out"))
    assert result.exit_code == 1
    assert "the scope has nothing to record" in result.stderr.splitlines()[-1]


def test_a_folder_with_a_bag_is_refused_unless_forced(config: Path, tmp_path: Path) -> None:
    out = tmp_path / "out"
    out.mkdir()
    (out / "earlier.bag").write_bytes(b"")
    line = one_line_error(record(str(config), "-o", str(out)), 2)  # an output refused
    assert line == (
        f"imrosc record: {out} holds a bag already (earlier.bag): record into a new folder, "
        f"or use --force"
    )
    forced = one_line_error(record(str(config), "-o", str(out), "--force"))
    assert "no ROS master" in forced  # got past the check
    assert (out / "earlier.bag").exists()


def test_an_output_that_is_a_file_is_refused(config: Path, tmp_path: Path) -> None:
    out = tmp_path / "file"
    out.write_text("x")
    assert record(str(config), "-o", str(out)).exit_code != 0


def test_bad_options_are_usage_errors(config: Path, tmp_path: Path) -> None:
    out = str(tmp_path / "out")
    for args in (
        ("--server", "no-equals-sign"),
        ("--server", "=/node"),
        ("--name", "a/b"),
        ("--name", ".hidden"),
        ("--duration", "0"),
        ("--period", "-1"),
    ):
        result = record(str(config), "-o", out, *args)
        assert result.exit_code == 2, (args, result.output)
        assert "Traceback" not in result.output
    assert record(str(config)).exit_code == 2  # -o is required


def test_launch_needs_to_know_the_servers(config: Path, tmp_path: Path) -> None:
    launch = tmp_path / "robot.launch"
    launch.write_text(LAUNCH)
    line = one_line_error(record(str(config), "-o", str(tmp_path / "out"), "--launch", str(launch)))
    assert "no graph says which node serves /task" in line
    assert "--server SERVICE=NODE" in line
    assert not (tmp_path / "robot.record.launch").exists()


def test_a_launch_file_that_cannot_be_read_is_named_first(config: Path, tmp_path: Path) -> None:
    """A missing --launch file is the error, not the servers no graph names (it would name
    them too late: the user would fix those first and meet the missing file next)."""
    missing = tmp_path / "gone.launch"
    result = record(str(config), "-o", str(tmp_path / "out"), "--launch", str(missing))
    line = one_line_error(result, 2)
    assert line == f"imrosc record: --launch {missing}: cannot read it: No such file or directory"
    assert not (tmp_path / "out").exists()


def test_launch_writes_a_remapped_copy_beside_the_original(config: Path, tmp_path: Path) -> None:
    launch = tmp_path / "robot.launch"
    launch.write_text(LAUNCH)
    args = (str(config), "-o", str(tmp_path / "out"), "--launch", str(launch))
    result = record(*args, "--server", "/task=/a/server")
    copy = tmp_path / "robot.record.launch"
    assert f"wrote {copy}: remapped /task on /a/server" in result.stdout
    assert f"roslaunch {copy}" in result.stdout
    assert "no ROS master" in result.stderr  # written first: it is needed to start the system
    assert launch.read_text() == LAUNCH
    text = copy.read_text()
    assert '<remap from="/task" to="/rec/task"/>' in text
    assert text.count("<remap") == 1
    assert "generated by imrosc" in text
    # a copy imrosc wrote is replaced; a file it did not write is not, unless forced
    assert "wrote" in record(*args, "--server", "/task=/a/server").stdout
    copy.write_text("<launch/>")
    refused = record(*args, "--server", "/task=/a/server")
    assert "was not generated by imrosc; use --force" in refused.stderr
    assert copy.read_text() == "<launch/>"
    elsewhere = tmp_path / "sub" / "rec.launch"
    moved = record(*args, "--server", "/task=/a/server", "--launch-out", str(elsewhere))
    assert f"wrote {elsewhere}" in moved.stdout


def test_launch_servers_can_come_from_the_master(
    config: Path, tmp_path: Path, master: FakeMaster
) -> None:
    launch = tmp_path / "robot.launch"
    launch.write_text(LAUNCH)
    args = (str(config), "-o", str(tmp_path / "out"), "--launch", str(launch))
    result = record(*args, "--python", str(tmp_path / "no-python"), uri=master.uri)
    assert "remapped /task on /a/server" in result.stdout
    assert result.exit_code == 1
    assert "cannot run the ROS Python" in result.stderr


def test_a_python_without_rospy_is_reported(
    config: Path, tmp_path: Path, master: FakeMaster
) -> None:
    result = record(
        str(config), "-o", str(tmp_path / "out"), "--python", sys.executable, uri=master.uri
    )
    line = one_line_error(result)
    assert line.startswith(f"imrosc record: the ROS Python {sys.executable} cannot import rospy:")
    assert not (tmp_path / "out" / "small_robot.bag").exists()


def test_relative_inputs_the_master_cannot_give_are_warned_about(
    tmp_path: Path, master: FakeMaster
) -> None:
    config = tmp_path / "other.xml"
    config.write_text(
        '<imROS project="p"><scope><publish id="a" relative="1">/odom</publish></scope></imROS>'
    )
    result = record(
        str(config), "-o", str(tmp_path / "out"), "--python", "/nonexistent", uri=master.uri
    )
    assert "warning" in result.stderr and "relative=1 on /odom" in result.stderr
    quiet = record(
        str(config),
        "-o",
        str(tmp_path / "out"),
        "--all",
        "--python",
        "/nonexistent",
        uri=master.uri,
    )
    assert "relative=1" not in quiet.stderr


def test_children_get_the_master_and_no_namespace() -> None:
    env = child_environment(
        {"ROS_NAMESPACE": "/robot", "PYTHONHOME": "/x", "HOME": "/h"}, NO_MASTER
    )
    assert env == {"HOME": "/h", "ROS_MASTER_URI": NO_MASTER, "PYTHONUNBUFFERED": "1"}
