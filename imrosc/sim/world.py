"""The physics and the controller of the landing system (thesis section 5.1.1).

A UAV (an AscTec Hummingbird) takes off, hovers, pursues an iRobot Create that carries a
50 cm x 50 cm platform through an 8 m x 8 m Vicon room, and lands on it; the controller is the
state machine of the thesis (startup, launch, hover, task, land, shutdown, numbered 0 to 5 as
``examples/uav_landing.xml`` assumes). Everything is computed on one 100 Hz time grid (the
Vicon rate) from a seeded numpy generator:

* the platform's "vacuum" motion is a list of segments (straight at 0.3 m/s, turning in place
  at a wall towards the room, now and then a spontaneous turn) evaluated on the whole grid at
  once;
* the UAV follows the controller's waypoint through a first-order velocity loop; this is the
  one sequential part (the waypoint depends on where the UAV is), a loop over plain floats that
  stops at touchdown, after which the UAV rides the platform and is filled in vectorised;
* the controller (``/a/car_ctrl``) runs at 20 Hz on the measured poses: it commands launch
  after 1 s, hover at the hover height, task after 2 s of hover, land once the UAV has been
  within 15 cm of the platform centre for 1.5 s (descending only while it stays within), and
  shutdown at touchdown, when it also tells the platform to stop. A successful run thus ends
  with the UAV on the platform with its motors off.

The result, :class:`World`, holds true states and the controller's cycles; the recording
(``imrosc.sim.recording``) adds sensor noise and message timing.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

__all__ = [
    "DT",
    "HOVER_Z",
    "LANDING_RADIUS",
    "LANDING_TIME",
    "PLATFORM_TOP",
    "ROOM_HALF",
    "STATES",
    "UAV_REST",
    "Call",
    "World",
    "simulate_world",
]

FloatArray = NDArray[np.float64]

DT = 0.01
"""The physics step and the Vicon period (s)."""
CTRL_PERIOD_STEPS = 5
"""The controller runs every 5 steps: 20 Hz."""
CTRL_PHASE_STEPS = 2
"""... 20 ms after the Vicon sample that /a/car_pose forwards."""

STATES = ("startup", "launch", "hover", "task", "land", "shutdown")
STARTUP, LAUNCH, HOVER, TASK, LAND, SHUTDOWN = range(6)

ROOM_HALF = 4.0
"""The room is 8 m x 8 m, centred on the Vicon origin."""
PLATFORM_LIMIT = ROOM_HALF - 0.3
"""How far the platform centre gets from the room's centre: its 50 cm platform meets the wall."""
PLATFORM_SPEED = 0.3
PLATFORM_TURN_RATE = 1.5
RANDOM_TURN_MEAN = 7.0
PLATFORM_TOP = 0.25
"""Height of the platform's markers (m)."""
PLATFORM_HALF = 0.25

UAV_GROUND = 0.08
"""Height of the UAV's markers when it stands on the floor (m)."""
UAV_REST = 0.08
"""Height of the UAV's markers above the platform when it stands on it (m)."""
HOVER_Z = 1.0
APPROACH = 0.6
"""Height above the platform at which the UAV pursues it (m)."""
LANDING_RADIUS = 0.15
LANDING_TIME = 1.5
LAND_SPEED = 0.3
STARTUP_TIME = 1.0
HOVER_TIME = 2.0
TOUCH_MARGIN = 0.03
MAX_SPEED = 1.5
MAX_CLIMB = 0.6
MAX_ACCEL = 3.0
KP_XY = 1.2
KP_Z = 1.5
TAU = 0.25
LEAD = 0.2
GRAVITY = 9.81
GUST_SIGMA = 0.15
GUST_TIME = 1.0
CALL_DELAY = 0.25
"""The least delay of an /a/execute_task call (s); an exponential tail adds about 80 ms."""

TASK_WANDER, TASK_TRACK, TASK_LAND, TASK_STOP = range(4)
"""Task ids of /a/execute_task: what the controller tells the platform it is doing."""


@dataclass(frozen=True)
class Call:
    """One /a/execute_task call: request time (s from the start), task id and delay (s)."""

    time: float
    task_id: int
    delay: float


@dataclass(frozen=True)
class World:
    """The simulated run: true states on the 100 Hz grid and the controller's 20 Hz cycles.

    ``platform`` and ``uav`` are (N, 6) arrays of x, y, z, roll, pitch, yaw; ``motors`` says
    when the UAV's motors run. ``cycle_step`` is the grid step of each controller cycle,
    ``mode`` the state it commands, ``waypoint`` (M, 4) its x, y, z, yaw and ``cmd`` whether
    it published a state command in that cycle (on change and at 5 Hz).
    """

    duration: float
    time: FloatArray
    platform: FloatArray
    uav: FloatArray
    motors: NDArray[np.bool_]
    cycle_step: NDArray[np.int64]
    mode: NDArray[np.uint8]
    waypoint: FloatArray
    cmd: NDArray[np.bool_]
    calls: tuple[Call, ...]
    touchdown: float | None
    platform_noise: FloatArray
    uav_noise: FloatArray

    @property
    def landed(self) -> bool:
        """Whether the UAV touched down on the platform."""
        return self.touchdown is not None


def _wrap(angle: float) -> float:
    return (angle + math.pi) % (2 * math.pi) - math.pi


def _wall_distance(x: float, y: float, heading: float) -> float:
    """How far the platform can drive from (x, y) along the heading before a wall."""
    distance = math.inf
    for position, direction in ((x, math.cos(heading)), (y, math.sin(heading))):
        if direction > 1e-9:
            distance = min(distance, (PLATFORM_LIMIT - position) / direction)
        elif direction < -1e-9:
            distance = min(distance, (-PLATFORM_LIMIT - position) / direction)
    return max(distance, 0.0)


def _inward(x: float, y: float) -> float:
    """The heading that points from the walls the platform touches into the room."""
    nx = (x <= -PLATFORM_LIMIT + 1e-6) - (x >= PLATFORM_LIMIT - 1e-6)
    ny = (y <= -PLATFORM_LIMIT + 1e-6) - (y >= PLATFORM_LIMIT - 1e-6)
    return math.atan2(ny, nx)


def _platform_track(rng: np.random.Generator, time: FloatArray) -> FloatArray:
    """The platform's x, y, yaw, vx, vy on the grid: the vacuum motion as segments."""
    duration = float(time[-1]) + DT
    x, y = (float(v) for v in rng.uniform(-3.0, 3.0, 2))
    heading = float(rng.uniform(-math.pi, math.pi))
    # (start, end, x0, y0, heading0, heading1); a move has heading0 == heading1
    segments: list[tuple[float, float, float, float, float, float]] = []
    now = 0.0
    while now < duration:
        to_wall = _wall_distance(x, y, heading) / PLATFORM_SPEED
        until_turn = float(rng.exponential(RANDOM_TURN_MEAN))
        moving = min(to_wall, until_turn)
        if moving > 0:
            segments.append((now, now + moving, x, y, heading, heading))
            x += PLATFORM_SPEED * moving * math.cos(heading)
            y += PLATFORM_SPEED * moving * math.sin(heading)
            now += moving
        if until_turn < to_wall:
            new = heading + float(rng.choice([-1.0, 1.0]) * rng.uniform(0.5, 2.0))
        else:
            new = _inward(x, y) + float(rng.uniform(-1.2, 1.2))
        turn = _wrap(new - heading)
        span = abs(turn) / PLATFORM_TURN_RATE
        segments.append((now, now + span, x, y, heading, heading + turn))
        heading = _wrap(heading + turn)
        now += span
    track = np.zeros((time.size, 5))
    for start, end, x0, y0, h0, h1 in segments:
        inside = (time >= start) & (time < end)
        if not inside.any():
            continue
        elapsed = time[inside] - start
        if h0 == h1:
            track[inside, 0] = x0 + PLATFORM_SPEED * elapsed * math.cos(h0)
            track[inside, 1] = y0 + PLATFORM_SPEED * elapsed * math.sin(h0)
            track[inside, 3] = PLATFORM_SPEED * math.cos(h0)
            track[inside, 4] = PLATFORM_SPEED * math.sin(h0)
        else:
            track[inside, 0] = x0
            track[inside, 1] = y0
            track[inside, 2] = h0 + math.copysign(PLATFORM_TURN_RATE, h1 - h0) * elapsed
    track[:, 2] = (track[:, 2] + np.pi) % (2 * np.pi) - np.pi
    return track


def _wobble(rng: np.random.Generator, time: FloatArray, amplitude: float) -> FloatArray:
    """A smooth small oscillation: three sinusoids of random frequency and phase."""
    frequency = rng.uniform(0.3, 2.0, 3)
    phase = rng.uniform(0, 2 * np.pi, 3)
    weight = rng.uniform(0.5, 1.0, 3)
    waves = np.sin(2 * np.pi * frequency[None, :] * time[:, None] + phase[None, :])
    return amplitude * (waves @ weight) / weight.sum()  # type: ignore[no-any-return]


def _clip_norm(x: float, y: float, limit: float) -> tuple[float, float]:
    norm = math.hypot(x, y)
    if norm > limit:
        return x * limit / norm, y * limit / norm
    return x, y


def _uav_start(rng: np.random.Generator, platform: FloatArray) -> tuple[float, float, float]:
    """Where the UAV stands at the start: anywhere in the room, away from the platform."""
    while True:
        x, y = (float(v) for v in rng.uniform(-3.5, 3.5, 2))
        if math.hypot(x - platform[0, 0], y - platform[0, 1]) > 1.5:
            return x, y, float(rng.uniform(-math.pi, math.pi))


def simulate_world(seed: int, duration: float) -> World:
    """Simulate one run of ``duration`` seconds from ``seed``: the same seed, the same run."""
    if not (math.isfinite(duration) and duration >= DT):
        raise ValueError(f"duration must be a finite time of at least {DT} s, not {duration!r}")
    streams = np.random.SeedSequence(seed).spawn(6)
    rng_platform, rng_uav, rng_gust, rng_noise, rng_calls, rng_wobble = (
        np.random.default_rng(s) for s in streams
    )
    steps = round(duration / DT)
    time: FloatArray = np.arange(steps, dtype=np.float64) * DT
    track = _platform_track(rng_platform, time)
    wobble = np.stack([_wobble(rng_wobble, time, a) for a in (0.001, 0.004, 0.004)], axis=1)
    ux, uy, uyaw = _uav_start(rng_uav, track)
    # Vicon noise: about half a millimetre and a milliradian, fixed per run
    platform_noise = rng_noise.normal(0.0, 1.0, (steps, 6)) * [5e-4, 5e-4, 5e-4, 1e-3, 1e-3, 1e-3]
    uav_noise = rng_noise.normal(0.0, 1.0, (steps, 6)) * [5e-4, 5e-4, 5e-4, 2e-3, 2e-3, 2e-3]
    gust_kicks = rng_gust.normal(0.0, GUST_SIGMA * math.sqrt(DT), (steps, 3))

    uav = np.zeros((steps, 6))
    motors = np.zeros(steps, dtype=bool)
    cycle_step: list[int] = []
    modes: list[int] = []
    waypoints: list[tuple[float, float, float, float]] = []
    cmds: list[bool] = []
    calls: list[Call] = []

    px, py, pz = ux, uy, UAV_GROUND
    vx = vy = vz = 0.0
    gx = gy = gz = 0.0
    mode = STARTUP
    last_cmd_mode, last_cmd_cycle = -1, -10
    hover_since = within_since = 0.0
    within = False
    wx, wy, wz = px, py, UAV_GROUND
    est_vx = est_vy = 0.0
    previous_car: tuple[float, float] | None = None
    touchdown_step: int | None = None

    def call(now: float, task: int) -> None:
        calls.append(Call(now + 0.0012, task, CALL_DELAY + float(rng_calls.exponential(0.08))))

    for step in range(steps):
        now = step * DT
        if step % CTRL_PERIOD_STEPS == CTRL_PHASE_STEPS:
            cycle = len(cycle_step)
            car_at = step - CTRL_PHASE_STEPS
            cx = track[car_at, 0] + platform_noise[car_at, 0]
            cy = track[car_at, 1] + platform_noise[car_at, 1]
            if previous_car is not None:
                alpha = 0.3
                est_vx += alpha * ((cx - previous_car[0]) / (CTRL_PERIOD_STEPS * DT) - est_vx)
                est_vy += alpha * ((cy - previous_car[1]) / (CTRL_PERIOD_STEPS * DT) - est_vy)
            previous_car = (cx, cy)
            seen = step - 1 - (step - 1) % 2  # the latest /a/subject_pose (50 Hz)
            mx = uav[seen, 0] + uav_noise[seen, 0]
            my = uav[seen, 1] + uav_noise[seen, 1]
            mz = uav[seen, 2] + uav_noise[seen, 2]
            distance = math.hypot(mx - cx, my - cy)
            if cycle == 0:
                call(now, TASK_WANDER)
            if mode == STARTUP and now >= STARTUP_TIME:
                mode = LAUNCH
            elif mode == LAUNCH and abs(mz - HOVER_Z) < 0.05:
                mode, hover_since = HOVER, now
            elif mode == HOVER and now - hover_since >= HOVER_TIME:
                mode = TASK
                call(now, TASK_TRACK)
            elif mode == TASK:
                if distance < LANDING_RADIUS:
                    if not within:
                        within, within_since = True, now
                    elif now - within_since >= LANDING_TIME - 1e-9:
                        mode, wz = LAND, PLATFORM_TOP + APPROACH
                        call(now, TASK_LAND)
                else:
                    within = False
            elif (
                mode == LAND
                and mz <= PLATFORM_TOP + UAV_REST + TOUCH_MARGIN
                and distance < PLATFORM_HALF
            ):
                mode = SHUTDOWN
                touchdown_step = step
                call(now, TASK_STOP)
            if mode in (STARTUP, LAUNCH, HOVER):
                wx, wy = ux, uy
                wz = UAV_GROUND if mode == STARTUP else HOVER_Z
            elif mode == TASK:
                wx, wy, wz = cx + est_vx * LEAD, cy + est_vy * LEAD, PLATFORM_TOP + APPROACH
            elif mode == LAND:
                wx, wy = cx + est_vx * LEAD, cy + est_vy * LEAD
                if distance < LANDING_RADIUS:
                    floor = PLATFORM_TOP + UAV_REST - 0.1
                    wz = max(wz - LAND_SPEED * CTRL_PERIOD_STEPS * DT, floor)
            else:
                wx, wy, wz = cx, cy, PLATFORM_TOP + UAV_REST
            cmd = mode != last_cmd_mode or cycle - last_cmd_cycle >= 4
            if cmd:
                last_cmd_mode, last_cmd_cycle = mode, cycle
            cycle_step.append(step)
            modes.append(mode)
            waypoints.append((wx, wy, wz, uyaw))
            cmds.append(cmd)
            if touchdown_step is not None:
                break
        flying = mode in (LAUNCH, HOVER, TASK, LAND)
        motors[step] = flying
        ax = ay = az = 0.0
        if flying:
            feed_x, feed_y = (est_vx, est_vy) if mode in (TASK, LAND) else (0.0, 0.0)
            want_x, want_y = _clip_norm(
                KP_XY * (wx - px) + feed_x, KP_XY * (wy - py) + feed_y, MAX_SPEED
            )
            want_z = min(max(KP_Z * (wz - pz), -MAX_CLIMB), MAX_CLIMB)
            ax, ay = _clip_norm((want_x - vx) / TAU, (want_y - vy) / TAU, MAX_ACCEL)
            az = (want_z - vz) / TAU
            gx += -gx * DT / GUST_TIME + gust_kicks[step, 0]
            gy += -gy * DT / GUST_TIME + gust_kicks[step, 1]
            gz += -gz * DT / GUST_TIME + gust_kicks[step, 2]
            vx += (ax + gx) * DT
            vy += (ay + gy) * DT
            vz += (az + gz) * DT
            px += vx * DT
            py += vy * DT
            pz += vz * DT
            if pz < UAV_GROUND:
                pz, vz = UAV_GROUND, max(vz, 0.0)
        body_x = math.cos(uyaw) * ax + math.sin(uyaw) * ay
        body_y = -math.sin(uyaw) * ax + math.cos(uyaw) * ay
        uav[step] = (px, py, pz, -math.atan(body_y / GRAVITY), math.atan(body_x / GRAVITY), uyaw)

    touchdown = None
    if touchdown_step is not None:
        touchdown = touchdown_step * DT
        _stop_platform(track, time, calls[-1].time + calls[-1].delay)
    platform = np.zeros((steps, 6))
    platform[:, 0:2] = track[:, 0:2]
    platform[:, 2] = PLATFORM_TOP + wobble[:, 0]
    speed = np.hypot(track[:, 3], track[:, 4]) / PLATFORM_SPEED
    platform[:, 3:5] = wobble[:, 1:3] * (0.25 + speed)[:, None]
    platform[:, 5] = track[:, 2]
    if touchdown_step is not None:
        _ride(uav, platform, touchdown_step)
        rest = np.arange(cycle_step[-1] + CTRL_PERIOD_STEPS, steps, CTRL_PERIOD_STEPS)
        count = len(cycle_step)
        car = rest - CTRL_PHASE_STEPS
        cycle_step += rest.tolist()
        modes += [SHUTDOWN] * rest.size
        cmds += [(count + k - last_cmd_cycle) % 4 == 0 for k in range(rest.size)]
        waypoints += [
            (float(x), float(y), PLATFORM_TOP + UAV_REST, uyaw)
            for x, y in zip(
                platform[car, 0] + platform_noise[car, 0],
                platform[car, 1] + platform_noise[car, 1],
                strict=True,
            )
        ]
    return World(
        duration=steps * DT,
        time=time,
        platform=platform,
        uav=uav,
        motors=motors,
        cycle_step=np.asarray(cycle_step, dtype=np.int64),
        mode=np.asarray(modes, dtype=np.uint8),
        waypoint=np.asarray(waypoints, dtype=np.float64).reshape(-1, 4),
        cmd=np.asarray(cmds, dtype=bool),
        calls=tuple(calls),
        touchdown=touchdown,
        platform_noise=platform_noise,
        uav_noise=uav_noise,
    )


def _stop_platform(track: FloatArray, time: FloatArray, when: float) -> None:
    """The platform stops where it is at ``when`` (told so by the task call)."""
    after = time >= when
    if after.any():
        first = int(np.argmax(after))
        track[after, 0:3] = track[first, 0:3]
        track[after, 3:5] = 0.0


def _ride(uav: FloatArray, platform: FloatArray, step: int) -> None:
    """After touchdown the UAV sits on the platform with its motors off.

    The loop stopped at ``step`` before moving the UAV: its last pose is that of ``step - 1``.
    """
    dx, dy = uav[step - 1, 0] - platform[step, 0], uav[step - 1, 1] - platform[step, 1]
    yaw0 = platform[step, 5]
    local_x = math.cos(yaw0) * dx + math.sin(yaw0) * dy
    local_y = -math.sin(yaw0) * dx + math.cos(yaw0) * dy
    yaw = platform[step:, 5]
    uav[step:, 0] = platform[step:, 0] + np.cos(yaw) * local_x - np.sin(yaw) * local_y
    uav[step:, 1] = platform[step:, 1] + np.sin(yaw) * local_x + np.cos(yaw) * local_y
    uav[step:, 2] = platform[step:, 2] + UAV_REST
    uav[step:, 3:5] = platform[step:, 3:5]
    uav[step:, 5] = uav[step - 1, 5] + (yaw - yaw0)
