"""The slowed link (Table 5.1, s5) offline: what the monitor's responses can do for it, and
what the controller would need. No ROS: ``landing_core`` as ``offline_trial`` runs it.

    python bench/slowed_offline.py [--seeds 20] [--timeout 300]

``/a/car_pose`` goes out at 0.5 Hz for 5 s in every 10 s (``car.py``: a pose, then the next
2 s later). The monitor is idealised as the live one alarms on ``15 <= freq(/a/car_pose) <=
25`` (1 s window): from 0.3 s into each slow stretch until 0.75 s into the next fast one.
Its responses (columns):

* ``none``: no monitor;
* ``once``: the generated monitor's rule (actions once per alarm): the task state commanded
  when the alarm is raised, whatever the controller is doing (a landing under way is called
  off, and so is a touchdown: the controller takes an uncommanded task state in its
  shutdown state as a call-off too, the fragile platform's rescue), the stale poses relayed;
* ``block+once``: the same with the stale poses withheld, as the example's monitor does
  (``/a/car_pose`` is blocked, and every message of an alarmed episode is withheld until
  the frequency holds again, 0.75 s into the fast stretch);
* ``block+hold``: the stale poses withheld and every landing called off while the alarm
  lasts;
* ``frozen``: no frequency alarm; every landing called off once its platform pose is 0.5 s
  old (the waypoint frozen while landing, ``var(task_waypose.pose.position.x)`` at point
  ``b?1`` as a monitor learnt without ``freq(/a/car_pose)`` alarms live), the stale poses
  relayed, a landed UAV left alone (the point is the landing's);
* ``landing``: the frequency alarm above learnt at the landing's point (``freq(/a/car_pose)``
  at ``v?1``, condition 1: the controller is landing): every landing called off while the
  alarm lasts, the stale poses relayed, a landed UAV left alone (the controller's shutdown
  ends the landing, so no alarm there lifts it). Idealised: no warm-up (a conditional
  point's windows restart with each landing and are defined 1 s into it) and a timer while
  landing (a live monitor's conditional points have none: docs/checking.md).

With a monitor a shutdown over anything but the platform is called off too (the live
monitor's shutdown height, ``a?cmd_subject_ctrl_state.data==5``).

Controllers (rows), the example's (``as is``) and variants of it, each a change a real
controller could have:

* ``predicting``: moves the platform's last pose on by its estimated velocity while the
  pose is late (dead reckoning, up to 3 s);
* ``near integral``: its position loop integrates only within 0.3 m of the waypoint;
* ``reset``: its position loop resets its integral on a setpoint step (a waypoint more than
  10 cm from the one before: the platform moves 1.5 cm between two 20 Hz waypoints), so the
  integral of the chases after stale poses that jumped does not push the UAV past the fresh
  ones;
* ``heard``: decides to land only when a platform pose arrives (the 1.5 s over the platform
  judged on what it hears: a withheld pose starts no landing);
* ``disarm``: once its motors have been off for 2 s it is landed for good and takes no
  command to fly again (PX4's auto-disarm after landing, ``COM_DISARM_LAND``, 2 s); the last
  row disarms after 0.5 s.

A landing called off sends the platform on again (the controller's task 1), as live.

Printed: the trials that landed on the platform, of ``--seeds`` (seeds 0, 1, ...), with the
mean simulated time to land.
"""

from __future__ import annotations

import argparse
import math
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT / "examples" / "landing_system" / "nodes"))

import landing_core as core  # noqa: E402

MODES = ("none", "once", "block+once", "block+hold", "frozen", "landing")


def alarmed(t: float) -> bool:
    """Whether the idealised frequency alarm is on at ``t`` (see the module's docstring)."""
    phase = t % 10.0
    return phase >= 5.3 or phase < 0.75


class Variant(core.LandingController):
    """The example's controller with the variants of the module's docstring switched on."""

    predict: float = 0.0
    """Dead reckoning horizon (s): 0, none."""
    heard_only: bool = False
    disarm: float | None = None

    def __init__(self) -> None:
        super().__init__()
        self.heard = False

    def see_car(self, t: float, x: float, y: float, z: float, yaw: float | None = None) -> None:
        super().see_car(t, x, y, z, yaw)
        self.heard = True

    def step(
        self, t: float, state: int, uav: tuple[float, float, float], vz: float
    ) -> tuple[int, tuple[float, float, float] | None, int | None]:
        disarm = self.disarm
        if disarm is not None and self.commanded == core.SHUTDOWN and t - self.since >= disarm:
            state = core.SHUTDOWN  # disarmed: a command to fly is not taken
        last, landing_time = self.last_car, self.landing_time
        if last is not None and self.predict > 0.0 and t - last[0] > 0.1:
            age = min(t - last[0], self.predict)
            vx, vy = self.car_velocity
            self.last_car = (last[0], last[1] + vx * age, last[2] + vy * age, last[3])
        if self.heard_only and not self.heard:
            self.landing_time = math.inf  # nothing heard this cycle: no landing begins
        try:
            return super().step(t, state, uav, vz)
        finally:
            self.last_car, self.landing_time, self.heard = last, landing_time, False


class NearIntegral(core.Attitude):
    """Integrates the position error only within 0.3 m of the waypoint (no wind-up while
    it chases a platform it lost)."""

    def command(
        self,
        state: int,
        waypoint: tuple[float, float, float] | None,
        pose: tuple[float, float, float],
        velocity: tuple[float, float, float],
        t: float | None = None,
    ) -> core.Command:
        if waypoint is not None and math.hypot(waypoint[0] - pose[0], waypoint[1] - pose[1]) > 0.3:
            self.stamp = None
        return super().command(state, waypoint, pose, velocity, t)


class ResetIntegral(core.Attitude):
    """Resets its integral on a setpoint step: a waypoint more than :attr:`jump` m from the
    one before."""

    jump: float = 0.1

    def see_waypoint(self, t: float, x: float, y: float, z: float) -> None:
        last = self.last
        if last is not None and math.hypot(x - last[1], y - last[2]) > self.jump:
            self.integral = (0.0, 0.0)
        super().see_waypoint(t, x, y, z)


LOOPS: dict[str, type[core.Attitude]] = {
    "plain": core.Attitude,
    "near": NearIntegral,
    "reset": ResetIntegral,
}
"""The position loops of the rows: the example's, and its two ways not to wind up."""

CONTROLLERS: dict[str, tuple[dict[str, object], str]] = {
    "as is": ({}, "plain"),
    "reset": ({}, "reset"),
    "disarm": ({"disarm": 2.0}, "plain"),
    "heard": ({"heard_only": True}, "plain"),
    "heard+disarm": ({"heard_only": True, "disarm": 2.0}, "plain"),
    "predicting": ({"predict": 3.0}, "plain"),
    "predicting+near": ({"predict": 3.0}, "near"),
    "pred+near+heard+disarm": ({"predict": 3.0, "heard_only": True, "disarm": 2.0}, "near"),
    "pred+near+heard+disarm0.5": ({"predict": 3.0, "heard_only": True, "disarm": 0.5}, "near"),
}


def controller(name: str) -> tuple[Variant, core.Attitude]:
    """A fresh controller and position loop of the row ``name``."""
    settings, loop = CONTROLLERS[name]
    control = Variant()
    for key, value in settings.items():
        setattr(control, key, value)
    return control, LOOPS[loop]()


def trial(seed: int, mode: str, name: str, timeout: float) -> tuple[bool, float]:
    """One slowed trial (``offline_trial``'s loop with a monitor's response): whether it
    landed on the platform, and when it ended."""
    world = core.World("slowed", seed, timeout=timeout)
    control, loop = controller(name)
    state, waypoint, step, was_alarmed, sent = core.STARTUP, None, 0, False, -9.0
    while True:
        step += 1
        uav = world.uav
        if step % 5 == 0:
            platform = world.platform
            slow = world.t % 10.0 >= 5.0
            alarm = mode not in ("none", "frozen", "landing") and alarmed(world.t)
            if not slow or world.t - sent >= 2.0 - 1e-9:
                sent = world.t
                if not (alarm and mode.startswith("block")):
                    control.see_car(
                        world.t, platform.x, platform.y, core.PLATFORM_TOP, platform.heading
                    )
            told = state
            raised = alarm and not was_alarmed
            was_alarmed = alarm
            held = alarm and mode.endswith("hold") and state in (core.LAND, core.SHUTDOWN)
            last = control.last_car
            frozen = mode == "frozen" and state == core.LAND and last is not None
            if frozen and last is not None and world.t - last[0] >= 0.5:
                told = core.TASK  # the landing's waypoint froze: the landing called off
            elif mode == "landing" and state == core.LAND and alarmed(world.t):
                told = core.TASK  # the alarm at the landing's point calls it off
            elif raised or held:
                told = core.TASK  # the monitor commands the task state
            elif mode != "none" and state == core.SHUTDOWN and uav.resting == "floor":
                told = core.TASK  # a shutdown over the floor (the shutdown height)
            state, waypoint, task = control.step(world.t, told, (uav.x, uav.y, uav.z), uav.vz)
            if waypoint is not None:
                loop.see_waypoint(world.t, *waypoint)
            if task is not None:
                world.drive(task)  # a called-off landing sends the platform on again
        if step % 2 == 0:
            world.command = loop.command(
                state, waypoint, (uav.x, uav.y, uav.z), (uav.vx, uav.vy, uav.vz), world.t
            )
        if world.step() is not None:
            return world.referee.success, world.t


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--seeds", type=int, default=20)
    parser.add_argument(
        "--timeout", type=float, default=300.0, help="simulated s per trial (as bench/casestudy.py)"
    )
    parser.add_argument("--controllers", default=",".join(CONTROLLERS), help="rows to run")
    args = parser.parse_args()
    names = [n for n in args.controllers.split(",") if n]
    unknown = [n for n in names if n not in CONTROLLERS]
    if unknown:
        sys.exit(
            f"slowed_offline: unknown controller {unknown[0]!r}; one of {', '.join(CONTROLLERS)}"
        )
    seeds = f"seeds 0-{args.seeds - 1}, {args.timeout:g} s"
    print(f"slowed link offline: landed of {args.seeds} ({seeds}; mean s to land)")
    print(f"  {'controller':24s}" + "".join(f"{mode:>16s}" for mode in MODES))
    for name in names:
        cells = []
        for mode in MODES:
            runs = [trial(s, mode, name, args.timeout) for s in range(args.seeds)]
            times = [t for ok, t in runs if ok]
            mean = f"({sum(times) / len(times):.0f})" if times else "(-)"
            cells.append(f"{len(times):>10d} {mean:>5s}")
        print(f"  {name:24s}" + "".join(cells), flush=True)


if __name__ == "__main__":
    main()
