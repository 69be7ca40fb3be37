"""rospy messages as the ROS 1 monitor reads and fills them
(``imrosc/onboard/monitor_ros1/messages.py``), with stand-ins for genpy's message classes."""

from __future__ import annotations

from typing import Any

import pytest

from imrosc.onboard import monitor as common
from imrosc.onboard.monitor_ros1 import messages
from tests.backends.support import HOSTILE


class FakeMessage:
    """A stand-in for a genpy message: ``__slots__`` and ``_slot_types``."""

    __slots__: tuple[str, ...] = ()
    _slot_types: tuple[str, ...] = ()

    def __init__(self) -> None:
        for name, kind in zip(self.__slots__, self._slot_types, strict=True):
            default: Any = 0 if "int" in kind else 0.0 if "float" in kind else ""
            default = [] if "[" in kind else False if kind == "bool" else default
            setattr(self, name, CLASSES[kind]() if kind in CLASSES else default)


class Vector3(FakeMessage):
    __slots__ = ("x", "y", "z")
    _slot_types = ("float64", "float64", "float64")


class Twist(FakeMessage):
    __slots__ = ("linear", "angular")  # noqa: RUF023 - genpy order
    _slot_types = ("geometry_msgs/Vector3", "geometry_msgs/Vector3")


class Everything(FakeMessage):
    __slots__ = ("level", "flag", "name", "points", "raw", "gains", "twist")  # noqa: RUF023
    _slot_types = (
        "uint8",
        "bool",
        "string",
        "geometry_msgs/Vector3[]",
        "uint8[]",
        "float32[3]",
        "geometry_msgs/Twist",
    )


CLASSES: dict[str, type[FakeMessage]] = {
    "geometry_msgs/Vector3": Vector3,
    "geometry_msgs/Twist": Twist,
}


def test_fill_sets_fields_from_an_action_value() -> None:
    value = {
        "level": 3,
        "flag": True,
        "name": HOSTILE,
        "points": [{"x": 1.5}, {"y": 2}],
        "raw": [1, 2, 255],
        "gains": [0.5, 1, 2.0],
        "twist": {"linear": {"x": 0.5}, "angular": {"z": -0.2}},
    }
    message = messages.fill(Everything(), value, CLASSES.__getitem__)
    assert (message.level, message.flag, message.name) == (3, True, HOSTILE)
    assert [(p.x, p.y) for p in message.points] == [(1.5, 0.0), (0.0, 2.0)]
    assert message.raw == b"\x01\x02\xff"
    assert message.gains == [0.5, 1.0, 2.0]
    assert (message.twist.linear.x, message.twist.angular.z) == (0.5, -0.2)


@pytest.mark.parametrize(
    ("value", "problem"),
    [
        ({"levle": 3}, "no such field"),
        ({"level": 256}, "out of range"),
        ({"level": -1}, "out of range"),
        ({"level": 2.5}, "not an integer"),
        ({"level": "3"}, "not an integer"),
        ({"flag": "yes"}, "not a bool"),
        ({"twist": {"linear": 3}}, "not a mapping"),
        ({"twist": {"linear": {"w": 1}}}, "no such field"),
        ({"points": {"x": 1}}, "not a list"),
        ({"name": {"a": 1}}, "mapping"),
    ],
)
def test_fill_refuses_values_that_do_not_fit(value: dict[str, Any], problem: str) -> None:
    with pytest.raises(messages.FillError, match=problem):
        messages.fill(Everything(), value, CLASSES.__getitem__)


def test_a_service_call_becomes_request_response_and_delay_values() -> None:
    class Stamp:
        __slots__ = ("nsecs", "secs")

        def __init__(self) -> None:
            self.secs, self.nsecs = 3, 500_000_000

    class Request(FakeMessage):
        __slots__ = ("task_id", "names")  # noqa: RUF023 - pairs with _slot_types
        _slot_types = ("int32", "string[]")
        task_id: int
        names: list[str]

    class Response(FakeMessage):
        __slots__ = ("status", "stamp")  # noqa: RUF023 - pairs with _slot_types
        _slot_types = ("string", "time")
        status: str
        stamp: Any

    request, response = Request(), Response()
    request.task_id, request.names = 4, ["a", "b"]
    response.status = "ok"
    response.stamp = Stamp()
    assert common.call_values(messages.message_data, request, response, 0.25) == {
        "request.task_id": 4,
        "len(request.names)": 2,
        "response.status": "ok",
        "response.stamp": 3.5,
        "delay": 0.25,
    }
    assert common.request_values(messages.message_data, request) == {
        "request.task_id": 4,
        "len(request.names)": 2,
    }
