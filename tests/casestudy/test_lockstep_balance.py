"""The lockstep's bookkeeping (``examples/landing_system/lockstep``), without ROS: the
balance of channels (a channel whose subscriber closed the connection no longer holds the
clock), the release, the board that gives the processes their time."""

from __future__ import annotations

import importlib.util
import threading
from pathlib import Path
from typing import Any

LOCKSTEP = Path(__file__).resolve().parents[2] / "examples" / "landing_system" / "lockstep"


def _module() -> Any:
    spec = importlib.util.spec_from_file_location("rospy_lockstep", LOCKSTEP / "rospy_lockstep.py")
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def _coordinator() -> Any:
    """A coordinator with no ROS behind it: its bookkeeping only."""
    coordinator = object.__new__(_module().Coordinator)
    coordinator.name = "/vicon"
    coordinator.reports = {"/a/thief": {}, "/monitor": {}}
    coordinator.sent, coordinator.received, coordinator.services = {}, {}, {}
    coordinator.unbalanced, coordinator.closed = set(), set()
    coordinator.channels, coordinator.inbox = {}, []
    coordinator.state = _State()
    coordinator.own_version = coordinator.state.version
    return coordinator


class _State:
    """The simulator's own lockstep state, as the coordinator reads it."""

    def __init__(self) -> None:
        self.busy = 0
        self.version = 0
        self.sleepers: dict[int, int | None] = {}
        self.sent: dict[str, int] = {}
        self.cond = threading.Condition()


def _report(**counts: Any) -> dict[str, Any]:
    return {"sent": {}, "received": {}, "calls": {}, "served": {}, **counts}


def test_a_message_lost_with_a_closed_connection_does_not_hold_the_clock() -> None:
    coordinator = _coordinator()
    # the thief wrote its first pose to the monitor, which dropped it as an unknown
    # publisher before reading it: sent 1, received 0 on that channel
    coordinator.apply("/a/thief", _report(sent={"/a/car_pose>/monitor": 1}))
    coordinator.apply("/monitor", _report())
    assert coordinator.unbalanced == {("/a/car_pose", "/a/thief", "/monitor")}
    coordinator.apply("/monitor", _report(closed=["/a/car_pose</a/thief"]))
    assert coordinator.unbalanced == set()
    coordinator.recheck()  # (a node joining rechecks every channel)
    assert coordinator.unbalanced == set()


def test_an_open_channel_still_balances() -> None:
    coordinator = _coordinator()
    coordinator.apply("/a/thief", _report(sent={"/a/car_pose>/monitor": 2}))
    coordinator.apply("/monitor", _report(received={"/a/car_pose</a/thief": 1}))
    assert coordinator.unbalanced == {("/a/car_pose", "/a/thief", "/monitor")}
    coordinator.apply("/monitor", _report(received={"/a/car_pose</a/thief": 2}))
    assert coordinator.unbalanced == set()


def _timing(
    time: int, next_: int | None, released: int = 0, waiting: bool = False
) -> dict[str, Any]:
    return {"sim": True, "time": time, "next": next_, "released": released, "waiting": waiting}


def test_the_release_goes_to_the_processes_with_a_timer_due_only() -> None:
    coordinator = _coordinator()
    coordinator.reports = {
        "/a/uav": _timing(20, 20),  # due at 20
        "/a/car": _timing(20, 50),  # next due at 50: nothing to release at 20
        "/a/car_ctrl": _timing(0, None, waiting=True),  # asleep since before time started
    }
    assert coordinator.due_now(20) == {"/a/uav", "/a/car_ctrl"}
    assert coordinator.due_now(50) == {"/a/uav", "/a/car", "/a/car_ctrl"}


def test_the_graph_settles_once_every_process_is_at_the_step_and_its_timers_ran() -> None:
    coordinator = _coordinator()
    coordinator.reports = {"/a/uav": _timing(10, 20), "/a/car": _timing(20, 50)}
    assert not coordinator.settled(20, released=False)  # /a/uav has not the step's clock
    assert coordinator.unsettled(20) == ["/a/uav is at 0.00 s"]
    coordinator.reports["/a/uav"] = _timing(20, 20)
    assert coordinator.settled(20, released=False)
    assert not coordinator.settled(20, released=True)  # its timer at 20 has not run
    coordinator.reports["/a/uav"] = _timing(20, 40, released=20)
    assert coordinator.settled(20, released=True)
    coordinator.apply("/a/uav", _report(sent={"/a/subject_pose>/a/car": 1}))
    assert not coordinator.settled(20, released=True)  # a message in flight
    assert coordinator.settled(20, released=True) == (coordinator.unsettled(20, True) == [])


def test_a_message_stamped_with_its_step_gives_its_stamp() -> None:
    module = _module()

    class Stamp:
        def to_nsec(self) -> int:
            return 1_230_000_000

    class Header:
        stamp = Stamp()

    class Pose:
        header = Header()

    assert module.stamp_of(Pose()) == 1_230_000_000
    assert module.stamp_of(object()) is None


def test_a_process_that_reads_the_board_need_not_be_at_the_step() -> None:
    coordinator = _coordinator()
    # it had no /clock at 20: its clock comes from the board when a message comes
    coordinator.reports = {"/a/uav": {**_timing(10, 20), "board": True}, "/a/car": _timing(20, 50)}
    assert coordinator.settled(20, released=False)
    assert not coordinator.settled(20, released=True)  # but its timer due at 20 must run
    coordinator.reports["/a/car"] = _timing(10, 50)  # no board: it needs the step's /clock
    assert coordinator.unsettled(20) == ["/a/car is at 0.00 s"]


def test_the_board_gives_the_last_time_written(tmp_path: Path) -> None:
    module = _module()
    path = str(tmp_path / "board")
    simulator = module.Board(path, create=True)
    node = module.Board(path)
    assert node.read() == 0
    for value in (20_000_000, 30_000_000, 12_340_000_000):
        simulator.write(value)
        assert node.read() == value
    simulator.close(unlink=True)
    node.close()
    assert not Path(path).exists()


def test_clock_goes_to_a_process_sent_to_since_the_last_due_step_but_not_at_this_one() -> None:
    coordinator = _coordinator()
    coordinator.state.sent = {"/vicon/car>/a/car": 5, "/vicon/uav>/a/uav": 5, "/x>/a/idle": 1}
    coordinator.at_due = {"/vicon/car>/a/car": 3, "/vicon/uav>/a/uav": 3, "/x>/a/idle": 1}
    coordinator.before = {"/vicon/car>/a/car": 4, "/vicon/uav>/a/uav": 5, "/x>/a/idle": 1}
    # /a/car has this step's pose (it reports), /a/uav only poses of steps nobody waited at
    assert coordinator.unreported() == {"/a/uav"}


def test_a_release_waits_for_the_simulators_messages_sent_before_it() -> None:
    process = _module().Process(None)
    # the release of 20 ms, after the simulator sent this process three poses
    process.pending = (20_000_000, {"/vicon/uav</vicon": 3})
    process.done = {"/vicon/uav</vicon": 2, "/a/other</a/car": 9}
    with process.cond:
        assert not process.take_release()
    assert process.released == 0  # its timer would miss the step's pose
    process.done["/vicon/uav</vicon"] = 3
    with process.cond:
        assert process.take_release()
    assert (process.released, process.pending) == (20_000_000, None)
