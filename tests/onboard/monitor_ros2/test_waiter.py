"""Waiting for messages on a set of subscriptions outside rclpy's executor
(``imrosc/onboard/monitor_ros2/plumbing.py``: ``Waiter``), with stand-ins for rclpy's wait
set, guard condition, context and subscription handles."""

from __future__ import annotations

from typing import Any, ClassVar

import pytest

from imrosc.onboard.monitor_ros2 import plumbing


class Handle:
    """A handle: a context manager (raises once destroyed) with a ``pointer``; ``ready``
    says whether a message waits on it."""

    def __init__(self, pointer: int, ready: bool = False) -> None:
        self.pointer = pointer
        self.ready = ready
        self.destroyed = False
        self.held = 0

    def __enter__(self) -> Handle:
        if self.destroyed:
            raise RuntimeError("InvalidHandle")
        self.held += 1
        return self

    def __exit__(self, *exc: object) -> None:
        self.held -= 1


class Entity:
    def __init__(self, handle: Handle) -> None:
        self.handle = handle


class Context:
    def __init__(self) -> None:
        self.handle = Handle(0)
        self.up = True

    def ok(self) -> bool:
        return self.up


class Guard:
    """rclpy's GuardCondition(callback, group, context=...)."""

    def __init__(self, callback: Any, group: Any, context: Any = None) -> None:
        self.handle = Handle(-1)
        self.triggered = 0

    def trigger(self) -> None:
        self.triggered += 1


class WaitSet:
    """rclpy's wait set: what was added, waited on while every handle is held."""

    made: ClassVar[list[WaitSet]] = []

    def __init__(self, subscriptions: int, guards: int, *rest: Any) -> None:
        self.sizes = (subscriptions, guards)
        self.subscriptions: list[Handle] = []
        self.guards: list[Handle] = []
        self.held_while_waiting: list[int] = []
        WaitSet.made.append(self)

    def clear_entities(self) -> None:
        self.subscriptions, self.guards = [], []

    def add_subscription(self, handle: Handle) -> None:
        self.subscriptions.append(handle)

    def add_guard_condition(self, handle: Handle) -> None:
        self.guards.append(handle)

    def wait(self, timeout: int) -> None:
        self.timeout = timeout
        self.held_while_waiting = [h.held for h in self.subscriptions]

    def get_ready_entities(self, kind: str) -> list[int]:
        assert kind == "subscription"
        return [h.pointer for h in self.subscriptions if h.ready]


@pytest.fixture
def waiter(monkeypatch: pytest.MonkeyPatch) -> tuple[plumbing.Waiter, Context]:
    monkeypatch.setattr(plumbing, "WAIT_SET", WaitSet)
    monkeypatch.setattr(plumbing, "GuardCondition", Guard, raising=False)
    WaitSet.made = []
    context = Context()
    return plumbing.Waiter(context), context


def test_the_ready_subscriptions_keys_come_back(waiter: tuple[plumbing.Waiter, Context]) -> None:
    wait, _ = waiter
    quiet, busy = Handle(1), Handle(2, ready=True)
    wait.put("/a", Entity(quiet))
    wait.put("/b", Entity(busy))
    assert wait.wait(0.5) == ["/b"]
    made = WaitSet.made[-1]
    assert made.sizes == (2, 1) and made.subscriptions == [quiet, busy]
    assert made.guards == [wait.wake.handle] and made.timeout == 500_000_000
    assert made.held_while_waiting == [1, 1]  # none destroyed while waited on
    assert quiet.held == busy.held == 0  # and let go after


def test_put_replaces_a_subscription_and_wakes_the_wait(
    waiter: tuple[plumbing.Waiter, Context],
) -> None:
    wait, _ = waiter
    wait.put("/a", Entity(Handle(1)))
    new = Handle(3, ready=True)
    wait.put("/a", Entity(new))
    assert wait.wake.triggered == 2
    assert wait.wait(0.1) == ["/a"] and WaitSet.made[-1].subscriptions == [new]


def test_a_destroyed_subscription_is_left_out(waiter: tuple[plumbing.Waiter, Context]) -> None:
    wait, _ = waiter
    gone = Handle(1, ready=True)
    gone.destroyed = True
    wait.put("/a", Entity(gone))
    wait.put("/b", Entity(Handle(2, ready=True)))
    assert wait.wait(0.1) == ["/b"]
    assert WaitSet.made[-1].subscriptions == [wait.subscriptions["/b"].handle]


def test_nothing_once_closed_or_shut_down(waiter: tuple[plumbing.Waiter, Context]) -> None:
    wait, context = waiter
    wait.put("/a", Entity(Handle(1, ready=True)))
    context.up = False
    assert wait.wait(0.1) == []
    context.up = True
    wait.close()
    assert wait.closed and wait.wait(0.1) == []


def test_no_waiter_without_rclpy_s_wait_set(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(plumbing, "WAIT_SET", None)
    assert not plumbing.Waiter.available()


def test_no_executor_runs_the_waiter_s_group() -> None:
    group = plumbing.NotByTheExecutor()
    assert not group.can_execute(object()) and not group.beginning_execution(object())
