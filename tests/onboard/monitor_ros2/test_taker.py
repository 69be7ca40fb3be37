"""Taking the messages waiting on a subscription outside rclpy's executor
(``imrosc/onboard/monitor_ros2/plumbing.py``: ``taker``), with a stand-in for rclpy's subscription
and its handle."""

from __future__ import annotations

from collections import deque
from typing import Any

from imrosc.onboard.monitor_ros2 import plumbing


class Handle:
    """rclpy's subscription handle: a context manager (``InvalidHandle`` once destroyed) with
    ``take_message(type, raw)`` giving ``(message, info)`` or ``None``."""

    def __init__(self, waiting: list[Any]) -> None:
        self.waiting = deque(waiting)
        self.destroyed = False
        self.asked: list[tuple[Any, bool]] = []

    def __enter__(self) -> Handle:
        if self.destroyed:
            raise RuntimeError("InvalidHandle")
        return self

    def __exit__(self, *exc: object) -> None:
        return None

    def take_message(self, kind: Any, raw: bool) -> tuple[Any, dict[str, int]] | None:
        self.asked.append((kind, raw))
        return (self.waiting.popleft(), {}) if self.waiting else None


class Subscription:
    def __init__(self, handle: Any, raw: bool = True) -> None:
        self.handle = handle
        self.msg_type = "Imu"
        self.raw = raw


def test_the_waiting_messages_come_in_order_then_none() -> None:
    handle = Handle([b"a", b"b"])
    take = plumbing.taker(Subscription(handle))
    assert take is not None
    assert [take(), take(), take()] == [b"a", b"b", None]
    assert handle.asked == [("Imu", True)] * 3


def test_a_destroyed_subscription_gives_nothing() -> None:
    handle = Handle([b"a"])
    take = plumbing.taker(Subscription(handle))
    assert take is not None
    handle.destroyed = True
    assert take() is None


def test_an_rclpy_without_take_message_gives_no_taker() -> None:
    assert plumbing.taker(Subscription(object())) is None
    assert plumbing.taker(object()) is None
