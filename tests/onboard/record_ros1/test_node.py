"""The recording node writes exactly the records ``imrosc.records`` reads.

The node (``imrosc/onboard/record_ros1/node.py``) writes with the one record encoder
(``imrosc/onboard/records.py``, tested in ``tests/onboard/test_records.py``); it imports
rospy only when it runs, so these tests import it where imrosc is and hold what it makes of
messages, the graph and the parameters to ``imrosc.records``.
"""

from __future__ import annotations

import json
import math
import subprocess
import sys
import xmlrpc.client

import pytest

from imrosc import records
from imrosc.onboard import records as onboard_records
from imrosc.onboard.record_ros1 import node
from imrosc.record.session import PACKAGE, RECORDER


def test_the_node_writes_with_the_one_record_encoder() -> None:
    assert node.records is onboard_records  # type: ignore[attr-defined]


class Time:
    """What rospy.Time and rospy.Duration look like to the encoder."""

    def __init__(self, seconds: float) -> None:
        self.seconds = seconds

    def to_sec(self) -> float:
        return self.seconds


class Point:
    __slots__ = ("x", "y")
    _slot_types = ("float64", "float64")

    def __init__(self, x: float, y: float) -> None:
        self.x, self.y = x, y


class Request:
    """A generated request class: fields in ``__slots__``, types in ``_slot_types``."""

    __slots__ = ("data", "name", "points", "stamp", "wait")
    _slot_types = ("uint8[]", "string", "geometry_msgs/Point[]", "time", "duration")

    def __init__(self) -> None:
        self.data = b"\x01\x02\xff"
        self.name = "task"
        self.points = [Point(1.0, 2.0), Point(float("nan"), -math.inf)]
        self.stamp = Time(12.5)
        self.wait = Time(-0.25)


def test_messages_become_json_objects_of_their_fields() -> None:
    request = node.plain(Request())
    assert request["data"] == [1, 2, 255]
    assert request["name"] == "task"
    assert request["stamp"] == 12.5
    assert request["wait"] == -0.25
    assert request["points"][0] == {"x": 1.0, "y": 2.0}
    text = onboard_records.call_text("/s", "/c", "/n", request, {"ok": True}, 1.0, 0.1)
    call = records.decode_call(text)
    assert call.request["points"][1]["y"] == -math.inf  # type: ignore[index]
    assert math.isnan(call.request["points"][1]["x"])  # type: ignore[index]
    assert text == records.encode(call)


STATE = [
    [
        ["/a/pose", ["/a/car", "/imrosc_recorder_1"]],
        ["/imrosc/arch", ["/imrosc_recorder_1"]],
        ["/rosout", ["/a/car", "/a/ctrl", "/imrosc_recorder_1"]],
        ["/gone", ["/imrosc_recorder_1"]],
    ],
    [
        ["/a/pose", ["/a/ctrl", "/imrosc_rosbag_1"]],
        ["/imrosc/srvs", ["/imrosc_rosbag_1"]],
        ["/rosout", ["/rosout"]],
    ],
    [
        ["/a/task", ["/imrosc_recorder_1"]],
        ["/rec/a/task", ["/a/car"]],
        ["/a/ctrl/get_loggers", ["/a/ctrl"]],
        ["/imrosc_recorder_1/get_loggers", ["/imrosc_recorder_1"]],
        ["/a/dead_srv", ["/a/dead"]],
    ],
]


def test_snapshots_leave_out_the_recording_and_show_relayed_services_as_the_robot_has_them() -> (
    None
):
    hidden = {"/imrosc_recorder_1", "/imrosc_rosbag_1", "/a/dead"}
    topics, services = node.snapshot(STATE, hidden, {"/rec/a/task": "/a/task"})
    text = onboard_records.arch_text(topics, services)
    snapshot = records.decode_arch(text)
    assert set(snapshot.topics) == {"/a/pose", "/rosout"}
    assert snapshot.topics["/a/pose"] == records.TopicEnds(
        frozenset({"/a/car"}), frozenset({"/a/ctrl"})
    )
    assert snapshot.services == {
        "/a/task": frozenset({"/a/car"}),
        "/a/ctrl/get_loggers": frozenset({"/a/ctrl"}),
    }
    assert "imrosc" not in text
    assert "/rec/" not in text


def test_an_unrelayed_service_keeps_its_server() -> None:
    state = [[], [], [["/a/task", ["/a/car"]]]]
    _, services = node.snapshot(state, set(), {"/rec/a/task": "/a/task"})
    assert services == {"/a/task": ["/a/car"]}


def test_parameters_are_those_of_the_scope_as_set() -> None:
    tree = {
        "a": {"car": {"rate": 10, "name": "car", "gains": [1, 2]}},
        "gps": {"origin": {"lat": 40.8, "lon": -96.7}},
        "blob": xmlrpc.client.Binary(b"\x00\x01"),
        "when": xmlrpc.client.DateTime("20240101T10:00:00"),
        "bad-name": 1,
    }
    found = node.param_values(tree, ["/a/car/rate", "/gps/origin", "/missing", "/blob"])
    assert found == {
        "/a/car/rate": 10,
        "/gps/origin": {"lat": 40.8, "lon": -96.7},
        "/blob": [0, 1],
    }
    every = node.param_values(tree, None)
    assert set(every) == {
        "/a/car/rate",
        "/a/car/name",
        "/a/car/gains",
        "/gps/origin/lat",
        "/gps/origin/lon",
        "/blob",
        "/when",
    }
    for params in (found, every):
        text = onboard_records.params_text(params)
        assert records.decode_params(text).params == json.loads(text)["params"]
        assert text == records.encode(records.ParamSnapshot(params))


def test_a_parameter_server_that_is_not_a_tree_gives_no_parameters() -> None:
    assert node.param_values("odd", None) == {}
    assert node.param_values(None, ["/a"]) == {}


@pytest.mark.parametrize(
    ("said", "expected"),
    [
        (
            "service [/rec/s] responded with an error: b'service cannot process request: no'",
            "no",
        ),
        ("service [/rec/s] responded with an error: error processing request: boom", None),
        ("unable to connect to service: [Errno 111] refused", None),
        ("transport error completing service call: x", None),
    ],
)
def test_a_client_sees_what_the_server_said(said: str, expected: str | None) -> None:
    message = node.client_message(said)
    if expected is not None:
        assert message == expected
    else:
        assert message in said
        assert not message.startswith("service [")


def test_the_specification_needs_the_node_names() -> None:
    spec = node.load_spec('{"node": "/imrosc_recorder_1", "rosbag": "/imrosc_rosbag_1"}')
    assert spec["services"] == []
    assert spec["period"] == 1.0
    assert spec["prefix"] == "/rec"
    with pytest.raises(ValueError, match="node"):
        node.load_spec('{"rosbag": "/b"}')
    with pytest.raises(ValueError, match="rosbag"):
        node.load_spec('{"node": "/a", "rosbag": "b"}')


def test_the_script_refuses_a_bad_specification_before_importing_rospy() -> None:
    for argv, status in ((["x"], 2), (["x", "not json"], 2), (["x", '{"node": "/a"}'], 2)):
        done = subprocess.run(
            [sys.executable, "-m", RECORDER, *argv[1:]],
            cwd=PACKAGE.parent,
            capture_output=True,
            text=True,
            timeout=60,
            check=False,
        )
        assert done.returncode == status, done.stderr
        assert "Traceback" not in done.stderr
        assert done.stderr.strip()
