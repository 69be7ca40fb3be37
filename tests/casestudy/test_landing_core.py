"""The landing system's physics, controller and referee, without ROS (offline trials)."""

from __future__ import annotations

import math
from typing import Any

import pytest

from tests.casestudy.core import landing_core

L: Any = landing_core


def test_a_normal_run_takes_off_pursues_and_lands_on_the_platform() -> None:
    referee = L.offline_trial("normal", 0)
    assert referee.outcome == "landed" and referee.success
    assert referee.detail == "motors off on the platform for 5 s"


@pytest.mark.parametrize("seed", range(4))
def test_an_occupied_platform_is_landed_on_without_a_monitor(seed: int) -> None:
    referee = L.offline_trial("occupied", seed)
    assert not referee.success  # success is not landing
    assert referee.outcome in ("landed_elsewhere", "crashed")


def test_a_false_airport_lands_the_uav_on_the_floor() -> None:
    referee = L.offline_trial("false_airport", 0)
    assert referee.outcome == "landed_elsewhere" and "floor" in referee.detail
    assert not referee.success


def test_a_fragile_platform_tips_when_landed_off_its_safe_quadrant() -> None:
    outcomes = [L.offline_trial("fragile", seed) for seed in range(6)]
    assert any(r.outcome == "crashed" and "tipping platform" in r.detail for r in outcomes)
    assert any(r.outcome == "landed" for r in outcomes)  # its safe quadrant holds


def test_a_fragile_platforms_safe_quadrant_is_one_of_four_drawn_by_the_seed() -> None:
    safe = [L.World("fragile", seed).platform.safe for seed in range(20)]
    assert set(safe) == {(1, 1), (1, -1), (-1, 1), (-1, -1)}
    # drawn last: the platform and the UAV start where the normal scenario's do
    fragile, normal = L.World("fragile", 3), L.World("normal", 3)
    assert (fragile.platform.x, fragile.uav.x, fragile.wind.phase) == (
        normal.platform.x,
        normal.uav.x,
        normal.wind.phase,
    )
    world = L.World("fragile", 0)
    platform = world.platform
    platform.heading, platform.moving = 0.0, False
    for su in (1, -1):
        for sv in (1, -1):
            u = world.uav
            u.x, u.y = platform.x + su * 0.1, platform.y + sv * 0.1
            u.resting, platform.tipping = "platform", None
            world._load_fragile_platform()
            # a quarter of the platform holds the UAV, the other three tip
            assert (platform.tipping is None) == ((su, sv) == platform.safe)


def test_a_fragile_platform_is_landed_on_safely_in_about_a_quarter_of_the_runs() -> None:
    landed = sum(L.offline_trial("fragile", seed).outcome == "landed" for seed in range(24))
    assert 2 <= landed <= 10  # the thesis: 20 % without a monitor


def test_a_fragile_platform_sags_slowly_and_rights_itself_once_the_uav_lifts_off() -> None:
    world = L.World("fragile", 0)
    world.platform.moving = False
    u = world.uav
    u.x, u.y = world.platform.x, world.platform.y  # its centre: outside the open quadrant
    u.z, u.resting = L.PLATFORM_TOP + L.UAV_REST, "platform"
    world.command = L.Command(thrust=L.GRAVITY * 0.5, motors=True)  # pressing on it
    for _ in range(40):  # 0.4 s: tipping, not yet steep enough to slide off
        world.step()
    assert world.platform.tipping is not None and world.onset is not None
    tilt = max(abs(world.platform.roll), abs(world.platform.pitch))
    assert 0.05 < tilt < L.SLIDE_TILT and u.broken is None
    world.command = L.Command(thrust=L.GRAVITY * 1.5, motors=True)  # lifts off
    for _ in range(200):
        world.step()
    assert u.resting is None and u.broken is None
    assert world.platform.tipping is None
    assert world.platform.roll == 0.0 and world.platform.pitch == 0.0


def test_the_platform_turns_in_place_at_the_walls() -> None:
    import itertools
    import random

    # its braking distance from the wall's limit, driving at full speed towards it
    brake = L.PLATFORM_SPEED**2 / (2 * L.PLATFORM_ACCEL)
    platform = L.Platform(random.Random(1), x=L.PLATFORM_LIMIT - brake - 0.002, y=0.0)
    platform.until_turn = 1e9
    platform.step(L.DT)
    assert platform.target is not None  # at the wall: it turns, it does not drive on
    assert abs(L.wrap(platform.target - math.atan2(0.0, -platform.x))) <= 1.0 + 1e-9
    speeds, rates = [], []
    for _ in range(60):  # it brakes to a standstill before it turns: no instant stop
        platform.step(L.DT)
        speeds.append(platform.speed)
        rates.append(platform.yaw_rate)
    assert speeds[0] > 0.9 * L.PLATFORM_SPEED and speeds[-1] == 0.0
    assert all(r == 0.0 for s, r in zip(speeds, rates, strict=True) if s > 0.0)
    spin = L.PLATFORM_YAW_ACCEL * L.DT + 1e-9
    assert all(abs(b - a) <= spin for a, b in itertools.pairwise(rates))
    x = platform.x
    for _ in range(400):
        platform.step(L.DT)
    assert abs(platform.x) <= L.PLATFORM_LIMIT and platform.x < x


def test_touching_down_fast_or_sliding_is_a_crash() -> None:
    import random

    platform = L.Platform(random.Random(0), x=3.0, y=3.0, present=False)
    fast = L.Uav(x=0.0, y=0.0, z=0.3, vz=-2.0, resting=None)
    fast.step(L.DT, L.Command(), (0.0, 0.0), platform, False)
    for _ in range(50):
        fast.step(L.DT, L.Command(), (0.0, 0.0), platform, False)
    assert fast.broken is not None and "crashed onto the floor" in fast.broken
    sliding = L.Uav(x=0.0, y=0.0, z=L.UAV_REST + 0.001, vx=0.6, vz=-0.1, resting=None)
    sliding.step(L.DT, L.Command(), (0.0, 0.0), platform, False)
    assert sliding.broken is not None and "sliding" in sliding.broken


def test_the_referee_scores_avoid_landing_scenarios_by_not_landing() -> None:
    referee = L.Referee("occupied", timeout=10.0)
    referee.outcome = "timeout"
    assert referee.success
    referee.outcome = "landed"
    assert not referee.success


def test_an_unknown_scenario_is_refused() -> None:
    with pytest.raises(ValueError, match="unknown scenario 'storm'"):
        L.World("storm", 0)


def _onset_after(scenario: str, seed: int, seconds: float) -> tuple[Any, float | None]:
    """A world stepped ``seconds`` with the motors off; it and the first time the platform
    was in the room's upper half (None: never)."""
    world = L.World(scenario, seed)
    upper = None
    while world.t < seconds:
        world.step()
        if upper is None and world.platform.y > 0.0:
            upper = world.t
    return world, upper


def test_a_fault_has_its_onset_when_it_first_acts() -> None:
    assert _onset_after("normal", 0, 8.0)[0].onset is None
    assert _onset_after("false_airport", 0, 1.0)[0].onset == pytest.approx(L.DT)
    assert _onset_after("slowed", 0, 8.0)[0].onset == pytest.approx(5.0, abs=L.DT)
    grounded = ("wind", "occupied", "fragile")  # no wind, object or tipping felt on the floor
    assert all(_onset_after(name, 0, 8.0)[0].onset is None for name in grounded)
    seed = next(s for s in range(50) if L.World("stealing", s).platform.y < -0.5)
    world, upper = _onset_after("stealing", seed, 60.0)
    assert upper is not None and world.onset == pytest.approx(upper)  # the thief's first lure


def test_the_blower_sweeps_gusts_of_8_to_38_kmh_over_calm_spells() -> None:
    import random

    wind = L.Wind(random.Random(0), enabled=True)
    speeds = []
    for _ in range(int(120 / L.DT)):  # two minutes at the room's centre
        wind.step(L.DT)
        speeds.append(math.hypot(*wind.at(0.0, 0.0)))
    assert max(speeds) <= 10.5 + 1e-9  # 38 km/h
    assert sum(s >= 2.2 for s in speeds) / len(speeds) > 0.05  # gusts of 8 km/h and more
    calm = [s < 0.3 for s in speeds]  # under 1 km/h: the jet points elsewhere
    assert 0.3 < sum(calm) / len(calm) < 0.9
    longest = run = 0
    for still in calm:
        run = run + 1 if still else 0
        longest = max(longest, run)
    assert longest * L.DT >= 5.0  # long enough to land in: 1.5 s over the platform, 2 s down
    assert L.Wind(random.Random(0)).at(0.0, 0.0) == (0.0, 0.0)  # no wind but in its scenario


def _landing(height: float) -> tuple[Any, float]:
    """A controller landing on a platform at the origin (heading 0, seen 20 times a second
    for 1 s), the UAV ``height`` over its markers; and the time it is at."""
    control = L.LandingController()
    for k in range(21):
        control.see_car(k * 0.05, 0.0, 0.0, L.PLATFORM_TOP, 0.0)
    control.commanded, control.since, control.land_z = L.LAND, 1.0, L.PLATFORM_TOP + height
    return control, 1.0


def test_a_landing_waits_over_the_platform_while_it_turns_in_place() -> None:
    control, t = _landing(0.3)
    control.see_car(t + 0.05, 0.0, 0.0, L.PLATFORM_TOP, 0.2)  # 4 rad/s: it turns
    state, waypoint, _ = control.step(t + 0.05, L.LAND, (0.0, 0.0, L.PLATFORM_TOP + 0.2), -0.3)
    assert state == L.LAND and waypoint is not None
    assert waypoint[2] == pytest.approx(L.PLATFORM_TOP + control.hold)  # back up, waiting
    for k in range(2, 50):  # the turn is over: after settling it descends again
        control.see_car(t + 0.05 * k, 0.0, 0.0, L.PLATFORM_TOP, 0.2)
        _, waypoint, _ = control.step(t + 0.05 * k, L.LAND, (0.0, 0.0, 0.5), -0.3)
    assert waypoint is not None and waypoint[2] < L.PLATFORM_TOP + control.hold - 0.2


def test_a_landing_that_touched_down_goes_on_when_the_platform_turns() -> None:
    control, t = _landing(0.0)
    control.see_car(t + 0.05, 0.0, 0.0, L.PLATFORM_TOP, 0.2)
    touched = (0.0, 0.0, L.PLATFORM_TOP + L.UAV_REST)
    _, waypoint, _ = control.step(t + 0.05, L.LAND, touched, 0.0)
    assert waypoint is not None and waypoint[2] < L.PLATFORM_TOP  # no climbing off it


def test_the_position_loop_never_pushes_up_towards_a_landing_target_below() -> None:
    loop = L.Attitude()
    pose, rising = (0.0, 0.0, 0.4), (0.0, 0.0, -0.4)  # descending fast onto a target below
    braking = loop.command(L.TASK, (0.0, 0.0, 0.3), pose, rising)
    assert braking.thrust > L.GRAVITY  # pursuing, it brakes the descent
    landing = loop.command(L.LAND, (0.0, 0.0, 0.3), pose, rising)
    assert landing.thrust <= L.GRAVITY  # landing, no bounce off the surface


def test_normal_runs_land_offline() -> None:
    outcomes = [L.offline_trial("normal", seed).outcome for seed in range(20)]
    assert outcomes == ["landed"] * 20


def test_the_top_of_a_climb_after_waiting_is_no_touchdown() -> None:
    control, t = _landing(0.3)
    control.see_car(t + 0.05, 0.0, 0.0, L.PLATFORM_TOP, 0.2)  # it turns: wait, climbing
    control.step(t + 0.05, L.LAND, (0.0, 0.0, L.PLATFORM_TOP + 0.2), -0.3)
    for k in range(2, 40):  # the turn is over; the UAV hangs at the top of its climb
        control.see_car(t + 0.05 * k, 0.0, 0.0, L.PLATFORM_TOP, 0.2)
        state, _, _ = control.step(t + 0.05 * k, L.LAND, (0.0, 0.0, L.PLATFORM_TOP + 0.2), 0.0)
        assert state == L.LAND  # not switched off in mid-air
    for k in range(40, 60):  # it descends and stops on the platform: that is a touchdown
        control.see_car(t + 0.05 * k, 0.0, 0.0, L.PLATFORM_TOP, 0.2)
        z, vz = (L.PLATFORM_TOP + L.UAV_REST, 0.0) if k >= 45 else (L.PLATFORM_TOP + 0.1, -0.3)
        state, _, _ = control.step(t + 0.05 * k, L.LAND, (0.0, 0.0, z), vz)
    assert state == L.SHUTDOWN


def test_a_landing_waits_over_the_platform_while_it_brakes() -> None:
    control = L.LandingController()
    for k in range(21):  # driving along x at 0.3 m/s
        control.see_car(k * 0.05, 0.3 * k * 0.05, 0.0, L.PLATFORM_TOP, 0.0)
    control.commanded, control.since, control.land_z = L.LAND, 1.0, L.PLATFORM_TOP + 0.3
    x, speed, braked = 0.3, 0.3, None
    for k in range(21, 35):  # it brakes at 0.5 m/s^2
        t = k * 0.05
        speed = max(0.0, speed - 0.5 * 0.05)
        x += speed * 0.05
        control.see_car(t, x, 0.0, L.PLATFORM_TOP, 0.0)
        _, waypoint, _ = control.step(t, L.LAND, (x, 0.0, L.PLATFORM_TOP + 0.2), -0.3)
        assert waypoint is not None
        if braked is None and waypoint[2] == pytest.approx(L.PLATFORM_TOP + control.hold):
            braked = t - 1.05
    assert braked is not None and braked <= 0.25  # seen braking within 0.25 s, waiting


def test_positions_that_jump_are_no_braking() -> None:
    control = L.LandingController()
    for k in range(30):  # a second source of positions 2 m away, every other pose
        control.see_car(k * 0.05, 0.0, 2.0 * (k % 2), L.PLATFORM_TOP, 0.0)
    assert control.turning_until < 0.0


def test_a_landing_begins_only_at_the_pursuit_height() -> None:
    control = L.LandingController()
    for k in range(60):
        control.see_car(k * 0.05, 0.0, 0.0, L.PLATFORM_TOP, 0.0)
    control.commanded, control.since = L.TASK, 0.0
    climbing = (0.0, 0.0, L.PLATFORM_TOP + 0.3)  # over its centre, climbing after a call-off
    for k in range(40):
        state, _, _ = control.step(k * 0.05, L.TASK, climbing, 0.3)
    assert state == L.TASK  # 2 s over the centre, but below the pursuit height
    level = (0.0, 0.0, L.PLATFORM_TOP + control.approach)
    for k in range(40, 80):
        state, _, task = control.step(k * 0.05, L.TASK, level, 0.0)
        if state == L.LAND:
            break
    assert state == L.LAND and task == L.TASK_LAND and k * 0.05 >= 2.0 + 1.5 - 1e-9


def test_a_called_off_landing_sends_the_stopped_platform_on_and_is_counted() -> None:
    world = L.World("normal", 0)
    control, t = _landing(0.0)
    world.drive(L.TASK_LAND)
    touched = (0.0, 0.0, L.PLATFORM_TOP + L.UAV_REST)
    control.descended = True
    for k in range(1, 20):  # touched down: motors off, the platform stopped
        control.see_car(t + 0.05 * k, 0.0, 0.0, L.PLATFORM_TOP, 0.0)
        state, _, task = control.step(t + 0.05 * k, L.LAND, touched, 0.0)
        if task is not None:
            world.drive(task)
        if state == L.SHUTDOWN:
            break
    assert state == L.SHUTDOWN and not world.platform.moving
    # the monitor commands the task state: the landing is called off; the UAV goes around
    # (straight up) and the platform drives on once it is back at its pursuit height
    state, waypoint, task = control.step(t + 1.0, L.TASK, touched, 0.0)
    assert state == L.TASK and task is None and waypoint is not None
    up = (0.0, 0.0, L.PLATFORM_TOP + control.approach)
    state, waypoint, task = control.step(t + 2.0, L.TASK, up, 0.0)
    assert state == L.TASK and task == L.TASK_TRACK and waypoint is not None
    world.drive(task)
    assert world.platform.moving and world.referee.reinitiated == 1
    world.drive(L.TASK_WANDER)  # the monitor's safe task: the platform wanders, no landing
    assert world.platform.moving and world.referee.reinitiated == 1


def test_a_landing_called_off_on_a_surface_goes_around_straight_up() -> None:
    # the UAV stands on the occupied platform's object off its centre, motors off, the
    # platform stopped; the monitor commands the task state (a called-off landing)
    world = L.World("occupied", 0)
    platform, uav = world.platform, world.uav
    platform.moving, platform.speed, platform.heading = False, 0.0, 0.0
    uav.x, uav.y = platform.x + 0.12, platform.y - 0.08
    uav.z, uav.resting = L.PLATFORM_TOP + L.OBJECT_HEIGHT + L.UAV_REST, "object"
    control, loop = L.LandingController(), L.Attitude()
    for k in range(21):
        control.see_car(k * 0.05, platform.x, platform.y, L.PLATFORM_TOP, platform.heading)
    control.commanded, control.since, control.home = L.SHUTDOWN, 0.5, (0.0, 0.0)
    start, world.t = (uav.x, uav.y), 1.0
    state, waypoint, step, tracked = L.SHUTDOWN, None, 0, None
    top = L.PLATFORM_TOP + control.approach
    clear = uav.z + 0.2  # its legs well off the object
    while world.t < 6.0:
        step += 1
        if step % 5 == 0:
            control.see_car(world.t, platform.x, platform.y, L.PLATFORM_TOP, platform.heading)
            state, waypoint, task = control.step(world.t, L.TASK, (uav.x, uav.y, uav.z), uav.vz)
            assert waypoint is not None
            loop.see_waypoint(world.t, *waypoint)
            if task is not None:
                assert task == L.TASK_TRACK and tracked is None
                tracked = (world.t, uav.z)
                world.drive(task)
        if step % 2 == 0:
            world.command = loop.command(
                state, waypoint, (uav.x, uav.y, uav.z), (uav.vx, uav.vy, uav.vz), world.t
            )
        world.step()
        assert uav.broken is None
        if uav.z < clear:  # going around: up where it stood, over a platform that waits
            assert not platform.moving
            # (the rotors' outwash pushes it a few centimetres while it is near the surface)
            assert math.hypot(uav.x - start[0], uav.y - start[1]) < 0.08
    # the platform was told to drive on once the UAV was back at its pursuit height, and the
    # UAV pursues it
    assert tracked is not None and tracked[0] < 3.0 and platform.moving
    assert tracked[1] >= top - control.landing_radius
    assert math.hypot(uav.x - platform.x, uav.y - platform.y) < 0.3
    assert abs(uav.z - top) < 0.1


def test_a_landing_called_off_high_over_the_platform_pursues_at_once() -> None:
    control, t = _landing(0.45)
    high = (0.0, 0.0, L.PLATFORM_TOP + 0.45)
    control.step(t + 0.05, L.LAND, high, -0.3)
    state, waypoint, task = control.step(t + 0.1, L.TASK, high, -0.3)
    assert state == L.TASK and task == L.TASK_TRACK
    assert waypoint == pytest.approx((0.0, 0.0, L.PLATFORM_TOP + control.approach))


def test_a_waypoint_that_stopped_coming_is_held_at_rest() -> None:
    # the waypoint moved along x at the platform's speed until t = 1 s (20 a second)
    loop = L.Attitude()
    for k in range(21):
        loop.see_waypoint(k * 0.05, L.PLATFORM_SPEED * k * 0.05, 0.0, 1.0)
    at_rest = (0.0, 0.0, 0.0)
    between = loop.command(L.TASK, (0.3, 0.0, 1.0), (0.3, 0.0, 1.0), at_rest, 1.04)
    assert between.pitch > 0.04  # between two waypoints its speed is fed forward
    # none for 0.6 s (the controller sends none, or a monitor withholds them): pid_ctrl holds
    # the UAV where it is, and the held point stands still; the platform's last speed fed
    # forward would fly the UAV on at it (over the object it stood on, in the occupied
    # scenario, catching its legs on it)
    held = loop.command(L.TASK, (0.3, 0.0, 1.0), (0.3, 0.0, 1.0), at_rest, 1.6)
    assert held.pitch == pytest.approx(0.0) and held.roll == pytest.approx(0.0)
