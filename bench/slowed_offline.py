"""The slowed link (Table 5.1, s5) offline: what a monitor's response can do for it, and what
the controller would need. No ROS: ``landing_core`` as ``offline_trial`` runs it.

    python bench/slowed_offline.py [--seeds 20] [--timeout 120]

``/a/car_pose`` goes out at 0.5 Hz for 5 s in every 10 s. A monitor is idealised as the live
one alarms on ``15 <= freq(/a/car_pose) <= 25`` (1 s window): from 0.3 s into each slow
stretch until 0.75 s into the next fast one. Its responses (columns):

* ``none``: no monitor;
* ``once``: the task state commanded when the alarm is raised (a landing under way is
  called off), the stale poses relayed: the generated monitor's rule (actions once per alarm);
* ``hold``: every landing begun while the alarm lasts is called off, the stale poses relayed;
* ``block+hold``: the same, the stale poses withheld (the controller hears none).

Controllers (rows): the example's (``as is``); one that moves the platform's last pose on by
its estimated velocity while the pose is late (``predicting``: up to 3 s); one whose position
loop integrates only within 0.3 m of its waypoint (``near integral``); both. Printed: the
trials that landed on the platform, of ``--seeds`` (seeds 0, 1, ...).
"""

from __future__ import annotations

import argparse
import math
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT / "examples" / "landing_system" / "nodes"))

import landing_core as core  # noqa: E402

MODES = ("none", "once", "hold", "block+hold")


def alarmed(t: float) -> bool:
    """Whether the idealised frequency alarm is on at ``t`` (see the module's docstring)."""
    phase = t % 10.0
    return phase >= 5.3 or phase < 0.75


class Predicting(core.LandingController):
    """Moves the platform's last pose on by its estimated velocity while it is late."""

    def step(
        self, t: float, state: int, uav: tuple[float, float, float], vz: float
    ) -> tuple[int, tuple[float, float, float] | None, int | None]:
        heard = self.last_car
        if heard is not None and t - heard[0] > 0.1:
            age = min(t - heard[0], 3.0)
            vx, vy = self.car_velocity
            self.last_car = (heard[0], heard[1] + vx * age, heard[2] + vy * age, heard[3])
        try:
            return super().step(t, state, uav, vz)
        finally:
            self.last_car = heard


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


CONTROLLERS = {
    "as is": (core.LandingController, core.Attitude),
    "predicting": (Predicting, core.Attitude),
    "near integral": (core.LandingController, NearIntegral),
    "both": (Predicting, NearIntegral),
}


def trial(seed: int, mode: str, controller: str, timeout: float) -> bool:
    """One slowed trial (``offline_trial``'s loop with a monitor's response); whether it
    landed on the platform."""
    world = core.World("slowed", seed, timeout=timeout)
    control_class, loop_class = CONTROLLERS[controller]
    control, loop = control_class(), loop_class()
    state, waypoint, step, was_alarmed = core.STARTUP, None, 0, False
    while True:
        step += 1
        uav, platform = world.uav, world.platform
        if step % 5 == 0:
            slow = world.t % 10.0 >= 5.0
            late = control.last_car is None or world.t - control.last_car[0] >= 2.0
            alarm = mode != "none" and alarmed(world.t)
            if (not slow or late) and not (alarm and mode == "block+hold"):
                control.see_car(
                    world.t, platform.x, platform.y, core.PLATFORM_TOP, platform.heading
                )
            told = state
            if alarm and state == core.LAND and (mode != "once" or not was_alarmed):
                told = core.TASK  # the monitor commands the task state
            was_alarmed = alarm
            state, waypoint, task = control.step(world.t, told, (uav.x, uav.y, uav.z), uav.vz)
            if waypoint is not None:
                loop.see_waypoint(world.t, *waypoint)
            if task == core.TASK_STOP:
                world.stop_platform()
        if step % 2 == 0:
            world.command = loop.command(
                state, waypoint, (uav.x, uav.y, uav.z), (uav.vx, uav.vy, uav.vz), world.t
            )
        if world.step() is not None:
            return world.referee.success


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--seeds", type=int, default=20)
    parser.add_argument("--timeout", type=float, default=120.0)
    args = parser.parse_args()
    seeds = f"seeds 0-{args.seeds - 1}, {args.timeout:g} s"
    print(f"slowed link offline: landed of {args.seeds} ({seeds})")
    print(f"  {'controller':14s}" + "".join(f"{mode:>12s}" for mode in MODES))
    for controller in CONTROLLERS:
        cells = []
        for mode in MODES:
            landed = sum(trial(s, mode, controller, args.timeout) for s in range(args.seeds))
            cells.append(f"{landed:>12d}")
        print(f"  {controller:14s}" + "".join(cells), flush=True)


if __name__ == "__main__":
    main()
