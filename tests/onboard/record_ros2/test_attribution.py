"""The ROS 2 recorder node records a call once the graph names its client and server
(``imrosc/onboard/record_ros2/node.py``: ``Recorder.flush``): a call paired before discovery
told the node of the service's request endpoints waits for it, :data:`ATTRIBUTE` seconds at
most, then goes out with ``/unknown``; nothing waits when the recorder stops. The recorder is
built without rclpy: its graph lookups and its publisher are stand-ins."""

from __future__ import annotations

import threading
import time
from typing import Any

import pytest

from imrosc import records
from imrosc.onboard.record_ros2 import logic
from imrosc.onboard.record_ros2 import node as recorder_node


class Clock:
    def __init__(self) -> None:
        self.now = 100.0

    def monotonic(self) -> float:
        return self.now


def recorder(known: dict[str, str], clock: Clock, monkeypatch: pytest.MonkeyPatch) -> Any:
    """A ``Recorder`` whose graph names the nodes in ``known`` (``client``, ``server``; a
    missing one is ``/unknown``) and whose records land in ``sent``."""
    monkeypatch.setattr(time, "monotonic", clock.monotonic)  # the node's clock
    stub: Any = object.__new__(recorder_node.Recorder)
    stub.lock = threading.Lock()
    stub.unattributed = []
    stub.counts = {}
    stub.sent = []
    stub.publish = lambda topic, text: stub.sent.append((topic, records.decode_call(text)))
    stub.client_of = lambda call: known.get("client", logic.UNKNOWN_NODE)
    stub.server_of = lambda call: known.get("server", logic.UNKNOWN_NODE)
    return stub


def call(stamp: float) -> logic.Call:
    return logic.Call("/sys/switch", b"\x01" * 16, {"data": True}, {"success": True}, stamp, 0.01)


def test_a_call_waits_for_the_graph_to_name_its_client(monkeypatch: pytest.MonkeyPatch) -> None:
    clock = Clock()
    known = {"server": "/sys/server"}
    node = recorder(known, clock, monkeypatch)
    node.flush([call(1.0)])
    assert node.sent == [] and len(node.unattributed) == 1
    known["client"] = "/sys/client"  # discovery caught up by the next poll
    clock.now += 0.5
    node.flush([call(1.5)])
    assert [(r.stamp, r.client, r.server) for _, r in node.sent] == [
        (1.0, "/sys/client", "/sys/server"),
        (1.5, "/sys/client", "/sys/server"),
    ]
    assert {topic for topic, _ in node.sent} == {records.SRVS_TOPIC}
    assert node.unattributed == [] and node.counts == {"/sys/switch": 2}


def test_a_call_the_graph_never_names_goes_out_as_unknown_after_the_wait(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    clock = Clock()
    node = recorder({"server": "/sys/server"}, clock, monkeypatch)
    node.flush([call(1.0)])
    clock.now += recorder_node.ATTRIBUTE - 0.1
    node.flush([])
    assert node.sent == []
    clock.now += 0.2
    node.flush([])
    assert [(r.client, r.server) for _, r in node.sent] == [("/unknown", "/sys/server")]


def test_nothing_waits_when_the_recorder_stops(monkeypatch: pytest.MonkeyPatch) -> None:
    node = recorder({}, Clock(), monkeypatch)
    node.flush([call(1.0)])
    node.flush([call(2.0)], final=True)
    assert [(r.stamp, r.client, r.server) for _, r in node.sent] == [
        (1.0, "/unknown", "/unknown"),
        (2.0, "/unknown", "/unknown"),
    ]
