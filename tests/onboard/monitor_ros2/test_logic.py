"""What the ROS 2 monitor's adapter decides without rclpy
(``imrosc/onboard/monitor_ros2/logic.py``): QoS, the graph, parameters, filling an action's
message, service calls, interface names and warnings. Moved from tests/backends/test_ros2.py
unchanged."""

from __future__ import annotations

import json
from types import SimpleNamespace
from typing import Any, ClassVar

import numpy as np
import pytest

from imrosc.onboard import monitor as common
from imrosc.onboard.fill import FillError
from imrosc.onboard.monitor_ros2 import logic
from imrosc.runtime import Violation
from tests.backends.ros2_support import parameter_value
from tests.backends.support import HOSTILE

RELIABLE = logic.Qos(logic.RELIABLE, logic.VOLATILE)
BEST_EFFORT = logic.Qos(logic.BEST_EFFORT, logic.VOLATILE)
LATCHED = logic.Qos(logic.RELIABLE, logic.TRANSIENT_LOCAL)


@pytest.mark.parametrize(
    ("publishers", "msgtype", "subscription", "relay"),
    [
        ([], "sensor_msgs/msg/Imu", BEST_EFFORT, BEST_EFFORT),  # qos_profile_sensor_data
        ([], "std_msgs/msg/UInt8", RELIABLE, RELIABLE),
        ([None], "std_msgs/msg/UInt8", RELIABLE, RELIABLE),  # a QoS it does not report
        ([RELIABLE], "sensor_msgs/msg/Imu", RELIABLE, RELIABLE),
        ([BEST_EFFORT], "std_msgs/msg/UInt8", BEST_EFFORT, BEST_EFFORT),
        ([RELIABLE, BEST_EFFORT], "std_msgs/msg/UInt8", BEST_EFFORT, RELIABLE),
        ([LATCHED], "std_msgs/msg/String", LATCHED, LATCHED),
        ([LATCHED, RELIABLE], "std_msgs/msg/String", RELIABLE, LATCHED),
    ],
)
def test_subscriptions_match_every_publisher_and_relays_offer_the_source_qos(
    publishers: list[logic.Qos | None],
    msgtype: str,
    subscription: logic.Qos,
    relay: logic.Qos,
) -> None:
    assert logic.subscription_qos(publishers, msgtype) == subscription
    assert logic.relay_qos(publishers, msgtype) == relay


def test_qos_changes_when_publishers_ask_for_it_and_stays_when_they_leave() -> None:
    battery = "sensor_msgs/msg/BatteryState"
    first = logic.qos_update(None, [], battery)
    assert first == logic.SENSOR_DATA
    assert logic.qos_update(first, [], battery) is None
    changed = logic.qos_update(first, [RELIABLE], battery)
    assert changed == RELIABLE
    assert logic.qos_update(changed, [RELIABLE], battery) is None
    assert logic.qos_update(changed, [None], battery) is None
    offer = logic.qos_update(None, [LATCHED], battery, logic.relay_qos)
    assert offer == LATCHED


def test_endpoint_qos_reads_rmw_values_of_enums_and_integers() -> None:
    class Reliability(int):
        pass

    rclpy_like = SimpleNamespace(reliability=Reliability(2), durability=Reliability(1))
    assert logic.endpoint_qos(rclpy_like) == logic.Qos(logic.BEST_EFFORT, logic.TRANSIENT_LOCAL)
    assert logic.endpoint_qos(SimpleNamespace(reliability=0, durability=2)) is None  # default
    assert logic.endpoint_qos(SimpleNamespace(reliability=3, durability=2)) is None  # unknown
    assert logic.endpoint_qos(None) is None


def graph_view() -> logic.GraphView:
    return logic.GraphView(
        topics={
            "/t": (["/a", "/mon", "/rogue"], ["/mon"]),
            "/m/t": (["/mon"], ["/b"]),
            "/rosout": (["/a", "/mon"], []),
        },
        types={"/t": ["std_msgs/msg/UInt8"]},
        publisher_qos={"/t": [("/a", RELIABLE), ("/mon", LATCHED), ("/rogue", BEST_EFFORT)]},
        services={"/s": ["/server"], "/m/s": ["/mon"], "/a/get_parameters": ["/a"]},
        service_types={"/s": ["std_srvs/srv/Trigger"]},
        nodes=["/a", "/b", "/mon", "/rogue", "/server"],
    )


def test_the_graph_from_rclpy_folds_relays_back_and_leaves_the_monitor_out() -> None:
    graph = logic.snapshot(graph_view(), {"/mon", "/mon_watchdog"}, {"/t": "/m/t"}, {"/s": "/m/s"})
    assert graph["pub"] == {"/t": frozenset({"/a", "/rogue"}), "/rosout": frozenset({"/a"})}
    assert graph["sub"] == {"/t": frozenset({"/b"})}
    assert graph["srv"] == {"/s": frozenset({"/server"}), "/a/get_parameters": frozenset({"/a"})}
    assert logic.publisher_qos(graph_view(), "/t", {"/mon"}) == [RELIABLE, BEST_EFFORT]
    assert logic.node_name("/", "x") == "/x" and logic.resolve_node("/a", "w") == "/a/w"


def test_ros2_bag_play_stands_for_the_publishers_learnt_and_ros2_bag_record_is_left_out() -> None:
    view = logic.GraphView(
        topics={
            "/t": (["/rosbag2_player"], ["/mon", "/rosbag2_recorder", "/b"]),
            "/u": (["/rosbag2_player"], []),
        },
        types={},
        publisher_qos={},
        services={},
        service_types={},
        nodes=["/b", "/mon", "/rosbag2_player", "/rosbag2_recorder"],
    )
    learnt = {"/t": frozenset({"/a"})}
    graph = logic.snapshot(view, {"/mon"}, {}, {}, learnt)
    # a recording played into the monitor is its publishers; on a topic nobody learnt the
    # player stays itself; the recorder is no subscriber of the robot's
    assert graph["pub"] == {"/t": frozenset({"/a"}), "/u": frozenset({"/rosbag2_player"})}
    assert graph["sub"] == {"/t": frozenset({"/b"})}
    assert logic.snapshot(view, {"/mon"}, {}, {})["pub"]["/t"] == frozenset({"/rosbag2_player"})


def test_parameters_are_asked_of_their_node_and_answered_by_type() -> None:
    names = ["/a/car_ctrl/landing_radius", "/a/car_ctrl/gains/p", "/a/car_ctrl/missing", "/z/k"]
    requests = logic.parameter_requests(names, ["/a", "/a/car_ctrl"])
    assert requests == {
        "/a/car_ctrl": [
            ("/a/car_ctrl/gains/p", "gains.p"),
            ("/a/car_ctrl/landing_radius", "landing_radius"),
            ("/a/car_ctrl/missing", "missing"),
        ],
        "/z": [("/z/k", "k")],
    }
    values = [parameter_value(0.5), parameter_value(2.5), SimpleNamespace(type=0)]
    answered, missing = logic.parameter_answers(requests["/a/car_ctrl"], values)
    assert answered == {"/a/car_ctrl/gains/p": 0.5, "/a/car_ctrl/landing_radius": 2.5}
    assert missing == ["/a/car_ctrl/missing"]
    assert logic.parameter_answers([("/x", "x")], []) == ({}, ["/x"])  # no answer: not set
    typed = [
        (SimpleNamespace(type=1, bool_value=True), True),
        (SimpleNamespace(type=2, integer_value=3), 3),
        (SimpleNamespace(type=4, string_value="fast"), "fast"),
        (SimpleNamespace(type=7, integer_array_value=np.array([1, 2])), [1, 2]),
        (SimpleNamespace(type=9, string_array_value=["a"]), ["a"]),
    ]
    for value, expected in typed:
        assert logic.parameter_value(value) == expected
    with pytest.raises(KeyError):
        logic.parameter_value(SimpleNamespace(type=0))
    flat = logic.param_values({"/a/k": [1.0, 2.0], "/a/m": "x"}, ["/a/k", "/a/m", "/a/none"])
    assert flat == {"len(/a/k)": 2, "/a/m": "x"}


class FakeRos2Message:
    """A stand-in for an rclpy message: ``get_fields_and_field_types`` and attributes."""

    FIELDS: ClassVar[dict[str, str]] = {}

    def __init__(self) -> None:
        for name, kind in self.FIELDS.items():
            setattr(self, name, _default(kind))

    @classmethod
    def get_fields_and_field_types(cls) -> dict[str, str]:
        return dict(cls.FIELDS)


class Vector3(FakeRos2Message):
    FIELDS: ClassVar[dict[str, str]] = {"x": "double", "y": "double", "z": "double"}


class Twist(FakeRos2Message):
    FIELDS: ClassVar[dict[str, str]] = {
        "linear": "geometry_msgs/Vector3",
        "angular": "geometry_msgs/Vector3",
    }


class Time(FakeRos2Message):
    FIELDS: ClassVar[dict[str, str]] = {"sec": "int32", "nanosec": "uint32"}


class Header(FakeRos2Message):
    FIELDS: ClassVar[dict[str, str]] = {"stamp": "builtin_interfaces/Time", "frame_id": "string"}


class Everything(FakeRos2Message):
    FIELDS: ClassVar[dict[str, str]] = {
        "header": "std_msgs/Header",
        "level": "uint8",
        "flag": "boolean",
        "name": "string",
        "short": "string<=4",
        "points": "sequence<geometry_msgs/Vector3>",
        "raw": "sequence<uint8>",
        "octets": "sequence<octet, 2>",
        "gains": "double[3]",
        "twist": "geometry_msgs/Twist",
    }


CLASSES: dict[str, type[FakeRos2Message]] = {
    "geometry_msgs/Vector3": Vector3,
    "geometry_msgs/Twist": Twist,
    "builtin_interfaces/Time": Time,
    "std_msgs/Header": Header,
}


def _default(kind: str) -> Any:
    if kind in CLASSES:
        return CLASSES[kind]()
    if kind.startswith("sequence") or kind.endswith("]"):
        return []
    return {"boolean": False, "double": 0.0, "string": ""}.get(kind.split("<", 1)[0], 0)


def test_fill_sets_fields_of_a_ros2_message_from_an_action_value() -> None:
    value = {
        "header": {"stamp": 3.25, "frame_id": "map"},
        "level": 3,
        "flag": True,
        "name": HOSTILE,
        "short": "abcd",
        "points": [{"x": 1.5}, {"y": 2}],
        "raw": [1, 2, 255],
        "octets": [7, 255],
        "gains": [0.5, 1, 2.0],
        "twist": {"linear": {"x": 0.5}, "angular": {"z": -0.2}},
    }
    message: Any = logic.fill(Everything(), value, CLASSES.__getitem__)
    assert (message.level, message.flag, message.name, message.short) == (3, True, HOSTILE, "abcd")
    assert (message.header.stamp.sec, message.header.stamp.nanosec) == (3, 250_000_000)
    assert message.header.frame_id == "map"
    assert [(p.x, p.y) for p in message.points] == [(1.5, 0.0), (0.0, 2.0)]
    assert message.raw == [1, 2, 255]
    assert message.octets == [b"\x07", b"\xff"]
    assert message.gains == [0.5, 1.0, 2.0]
    assert (message.twist.linear.x, message.twist.angular.z) == (0.5, -0.2)
    assert logic.message_data(message)["header"] == {"stamp": 3.25, "frame_id": "map"}


@pytest.mark.parametrize(
    ("value", "problem"),
    [
        ({"levle": 3}, "no such field"),
        ({"level": 256}, "out of range"),
        ({"level": -1}, "out of range"),
        ({"level": 2.5}, "not an integer"),
        ({"level": "3"}, "not an integer"),
        ({"flag": "yes"}, "not a bool"),
        ({"short": "abcde"}, "longer than 4"),
        ({"twist": {"linear": 3}}, "not a mapping"),
        ({"twist": {"linear": {"w": 1}}}, "no such field"),
        ({"points": {"x": 1}}, "not a list"),
        ({"gains": [1.0]}, "1 values for an array of 3"),
        ({"octets": [1, 2, 3]}, "more than 2"),
        ({"name": {"a": 1}}, "mapping"),
        ({"header": {"stamp": "now"}}, "not a number of seconds"),
    ],
)
def test_fill_refuses_values_that_do_not_fit(value: dict[str, Any], problem: str) -> None:
    with pytest.raises(FillError, match=problem):
        logic.fill(Everything(), value, CLASSES.__getitem__)


def test_a_ros2_service_call_becomes_request_response_and_delay_values() -> None:
    class Request(FakeRos2Message):
        FIELDS: ClassVar[dict[str, str]] = {
            "task_id": "int32",
            "names": "sequence<string>",
            "gains": "double[2]",
        }

    class Response(FakeRos2Message):
        FIELDS: ClassVar[dict[str, str]] = {"status": "string", "stamp": "builtin_interfaces/Time"}

    request: Any = Request()
    response: Any = Response()
    request.task_id, request.names, request.gains = 4, ["a", "b"], np.array([0.5, 1.5])
    response.status = "ok"
    response.stamp.sec, response.stamp.nanosec = 3, 500_000_000
    assert common.call_values(logic.message_data, request, response, 0.25) == {
        "request.task_id": 4,
        "len(request.names)": 2,
        "len(request.gains)": 2,
        "response.status": "ok",
        "response.stamp": 3.5,
        "delay": 0.25,
    }
    assert common.request_values(logic.message_data, request) == {
        "request.task_id": 4,
        "len(request.names)": 2,
        "len(request.gains)": 2,
    }


def test_interface_names_are_checked_before_they_are_imported() -> None:
    assert logic.interface_name("std_msgs/msg/UInt8") == ("std_msgs.msg", "UInt8")
    assert logic.interface_name("std_srvs/srv/Trigger", "srv") == ("std_srvs.srv", "Trigger")
    for bad in ("std_msgs/srv/UInt8", "a.b/msg/C", "x/msg/Y; import os", "../x/msg/Y", "x/msg/"):
        with pytest.raises(ValueError, match="type name"):
            logic.interface_name(bad, "msg")


def test_only_an_unknown_publisher_gets_a_note() -> None:
    arch = Violation(1.0, "d", "i1", "architecture", "max_pubs", "t", ["/x"], "only {/a}")
    bounds = Violation(1.0, "a", "i2", "bounds", "range", "t", 3.0, "[0, 1]")
    assert json.loads(logic.warning(arch))["note"] == logic.NO_MASTER
    assert logic.warning(bounds, ["f"]) == common.violation_json(bounds, ["f"])
    alone = common.Report(arch, False, None, [])
    warning = json.loads(logic.report_warning(alone))
    assert (warning["alarm"], warning["rule"], warning["note"]) == (False, None, logic.NO_MASTER)
    raised = common.Report(bounds, True, "persist", ["f"])
    assert logic.report_warning(raised) == common.report_json(raised)
