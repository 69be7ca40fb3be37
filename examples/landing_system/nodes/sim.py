#!/usr/bin/python3
"""``/vicon``: the world of the landing system and its motion capture, on simulated time.

Steps :class:`landing_core.World` at 100 Hz of simulated time and publishes ``/clock``, the
platform's pose on ``/vicon/car`` and the UAV's on ``/vicon/uav``
(``geometry_msgs/TransformStamped``, 100 Hz, 1 mm of noise; no ``/vicon/car`` in the
false-airport scenario: there is no vehicle). It takes the UAV's command from
``/a/cmd_attitude`` (``geometry_msgs/Twist``: angular.x roll, angular.y pitch, linear.z
thrust in m/s^2, linear.x > 0.5 motors on) and the platform's drive from ``/a/car_drive``
(``std_msgs/UInt8``, a task id: 3 stops it, 0 and 1 send it on again). When the run is
over (Table 5.1's criteria) it writes the outcome as JSON to ``~outcome`` (a file;
``~trace``, a file too, gets each step's command and UAV state), publishes it on
``/landing/outcome`` (latched) and exits, which
ends the launch (the node is ``required``).

**Lockstep**: when the graph's processes run with ``rospy_lockstep`` (``LANDING_LOCKSTEP=1``
and ``../lockstep`` on ``PYTHONPATH``), time starts once every node of the launch is ready
and connected, and each step waits until the whole graph has reacted to the last one (every
message delivered, every callback and timer done; :class:`rospy_lockstep.Coordinator`).
The run is then the same whatever the machine's load; ``~speed`` only caps how much faster
than real time it runs (0: as fast as the graph goes). Without lockstep, time runs
``~speed`` times faster than real time whether the nodes keep up or not.
"""

from __future__ import annotations

import json
import random
import time

import landing_core as core

try:
    import rospy_lockstep
except ImportError:  # not on the path: no lockstep
    rospy_lockstep = None
import landing_node as node
import rospy  # type: ignore[import-not-found]
from geometry_msgs.msg import TransformStamped, Twist  # type: ignore[import-not-found]
from rosgraph_msgs.msg import Clock  # type: ignore[import-not-found]
from std_msgs.msg import String, UInt8  # type: ignore[import-not-found]

NOISE = 0.001


def main() -> None:
    node.init_node("vicon")
    name, trial = node.scenario(), node.seed()
    speed = float(rospy.get_param("~speed", 4.0))
    outcome_file = str(rospy.get_param("~outcome", ""))
    world = core.World(name, trial, timeout=float(rospy.get_param("/landing/timeout", 120.0)))
    noise = random.Random(trial + 1_000_003)
    clock = rospy.Publisher("/clock", Clock, queue_size=10)
    car = rospy.Publisher("/vicon/car", TransformStamped, queue_size=10)
    uav = rospy.Publisher("/vicon/uav", TransformStamped, queue_size=10)
    result = rospy.Publisher("/landing/outcome", String, queue_size=1, latch=True)

    def on_command(msg: Twist) -> None:
        world.command = core.Command(msg.angular.x, msg.angular.y, msg.linear.z, msg.linear.x > 0.5)

    def on_drive(msg: UInt8) -> None:
        world.drive(msg.data)

    rospy.Subscriber("/a/cmd_attitude", Twist, on_command, queue_size=1)
    rospy.Subscriber("/a/car_drive", UInt8, on_drive, queue_size=10)
    lockstep = rospy_lockstep.process() if rospy_lockstep is not None else None
    coordinator = rospy_lockstep.Coordinator(lockstep, clock) if lockstep is not None else None
    if coordinator is not None:
        coordinator.start()
    else:
        time.sleep(1.0)  # let the other nodes subscribe to /clock before time starts
    start = time.monotonic()
    step = 0
    outcome = None
    trace_file = str(rospy.get_param("~trace", ""))
    trace = open(trace_file, "w", encoding="utf-8") if trace_file else None  # noqa: SIM115
    while not rospy.is_shutdown() and outcome is None:
        step += 1
        if trace is not None:  # the command the step applies, the UAV it moves
            trace.write(f"{world.t:.2f} {world.command} {world.uav}\n")
        outcome = world.step()
        stamp = rospy.Time.from_sec(world.t)
        # in lockstep, only the steps where a timer of the graph is due count (in between
        # no node runs but to take in the motion capture, which the next due step waits
        # for), and /clock goes only where it is needed (the coordinator publishes it)
        due = coordinator is not None and coordinator.tick(stamp)
        if coordinator is None:
            clock.publish(Clock(clock=stamp))
        p, u = world.platform, world.uav
        if p.present:
            car.publish(
                node.transform(
                    "world",
                    "car",
                    stamp,
                    (
                        p.x + noise.gauss(0, NOISE),
                        p.y + noise.gauss(0, NOISE),
                        core.PLATFORM_TOP,
                        p.roll,
                        p.pitch,
                        p.heading,
                    ),
                )
            )
        uav.publish(
            node.transform(
                "world",
                "uav",
                stamp,
                (
                    u.x + noise.gauss(0, NOISE),
                    u.y + noise.gauss(0, NOISE),
                    u.z + noise.gauss(0, NOISE),
                    u.roll,
                    u.pitch,
                    0.0,
                ),
            )
        )
        if due:
            coordinator.step(stamp)
        ahead = start + step * core.DT / speed - time.monotonic() if speed > 0 else 0.0
        if ahead > 0:
            time.sleep(ahead)
    if trace is not None:
        trace.close()
    referee = world.referee
    report = {
        "scenario": name,
        "seed": trial,
        "outcome": referee.outcome,
        "success": referee.success,
        "detail": referee.detail,
        "time": round(world.t, 2),
        "reinitiated": referee.reinitiated,
        "onset": None if world.onset is None else round(world.onset, 2),
        "wall": round(time.monotonic() - start, 2),
        "lockstep": coordinator is not None,
        "stalls": coordinator.stalls if coordinator is not None else 0,
    }
    text = json.dumps(report)
    result.publish(String(text))
    if outcome_file:
        with open(outcome_file, "w", encoding="utf-8") as out:
            out.write(text + "\n")
    rospy.loginfo("landing outcome: %s", text)
    time.sleep(0.5)


if __name__ == "__main__":
    main()
