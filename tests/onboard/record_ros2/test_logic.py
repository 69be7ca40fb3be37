"""What the ROS 2 recorder decides without rclpy (``imrosc/onboard/record_ros2/logic.py``):
the records the readers accept and service calls paired from introspection events. Moved
from tests/backends/test_ros2_recorder.py unchanged."""

from __future__ import annotations

import math
from types import SimpleNamespace
from typing import Any

import pytest

from imrosc import records
from imrosc.onboard import records as record_format
from imrosc.onboard.monitor_ros2 import logic as graph
from imrosc.onboard.record_ros2 import logic

GID = bytes(range(16))
OTHER = bytes(range(1, 17))


# -- records the readers accept -------------------------------------------------------------


def test_architecture_records_decode_and_leave_the_machinery_out() -> None:
    view = graph.GraphView(
        topics={
            "/a/pose": (["/a/car", "/rec"], ["/a/ctrl", "/rosbag2_recorder"]),
            "/imrosc/arch": (["/rec"], ["/rosbag2_recorder"]),
            "/a/reset/_service_event": (["/a/car"], ["/rec"]),
            "/parameter_events": (["/a/car"], []),
            "/lonely": (["/rec"], []),
        },
        types={},
        publisher_qos={},
        services={"/a/reset": ["/a/car"], "/rec/get_parameters": ["/rec"]},
        service_types={},
        nodes=["/a/car", "/a/ctrl", "/rec", "/_ros2cli_daemon_0"],
    )
    topics, services = logic.arch_of(view, ["/rec"])
    text = record_format.arch_text(topics, services)
    decoded = records.decode_arch(text)
    assert records.encode(decoded) == text
    assert decoded.topics["/a/pose"] == records.TopicEnds(
        frozenset({"/a/car"}), frozenset({"/a/ctrl"})
    )
    assert set(decoded.topics) == {"/a/pose", "/parameter_events"}
    assert decoded.services == {"/a/reset": frozenset({"/a/car"})}


def test_parameter_records_decode_identically() -> None:
    answers = {"/a/car_ctrl/gain": 2.5, "/a/car_ctrl/mode": "x", "/a/raw": [b"\x01", b"\x02"]}
    answers["/a/nan"] = math.nan
    text = record_format.params_text(logic.params_of(answers, [*answers, "/a/unset"]))
    decoded = records.decode_params(text)
    assert records.encode(decoded) == text
    assert decoded.params["/a/raw"] == [1, 2] and "/a/unset" not in decoded.params
    assert record_format.params_text({}) == records.encode(records.ParamSnapshot({}))


def test_change_detection_publishes_only_on_change() -> None:
    changes = logic.Changes()
    first = record_format.arch_text({"/t": (["/a"], [])}, {})
    same = record_format.arch_text({"/t": ({"/a"}, ())}, {})
    other = record_format.arch_text({"/t": (["/a", "/b"], [])}, {})
    published = [
        text
        for topic, text in [
            (record_format.ARCH_TOPIC, first),
            (record_format.ARCH_TOPIC, same),
            (record_format.PARAMS_TOPIC, record_format.params_text({})),
            (record_format.ARCH_TOPIC, other),
            (record_format.PARAMS_TOPIC, record_format.params_text({})),
            (record_format.ARCH_TOPIC, first),
        ]
        if changes.changed(topic, text)
    ]
    assert published == [first, record_format.params_text({}), other, first]


# -- service calls from introspection events ------------------------------------------------


def event(
    kind: int, stamp: float, gid: bytes = GID, sequence: int = 1, **data: Any
) -> logic.ServiceEvent:
    return logic.ServiceEvent(kind, stamp, gid, sequence, data.get("request"), data.get("response"))


def record(
    call: logic.Call, client: str = "/a/ctrl", server: str = "/a/car"
) -> records.ServiceCall:
    text = logic.call_record(call, client, server)
    decoded = records.decode_call(text)
    assert records.encode(decoded) == text
    return decoded


def test_four_events_make_one_call_timed_by_the_client() -> None:
    pairing = logic.Pairing()
    calls = []
    calls += pairing.add("/a/reset", event(logic.REQUEST_SENT, 10.0, request={"data": 1.5}), 0.0)
    calls += pairing.add(
        "/a/reset", event(logic.REQUEST_RECEIVED, 10.1, request={"data": 1.5}), 0.0
    )
    calls += pairing.add(
        "/a/reset", event(logic.RESPONSE_SENT, 10.2, response={"success": True}), 0.0
    )
    assert calls == []  # the client's side is still missing
    calls += pairing.add(
        "/a/reset", event(logic.RESPONSE_RECEIVED, 10.25, response={"success": True}), 0.0
    )
    (call,) = calls
    decoded = record(call)
    assert decoded.service == "/a/reset" and decoded.ok
    assert decoded.request == {"data": 1.5} and decoded.response == {"success": True}
    assert decoded.stamp == 10.0 and math.isclose(decoded.delay, 0.25)
    assert (decoded.client, decoded.server) == ("/a/ctrl", "/a/car")
    # a repeated event of a finished call starts nothing that completes
    assert pairing.add("/a/reset", event(logic.RESPONSE_RECEIVED, 10.25), 0.0) == []
    assert pairing.drain() == [] and pairing.dropped == 1


def test_server_side_introspection_alone_records_calls() -> None:
    pairing = logic.Pairing()
    assert pairing.add("/s", event(logic.REQUEST_RECEIVED, 5.0, request={"a": 1}), 0.0) == []
    (call,) = pairing.add("/s", event(logic.RESPONSE_SENT, 5.5, response={"b": [1, 2]}), 0.1)
    decoded = record(call)
    assert decoded.stamp == 5.0 and math.isclose(decoded.delay, 0.5)
    assert decoded.response == {"b": [1, 2]}


PARTICIPANT = bytes(range(100, 112))
WRITER = PARTICIPANT + bytes([0, 0, 0x2A, 0x03])
"""The client's request writer: the gid of the client's own events (rmw_fastrtps, Jazzy)."""
READER = PARTICIPANT + bytes([0, 0, 0x29, 0x04])
"""The client's response reader: the gid the server's events carry for that client."""


@pytest.mark.parametrize("order", [(0, 1, 2, 3), (1, 2, 0, 3), (1, 0, 2, 3), (2, 1, 3, 0)])
def test_the_two_sides_name_the_client_by_two_endpoints_and_make_one_call(
    order: tuple[int, ...],
) -> None:
    pairing = logic.Pairing()
    gids = {logic.REQUEST_SENT: WRITER, logic.RESPONSE_RECEIVED: WRITER}
    calls = []
    for sequence in (4, 5):
        events = [
            event(logic.REQUEST_SENT, sequence + 0.0, WRITER, sequence, request={"data": True}),
            event(logic.REQUEST_RECEIVED, sequence + 0.1, READER, sequence, request={"data": True}),
            event(logic.RESPONSE_SENT, sequence + 0.2, READER, sequence, response={"ok": 1}),
            event(logic.RESPONSE_RECEIVED, sequence + 0.3, WRITER, sequence, response={"ok": 1}),
        ]
        for index in order:
            assert gids.get(events[index].kind, READER) == events[index].client_gid
            calls += pairing.add("/s", events[index], 0.0)
    assert [(c.request, c.response) for c in calls] == [({"data": True}, {"ok": 1})] * 2
    # once both sides have been seen introspecting, a call is the client's, timed by it (the
    # first is the server's when the server's events came first and completed it)
    assert (calls[1].client_gid, calls[1].stamp, round(calls[1].delay, 6)) == (WRITER, 5.0, 0.3)
    first = (calls[0].client_gid, calls[0].stamp, round(calls[0].delay, 6))
    assert first in ((WRITER, 4.0, 0.3), (READER, 4.1, 0.1))
    assert pairing.drain() == [] and pairing.dropped == 0 and pairing.aliases == {}


def test_the_late_side_of_a_call_given_out_already_is_part_of_it() -> None:
    pairing = logic.Pairing()
    client = [
        event(logic.REQUEST_SENT, 1.0, WRITER, 1, request={"data": True}),
        event(logic.RESPONSE_RECEIVED, 1.3, WRITER, 1, response={"ok": 1}),
    ]
    assert pairing.add("/s", client[0], 0.0) == []
    (call,) = pairing.add("/s", client[1], 0.0)  # the server has not been seen introspecting
    assert pairing.add("/s", event(logic.REQUEST_RECEIVED, 1.1, READER, 1), 0.0) == []
    assert pairing.add("/s", event(logic.RESPONSE_SENT, 1.2, READER, 1), 0.0) == []
    assert pairing.drain() == [] and pairing.dropped == 0
    assert call.stamp == 1.0


def test_calls_of_two_clients_with_the_same_sequence_number_stay_apart() -> None:
    pairing = logic.Pairing()
    pairing.add("/s", event(logic.REQUEST_RECEIVED, 1.0, GID, 7, request={"x": 1}), 0.0)
    pairing.add("/s", event(logic.REQUEST_RECEIVED, 1.1, OTHER, 7, request={"x": 2}), 0.0)
    (second,) = pairing.add("/s", event(logic.RESPONSE_SENT, 1.3, OTHER, 7, response={"y": 2}), 0.0)
    (first,) = pairing.add("/s", event(logic.RESPONSE_SENT, 1.2, GID, 7, response={"y": 1}), 0.0)
    assert (first.request, first.response, first.client_gid) == ({"x": 1}, {"y": 1}, GID)
    assert (second.request, second.response, second.client_gid) == ({"x": 2}, {"y": 2}, OTHER)


def test_a_call_without_response_is_recorded_as_failed_after_the_timeout() -> None:
    pairing = logic.Pairing(settle=1.0, timeout=5.0)
    pairing.add("/s", event(logic.REQUEST_RECEIVED, 1.0, request={"x": 1}), 100.0)
    assert pairing.due(104.0) == []
    (call,) = pairing.due(105.0)
    decoded = record(call)
    assert not decoded.ok and decoded.response is None and decoded.delay == 0.0


def test_a_side_that_stops_introspecting_delays_the_call_by_settle_only() -> None:
    pairing = logic.Pairing(settle=1.0, timeout=5.0)
    for kind in (
        logic.REQUEST_SENT,
        logic.REQUEST_RECEIVED,
        logic.RESPONSE_SENT,
        logic.RESPONSE_RECEIVED,
    ):
        pairing.add("/s", event(kind, 1.0 + kind / 10, sequence=1), 0.0)
    # the client stops introspecting: call 2 has the server's events only
    pairing.add("/s", event(logic.REQUEST_RECEIVED, 2.0, sequence=2), 10.0)
    assert pairing.add("/s", event(logic.RESPONSE_SENT, 2.5, sequence=2), 10.0) == []
    assert pairing.due(10.5) == []
    (call,) = pairing.due(11.0)
    assert call.stamp == 2.0 and math.isclose(call.delay, 0.5)
    assert record(call).response == {}  # metadata only: no contents


def test_a_response_without_its_request_is_dropped() -> None:
    pairing = logic.Pairing(settle=0.0)
    assert pairing.add("/s", event(logic.RESPONSE_SENT, 1.0), 0.0) == []
    assert pairing.due(0.0) == [] and pairing.dropped == 1


def test_events_are_read_from_rclpy_messages() -> None:
    class Request:
        def __init__(self) -> None:
            self.data = True
            self.name = "x"
            self.raw = b"\x01\x02"

        @staticmethod
        def get_fields_and_field_types() -> dict[str, str]:
            return {"data": "boolean", "name": "string", "raw": "sequence<uint8>"}

    info = SimpleNamespace(
        event_type=logic.REQUEST_SENT,
        stamp=SimpleNamespace(sec=3, nanosec=500_000_000),
        client_gid=list(GID),
        sequence_number=4,
    )
    found = logic.event_of(SimpleNamespace(info=info, request=[Request()], response=[]))
    assert found == logic.ServiceEvent(
        logic.REQUEST_SENT, 3.5, GID, 4, {"data": True, "name": "x", "raw": [1, 2]}, None
    )


def test_the_client_is_named_by_its_gid_or_the_event_publishers() -> None:
    writers = [(GID + b"\x00" * 8, "/a/ctrl"), (OTHER, "/b/ctrl")]
    assert logic.client_node(GID, writers) == "/a/ctrl"
    assert logic.client_node(OTHER, writers) == "/b/ctrl"
    assert logic.client_node(b"\x09" * 16, writers, ["/a/car", "/c"], ["/a/car"]) == "/c"
    assert logic.client_node(b"\x09" * 16, writers) == logic.UNKNOWN_NODE
    unknown = logic.UNKNOWN_NODE
    text = record_format.call_text("/s", unknown, unknown, {}, None, 1.0, 0.0)
    assert records.decode_call(text).client == unknown


def test_a_call_unanswered_when_the_recorder_stops_is_left_out_unless_its_time_is_up() -> None:
    """The client's call in flight at Ctrl-C is not a failed call: the recording ended
    before its answer. One waiting longer than ``timeout`` is recorded as failed, and an
    answered one still settling is given out as usual."""
    pairing = logic.Pairing(settle=1.0, timeout=10.0)
    assert pairing.add("/s", event(logic.REQUEST_SENT, 1.0, WRITER, 1, request={"a": 1}), 0.0) == []
    assert pairing.add("/s", event(logic.REQUEST_SENT, 2.0, WRITER, 2, request={"a": 2}), 5.0) == []
    assert pairing.add("/s", event(logic.REQUEST_SENT, 3.0, WRITER, 3, request={"a": 3}), 9.0) == []
    answered = event(logic.RESPONSE_RECEIVED, 3.2, WRITER, 3, response={"b": 1})
    pairing.add("/s", event(logic.REQUEST_RECEIVED, 3.1, READER, 3, request={"a": 3}), 9.0)
    assert pairing.add("/s", answered, 9.1) == []  # the server's response event is missing
    calls = pairing.drain(12.0)
    assert [(c.request, c.response) for c in calls] == [({"a": 1}, None), ({"a": 3}, {"b": 1})]
    assert record(calls[0]).ok is False and record(calls[1]).ok
    assert pairing.unfinished == 1 and pairing.pending == {} and pairing.aliases == {}
