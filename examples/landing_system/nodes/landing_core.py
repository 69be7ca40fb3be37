"""The landing system of the thesis' case study 1 (section 5.1): physics, controller, faults.

Pure Python (no rospy, no numpy): the rospy nodes of this package run it under Debian's
``/usr/bin/python3``, and the tests import it under any interpreter.

* :class:`Platform`: an iRobot Create with a 50 cm x 50 cm platform (markers 25 cm high)
  wandering an 8 m x 8 m room in its "vacuum" pattern: straight at 0.3 m/s, turning in place
  towards the room at a wall, and now and then a spontaneous turn. The fragile platform tips
  when the UAV rests on it outside its safe quadrant.
* :class:`Uav`: a quadrotor (AscTec Hummingbird-sized) driven by roll, pitch and collective
  thrust: attitude follows its command with a first-order lag, thrust tilts with it, gravity
  and linear drag act on the velocity relative to the air (wind included), and the ground,
  the platform (or what occupies it) stop it. Touching down too fast or too tilted is a crash;
  resting on the platform it rides along, and falls off (a crash) when its centre leaves the
  platform or the platform tips.
* :class:`Wind`: a blower in one corner of the room that sweeps it like an oscillating fan:
  a point sees gusts of 8 to 38 km/h while the jet passes over it, calm in between.
* :class:`LandingController`: the controller of Figure 3.6 (``/a/car_ctrl``): states startup,
  launch, hover, task, land, shutdown (0-5); it pursues the platform at 0.6 m above it and
  lands when the UAV has been within 15 cm of its centre for 1.5 s at its pursuit height,
  descending at 0.3 m/s (waiting while the platform turns or brakes) until it senses the
  touchdown, then switches the motors off and stops the platform; a
  landing called off (a task state it did not command, the monitor's) sends the platform on
  again (task 1, track) and pursues it, after going around (straight up to its pursuit
  height) when it was called off on or near a surface.
* :class:`Attitude`: the position loop of ``/a/pid_ctrl`` (waypoint to roll, pitch, thrust).
* :class:`Referee`: how a run ends (Table 5.1's criteria): landed (motors off on the platform
  for 5 s), crashed, fallen off, landed elsewhere, or timed out.

Every random choice comes from a ``random.Random`` seeded by the run's seed, so a trial is
repeatable apart from the timing of the ROS graph.
"""

from __future__ import annotations

import math
import random
from dataclasses import dataclass, field

DT = 0.01
"""The physics step and the motion-capture period (s)."""
GRAVITY = 9.81
ROOM_HALF = 4.0
PLATFORM_HALF = 0.25
PLATFORM_TOP = 0.25
"""Height of the platform's markers, its top surface (m)."""
PLATFORM_SPEED = 0.3
PLATFORM_TURN_RATE = 1.5
PLATFORM_ACCEL = 0.5
"""How fast the vehicle speeds up and brakes (m/s^2): it stops from full speed in 0.6 s,
over 9 cm."""
PLATFORM_YAW_ACCEL = 3.0
"""How fast its turn rate builds up and dies down (rad/s^2): a full-rate turn in place
starts and ends over 0.5 s."""
PLATFORM_LIMIT = ROOM_HALF - 0.35
RANDOM_TURN_MEAN = 7.0
"""Mean seconds between spontaneous turns of the vacuum pattern."""
OBJECT_HALF = 0.2
OBJECT_HEIGHT = 0.15
"""What occupies the platform in the occupied-landing scenario (m)."""
TIP_ANGLE = 0.35
TIP_RATE = 0.3
"""A fragile platform sags under a load off its safe quadrant this far (rad), this fast
(rad/s), and springs back level at the same rate once the load is gone; the UAV slides off
at :data:`SLIDE_TILT`, about 0.8 s after it began to tip."""
SLIDE_TILT = 0.25
WIND_PERIOD = 20.0
WIND_WIDTH = 0.25
"""The blower's sweep (s, there and back) and its jet's half-width (rad)."""
GROUND_EFFECT_HEIGHT = 0.4
GROUND_EFFECT_AIR = 0.5
"""Near a surface the rotors' downwash comes back off it: below this height over what is
under it (m) the UAV sits in an unsteady outwash, air moving sideways at up to this speed
(m/s, standard deviation right at the surface, falling off linearly with height; it changes
over about 0.3 s): a landing touches down a few centimetres from where it aimed, never twice
at the same spot."""
UAV_REST = 0.08
"""Height of the UAV's markers above the surface it stands on (m)."""
UAV_MASS = 0.7
ATTITUDE_TAU = 0.12
MAX_TILT = 0.45
DRAG = 0.35
"""Linear drag per unit mass (1/s)."""
CRASH_SPEED = 1.2
"""Vertical speed of a touchdown (m/s) above which the UAV breaks."""
CRASH_TILT = 0.6
CRASH_SLIDE = 0.25
"""Horizontal speed over the surface at touchdown (m/s) above which its legs catch and it
flips."""
MAX_THRUST = 2.0 * GRAVITY

STATES = ("startup", "launch", "hover", "task", "land", "shutdown")
STARTUP, LAUNCH, HOVER, TASK, LAND, SHUTDOWN = range(6)
TASK_WANDER, TASK_TRACK, TASK_LAND, TASK_STOP = range(4)
"""Task ids of /a/execute_task: what the controller tells the platform it is doing."""

SCENARIOS = (
    "normal",
    "wind",
    "occupied",
    "fragile",
    "slowed",
    "stealing",
    "false_airport",
)
"""Table 5.1: s1 to s7."""
AVOID_LANDING = frozenset({"occupied", "false_airport"})
"""Scenarios whose success is *not* landing."""


def wrap(angle: float) -> float:
    """The angle in [-pi, pi)."""
    return (angle + math.pi) % (2 * math.pi) - math.pi


def clip(value: float, low: float, high: float) -> float:
    return low if value < low else high if value > high else value


# -- the platform -----------------------------------------------------------------------------


@dataclass
class Platform:
    """The iRobot Create and its platform: pose, motion, tilt."""

    rng: random.Random
    x: float = 0.0
    y: float = 0.0
    heading: float = 0.0
    moving: bool = True
    target: float | None = None
    """The heading it turns to in place (None: driving straight)."""
    until_turn: float = RANDOM_TURN_MEAN
    roll: float = 0.0
    pitch: float = 0.0
    tipping: tuple[float, float] | None = None
    present: bool = True
    safe: tuple[int, int] = (1, 1)
    """The quadrant of a fragile platform that holds a load (signs of its forward and leftward
    coordinates): the one over the vehicle's support, which differs from one platform to the
    next (:class:`World` draws it for the fragile scenario)."""
    speed: float = PLATFORM_SPEED
    """Forward speed (m/s): it drives straight at :data:`PLATFORM_SPEED` and brakes before
    each turn in place (:data:`PLATFORM_ACCEL`)."""
    vx: float = 0.0
    vy: float = 0.0
    yaw_rate: float = 0.0

    @classmethod
    def start(cls, rng: random.Random) -> Platform:
        platform = cls(rng)
        platform.x = rng.uniform(-2.0, 2.0)
        platform.y = rng.uniform(-2.0, 2.0)
        platform.heading = rng.uniform(-math.pi, math.pi)
        platform.until_turn = rng.expovariate(1.0 / RANDOM_TURN_MEAN)
        return platform

    def _inward(self) -> float:
        """A heading into the room, away from the walls it touches."""
        away = math.atan2(-self.y, -self.x)
        return wrap(away + self.rng.uniform(-1.0, 1.0))

    def step(self, dt: float) -> None:
        if self.tipping is not None or self.roll or self.pitch:
            goal_roll, goal_pitch = self.tipping if self.tipping is not None else (0.0, 0.0)
            self.roll += clip(goal_roll - self.roll, -TIP_RATE * dt, TIP_RATE * dt)
            self.pitch += clip(goal_pitch - self.pitch, -TIP_RATE * dt, TIP_RATE * dt)
        brake, spin = PLATFORM_ACCEL * dt, PLATFORM_YAW_ACCEL * dt
        if not self.moving or self.target is not None:
            # stopping, or about to turn in place: brake to a standstill first
            self.speed = max(0.0, self.speed - brake)
        if not self.moving or (self.target is not None and self.speed > 0.0):
            self.yaw_rate = clip(0.0, self.yaw_rate - spin, self.yaw_rate + spin)
        elif self.target is not None:
            # turn in place: the turn rate builds up, and dies down in time to stop on target
            error = wrap(self.target - self.heading)
            goal = math.copysign(
                min(PLATFORM_TURN_RATE, math.sqrt(2.0 * PLATFORM_YAW_ACCEL * abs(error))), error
            )
            self.yaw_rate = clip(goal, self.yaw_rate - spin, self.yaw_rate + spin)
            self.heading = wrap(self.heading + self.yaw_rate * dt)
            if abs(wrap(self.target - self.heading)) <= 0.01 and abs(self.yaw_rate) <= spin:
                self.target, self.yaw_rate = None, 0.0
        else:
            self.speed = min(PLATFORM_SPEED, self.speed + brake)
            reach = self.speed * dt + self.speed**2 / (2.0 * PLATFORM_ACCEL)  # braking distance
            ahead_x = self.x + reach * math.cos(self.heading)
            ahead_y = self.y + reach * math.sin(self.heading)
            if abs(ahead_x) > PLATFORM_LIMIT or abs(ahead_y) > PLATFORM_LIMIT:
                self.target = self._inward()
            else:
                self.until_turn -= dt
                if self.until_turn <= 0.0:
                    turn = self.rng.choice((-1, 1)) * self.rng.uniform(0.5, 2.5)
                    self.target = wrap(self.heading + turn)
                    self.until_turn = self.rng.expovariate(1.0 / RANDOM_TURN_MEAN)
        self.vx = self.speed * math.cos(self.heading)
        self.vy = self.speed * math.sin(self.heading)
        self.x += self.vx * dt
        self.y += self.vy * dt

    def local(self, x: float, y: float) -> tuple[float, float]:
        """A point of the room in the platform's frame."""
        dx, dy = x - self.x, y - self.y
        c, s = math.cos(self.heading), math.sin(self.heading)
        return c * dx + s * dy, -s * dx + c * dy

    def carries(self, x: float, y: float, half: float = PLATFORM_HALF) -> bool:
        """Whether (x, y) is over the platform (or a square of ``half`` on its centre)."""
        if not self.present:
            return False
        u, v = self.local(x, y)
        return abs(u) <= half and abs(v) <= half

    def velocity_at(self, x: float, y: float) -> tuple[float, float]:
        """The velocity of the platform's surface at (x, y): translation and turn."""
        dx, dy = x - self.x, y - self.y
        return self.vx - self.yaw_rate * dy, self.vy + self.yaw_rate * dx


# -- wind -------------------------------------------------------------------------------------


@dataclass
class Wind:
    """A blower in a corner that sweeps the room like an oscillating fan: inside its jet the
    air moves at 8 to 38 km/h (38 next to the blower, about 8 at the far walls) with
    turbulence; outside it the air is nearly still. A point of the room thus sees a gust
    each time the jet sweeps over it, and a calm spell until it comes back."""

    rng: random.Random
    enabled: bool = False
    source: tuple[float, float] = (-ROOM_HALF, -ROOM_HALF)
    period: float = WIND_PERIOD
    """Seconds for a sweep across the room and back."""
    width: float = WIND_WIDTH
    """The jet's angular half-width (rad, the standard deviation of its profile)."""
    phase: float = 0.0
    t: float = 0.0
    gust: float = 0.0
    gust_angle: float = 0.0

    def __post_init__(self) -> None:
        self.phase = self.rng.uniform(0.0, 2.0 * math.pi)

    def step(self, dt: float) -> None:
        if not self.enabled:
            return
        self.t += dt
        # turbulence inside the jet: an Ornstein-Uhlenbeck gust on the speed and the
        # direction, time constant 1 s
        self.gust += -self.gust * dt + 0.6 * math.sqrt(dt) * self.rng.gauss(0.0, 1.0)
        self.gust_angle += -self.gust_angle * dt + 0.4 * math.sqrt(dt) * self.rng.gauss(0.0, 1.0)

    @property
    def axis(self) -> float:
        """Where the jet points now (rad): it sweeps the quarter of directions from its
        corner into the room, a little beyond the walls."""
        middle = math.atan2(-self.source[1], -self.source[0])
        swing = math.pi / 4 + 0.15
        return middle + swing * math.sin(2.0 * math.pi * self.t / self.period + self.phase)

    def at(self, x: float, y: float) -> tuple[float, float]:
        """The wind velocity (m/s) at (x, y)."""
        if not self.enabled:
            return 0.0, 0.0
        dx, dy = x - self.source[0], y - self.source[1]
        distance = max(math.hypot(dx, dy), 0.5)
        direction = math.atan2(dy, dx)
        off = wrap(direction - self.axis) / self.width
        jet = clip(10.5 / (1.0 + 0.35 * distance) * (1.0 + self.gust), 2.2, 10.5)
        speed = jet * math.exp(-0.5 * off * off)
        angle = direction + self.gust_angle
        return speed * math.cos(angle), speed * math.sin(angle)


# -- the UAV ----------------------------------------------------------------------------------


@dataclass
class Command:
    """What ``/a/pid_ctrl`` asks of the UAV: attitude (rad), thrust (m/s^2), motors."""

    roll: float = 0.0
    pitch: float = 0.0
    thrust: float = 0.0
    motors: bool = False


@dataclass
class Uav:
    """The quadrotor: position, velocity, attitude, and what it stands on."""

    x: float = 0.0
    y: float = 0.0
    z: float = UAV_REST
    vx: float = 0.0
    vy: float = 0.0
    vz: float = 0.0
    roll: float = 0.0
    pitch: float = 0.0
    ax: float = 0.0
    ay: float = 0.0
    az: float = 0.0
    resting: str | None = "floor"
    """``floor``, ``platform``, ``object`` or None (flying)."""
    broken: str | None = None
    """Why it crashed (None: it did not)."""

    def surface(self, platform: Platform, occupied: bool) -> tuple[float, str]:
        """The height of what is under the UAV and its name."""
        if platform.carries(self.x, self.y):
            if occupied and platform.carries(self.x, self.y, OBJECT_HALF):
                return PLATFORM_TOP + OBJECT_HEIGHT, "object"
            return PLATFORM_TOP, "platform"
        return 0.0, "floor"

    def step(
        self,
        dt: float,
        command: Command,
        wind: tuple[float, float],
        platform: Platform,
        occupied: bool,
    ) -> None:
        if self.broken is not None:
            return
        lag = dt / ATTITUDE_TAU
        goal_roll = clip(command.roll, -MAX_TILT, MAX_TILT) if command.motors else 0.0
        goal_pitch = clip(command.pitch, -MAX_TILT, MAX_TILT) if command.motors else 0.0
        self.roll += (goal_roll - self.roll) * lag
        self.pitch += (goal_pitch - self.pitch) * lag
        thrust = clip(command.thrust, 0.0, MAX_THRUST) if command.motors else 0.0
        # body z axis with yaw 0: pitch tilts thrust to +x, roll to -y
        fx = thrust * math.sin(self.pitch) * math.cos(self.roll)
        fy = -thrust * math.sin(self.roll)
        fz = thrust * math.cos(self.pitch) * math.cos(self.roll)
        ax = fx - DRAG * (self.vx - wind[0])
        ay = fy - DRAG * (self.vy - wind[1])
        az = fz - GRAVITY - DRAG * self.vz
        if self.resting is not None:
            if az <= 0.0:  # still pressed on its surface: it rides along
                self._ride(dt, platform)
                self.ax = self.ay = self.az = 0.0
                return
            self.resting = None  # lifts off
        self.ax, self.ay, self.az = ax, ay, az
        self.vx += ax * dt
        self.vy += ay * dt
        self.vz += az * dt
        self.x += self.vx * dt
        self.y += self.vy * dt
        self.z += self.vz * dt
        self.x = clip(self.x, -ROOM_HALF, ROOM_HALF)
        self.y = clip(self.y, -ROOM_HALF, ROOM_HALF)
        height, name = self.surface(platform, occupied)
        if self.z - UAV_REST <= height:
            speed = -self.vz
            tilt = max(abs(self.roll), abs(self.pitch))
            sx, sy = platform.velocity_at(self.x, self.y) if name != "floor" else (0.0, 0.0)
            sliding = math.hypot(self.vx - sx, self.vy - sy)
            self.z = height + UAV_REST
            if speed > CRASH_SPEED or tilt > CRASH_TILT:
                self.broken = f"crashed onto the {name} at {speed:.2f} m/s, tilted {tilt:.2f} rad"
                return
            if sliding > CRASH_SLIDE:
                self.broken = f"tipped over touching the {name} sliding at {sliding:.2f} m/s"
                return
            self.resting = name
            self.vx = self.vy = self.vz = 0.0

    def _ride(self, dt: float, platform: Platform) -> None:
        """Stand on the surface: on the platform, move with it and fall off its edges."""
        if self.resting in ("platform", "object"):
            vx, vy = platform.velocity_at(self.x, self.y)
            self.x += vx * dt
            self.y += vy * dt
            self.vx, self.vy, self.vz = vx, vy, 0.0
            if not platform.carries(self.x, self.y):
                self.broken = "fell off the platform's edge"
            elif max(abs(platform.roll), abs(platform.pitch)) > SLIDE_TILT:
                self.broken = "slid off the tipping platform"
        else:
            self.vx = self.vy = self.vz = 0.0


# -- control ----------------------------------------------------------------------------------


@dataclass
class Attitude:
    """``/a/pid_ctrl``: a PD position loop from the waypoint to roll, pitch and thrust; the
    waypoint's velocity (its smoothed finite difference) is fed forward, so the UAV keeps up
    with a moving platform without a steady lag. A waypoint that stopped coming (none for
    :attr:`smoothing` s: the controller sends none, or a monitor withholds them) is a point at
    rest: its last velocity is no longer fed forward, so a UAV holding a stale waypoint (or,
    in ``pid_ctrl``, where it is) stops instead of flying on at the platform's last speed."""

    kp_xy: float = 1.6
    kd_xy: float = 1.8
    kp_z: float = 3.0
    kd_z: float = 2.5
    max_accel: float = 3.5
    smoothing: float = 0.3
    """Seconds over which the waypoint's velocity is averaged."""
    ki_xy: float = 0.6
    max_integral: float = 3.0
    """Acceleration (m/s^2) the integral term may give: it takes up a steady wind."""
    last: tuple[float, float, float, float] | None = None
    target_velocity: tuple[float, float] = (0.0, 0.0)
    integral: tuple[float, float] = (0.0, 0.0)
    stamp: float | None = None

    def see_waypoint(self, t: float, x: float, y: float, z: float) -> None:
        """A waypoint arrived (``/a/task_waypose``)."""
        if self.last is not None and t > self.last[0]:
            dt = t - self.last[0]
            a = min(1.0, dt / self.smoothing)
            vx = clip((x - self.last[1]) / dt, -1.0, 1.0)
            vy = clip((y - self.last[2]) / dt, -1.0, 1.0)
            self.target_velocity = (
                (1 - a) * self.target_velocity[0] + a * vx,
                (1 - a) * self.target_velocity[1] + a * vy,
            )
        self.last = (t, x, y, z)

    def command(
        self,
        state: int,
        waypoint: tuple[float, float, float] | None,
        pose: tuple[float, float, float],
        velocity: tuple[float, float, float],
        t: float | None = None,
    ) -> Command:
        """The command for the current state, waypoint and UAV pose; ``t`` (s) integrates."""
        if state in (STARTUP, SHUTDOWN) or waypoint is None:
            self.integral, self.stamp = (0.0, 0.0), None
            return Command()
        ex = waypoint[0] - pose[0]
        ey = waypoint[1] - pose[1]
        ez = waypoint[2] - pose[2]
        if t is not None and self.last is not None and t - self.last[0] > self.smoothing:
            self.target_velocity = (0.0, 0.0)  # no waypoint for a while: it stands still
        tvx, tvy = self.target_velocity
        ix, iy = self.integral
        if t is not None and self.stamp is not None and pose[2] > UAV_REST + 0.1:
            dt = clip(t - self.stamp, 0.0, 0.1)
            ix = clip(ix + self.ki_xy * ex * dt, -self.max_integral, self.max_integral)
            iy = clip(iy + self.ki_xy * ey * dt, -self.max_integral, self.max_integral)
            self.integral = (ix, iy)
        self.stamp = t
        ax = self.kp_xy * ex + self.kd_xy * (tvx - velocity[0]) + ix
        ay = self.kp_xy * ey + self.kd_xy * (tvy - velocity[1]) + iy
        ax = clip(ax, -self.max_accel, self.max_accel)
        ay = clip(ay, -self.max_accel, self.max_accel)
        az = clip(self.kp_z * ez - self.kd_z * velocity[2], -5.0, 5.0)
        if state == LAND and ez < 0.0:
            az = min(az, 0.0)  # landing on a target below: never push up, no bounce at touchdown
        thrust = clip(GRAVITY + az, 0.0, MAX_THRUST)
        pitch = math.atan2(ax, GRAVITY)
        roll = -math.atan2(ay, GRAVITY)
        return Command(roll, pitch, thrust, True)


@dataclass
class LandingController:
    """``/a/car_ctrl``: the state commands and waypoints of Figure 3.6."""

    landing_radius: float = 0.15
    landing_time: float = 1.5
    hover_z: float = 1.0
    approach: float = 0.6
    land_speed: float = 0.3
    lead: float = 0.1
    startup_time: float = 1.0
    hover_time: float = 2.0
    commanded: int = STARTUP
    since: float = 0.0
    """When the current commanded state began (s)."""
    within_since: float | None = None
    land_z: float = 0.0
    touch_since: float | None = None
    descended: bool = False
    """The UAV has descended (faster than 0.1 m/s) since the landing began or last waited:
    only then does a standstill mean a touchdown, not the top of a climb."""
    home: tuple[float, float] | None = None
    last_car: tuple[float, float, float, float] | None = None
    track: list[tuple[float, float, float]] = field(default_factory=list)
    """The platform's positions of the last :attr:`window` s (t, x, y)."""
    window: float = 0.2
    speed_change: float = 0.04
    """The platform's mean speed over :attr:`window` dropping by more than this (m/s) from
    the window before means it brakes (for a turn in place, or to stop): it counts as
    turning. Speeds no vehicle drives (over twice its top speed: positions that jump) are
    no measurement of braking."""
    brake_settle: float = 0.6
    """How long (s) after it saw the platform brake it still counts as turning (braking
    from full speed takes 0.6 s; a turn in place that follows counts by its heading, and
    :attr:`settle` s after it)."""
    speeds: list[tuple[float, float]] = field(default_factory=list)
    car_velocity: tuple[float, float] = (0.0, 0.0)
    car_yaw: float | None = None
    turning_until: float = -1.0
    """Until when (s) the platform counts as turning: its heading changed between two poses
    faster than :attr:`turn_rate`, and :attr:`settle` s after that."""
    turn_rate: float = 0.3
    settle: float = 1.5
    hold: float = 0.3
    """How high over the platform (m) the UAV waits while the platform turns in a landing."""
    commit: float = UAV_REST + 0.01
    """Below this height over the platform's markers (m) the UAV has touched down: the
    landing goes on whatever the platform does."""
    go_around_below: float = 0.3
    """A landing called off with the UAV lower than this over the platform's markers (m: on
    a surface or just over it, in the rotors' outwash) goes around: the UAV climbs straight
    up to its pursuit height, keeping where it is over the platform, before it pursues
    again; only then is the platform told to drive on (task 1). Pursuing from a surface, or
    with the surface driving off under its legs, drags them sideways over it (a crash above
    :data:`CRASH_SLIDE`)."""
    climb: tuple[float, float] | None = None
    """In a go-around, the UAV's offset (x, y) from the platform's position when the landing
    was called off, which it keeps while it climbs (None: no go-around)."""

    def see_car(self, t: float, x: float, y: float, z: float, yaw: float | None = None) -> None:
        """A platform position (and heading, when known) arrived (``/a/car_pose``)."""
        if self.last_car is not None:
            t0, x0, y0, _ = self.last_car
            if t > t0:
                a = min(1.0, (t - t0) / 0.5)
                vx, vy = (x - x0) / (t - t0), (y - y0) / (t - t0)
                self.car_velocity = (
                    (1 - a) * self.car_velocity[0] + a * clip(vx, -1.0, 1.0),
                    (1 - a) * self.car_velocity[1] + a * clip(vy, -1.0, 1.0),
                )
                turned = None if yaw is None or self.car_yaw is None else wrap(yaw - self.car_yaw)
                if turned is not None and abs(turned) > self.turn_rate * (t - t0):
                    self.turning_until = t + self.settle
        if yaw is not None:
            self.car_yaw = yaw
        self.last_car = (t, x, y, z)
        self.track = [p for p in self.track if t - p[0] < self.window + 0.01] + [(t, x, y)]
        first = self.track[0]
        if t - first[0] >= self.window - 0.01:
            speed = math.hypot(x - first[1], y - first[2]) / (t - first[0])
            self.speeds = [v for v in self.speeds if t - v[0] <= self.window + 0.01]
            before = self.speeds[0] if self.speeds else None
            if before is not None and t - before[0] >= self.window - 0.01:
                plausible = max(speed, before[1]) <= 2.0 * PLATFORM_SPEED
                if plausible and before[1] - speed > self.speed_change:
                    self.turning_until = max(self.turning_until, t + self.brake_settle)
            self.speeds.append((t, speed))

    def _go(self, state: int, t: float) -> int:
        self.commanded, self.since, self.climb = state, t, None
        return state

    def step(
        self, t: float, state: int, uav: tuple[float, float, float], vz: float
    ) -> tuple[int, tuple[float, float, float] | None, int | None]:
        """One 20 Hz cycle: the state to command, the waypoint, and a task to call (or None).

        ``state`` is the state the state machine reports: a command from elsewhere (the
        monitor's) is obeyed as the new current state."""
        task: int | None = None
        if (
            state != self.commanded
            and state in (TASK, HOVER)
            and self.commanded in (LAND, SHUTDOWN)
        ):
            self._go(state, t)  # someone (the monitor) called the landing off
            self.within_since = self.touch_since = None
            car = self.last_car
            if state == TASK and car is not None and uav[2] - car[3] < self.go_around_below:
                self.climb = (uav[0] - car[1], uav[1] - car[2])  # low: go around first
            elif state == TASK:  # tracking again: the platform drives on (after a stop too)
                task = TASK_TRACK
        if self.home is None:
            self.home = (uav[0], uav[1])
        car = self.last_car
        if self.commanded == STARTUP:
            if t - self.since >= self.startup_time:
                self._go(LAUNCH, t)
            return self.commanded, None, None
        if self.commanded == LAUNCH:
            if uav[2] >= self.hover_z - 0.1:
                self._go(HOVER, t)
            return self.commanded, (self.home[0], self.home[1], self.hover_z), None
        if self.commanded == HOVER:
            if t - self.since >= self.hover_time and car is not None:
                self._go(TASK, t)
                task = TASK_TRACK
            return self.commanded, (uav[0], uav[1], self.hover_z), task
        if car is None:
            return self.commanded, (uav[0], uav[1], self.hover_z), task
        cx = car[1] + self.lead * self.car_velocity[0]
        cy = car[2] + self.lead * self.car_velocity[1]
        distance = math.hypot(uav[0] - car[1], uav[1] - car[2])
        if self.commanded == TASK and self.climb is not None:
            top = car[3] + self.approach
            if uav[2] < top - self.landing_radius:  # going around: straight up
                goal = (car[1] + self.climb[0], car[2] + self.climb[1], top)
                return self.commanded, goal, task
            self.climb = None  # back at the pursuit height: the platform drives on (after
            task = TASK_TRACK  # a stop too), and the UAV pursues it
        if self.commanded == TASK:
            # over the platform at the pursuit height (after a landing called off the UAV
            # climbs back first: a landing begun in the climb starts off the platform's pace)
            level = abs(uav[2] - car[3] - self.approach) <= self.landing_radius
            if distance <= self.landing_radius and level:
                if self.within_since is None:
                    self.within_since = t
                if t - self.within_since >= self.landing_time:
                    self._go(LAND, t)
                    self.land_z = car[3] + self.approach
                    self.touch_since, self.descended = None, False
                    task = TASK_LAND
            else:
                self.within_since = None
            return self.commanded, (cx, cy, car[3] + self.approach), task
        if self.commanded == LAND:
            self.land_z -= self.land_speed / 20.0
            if t < self.turning_until and uav[2] - car[3] > self.commit:
                # the platform turns in place: its surface would sweep the legs sideways at
                # the touchdown; wait over it until it drives straight again (unless it
                # touched down already: climbing off the turning surface would slide on it)
                self.land_z = max(self.land_z, car[3] + self.hold)
                self.descended = False
            else:
                self.descended = self.descended or vz < -0.1
            if self.descended and abs(vz) < 0.05 and uav[2] > self.land_z + 0.1:
                self.touch_since = self.touch_since if self.touch_since is not None else t
                if t - self.touch_since >= 0.3:
                    self._go(SHUTDOWN, t)
                    return self.commanded, None, TASK_STOP
            else:
                self.touch_since = None
            return self.commanded, (cx, cy, self.land_z), None
        return self.commanded, None, None


# -- the referee ------------------------------------------------------------------------------


@dataclass
class Referee:
    """How a run ends (Table 5.1): ``landed``, ``crashed``, ``landed_elsewhere``,
    ``timeout``; and whether that is a success in its scenario."""

    scenario: str
    timeout: float
    rested_since: float | None = None
    reinitiated: int = 0
    """Landings called off: the controller told the platform it tracks it again (task 1)
    after it had begun a landing (task 2), whether or not the UAV had touched down."""
    landing: bool = False
    """A landing has begun and was not called off since."""
    was_resting: bool = False
    outcome: str | None = None
    detail: str = ""

    def step(self, t: float, uav: Uav, motors: bool) -> str | None:
        if self.outcome is not None:
            return self.outcome
        if uav.broken is not None:
            return self._end("crashed", uav.broken)
        resting = uav.resting is not None and not motors and t > 3.0
        if resting and not self.was_resting:
            self.rested_since = t
        if not resting and self.was_resting:
            self.rested_since = None
        self.was_resting = resting
        if resting and self.rested_since is not None and t - self.rested_since >= 5.0:
            if uav.resting == "platform":
                return self._end("landed", "motors off on the platform for 5 s")
            return self._end("landed_elsewhere", f"motors off on the {uav.resting} for 5 s")
        if t >= self.timeout:
            return self._end("timeout", f"no landing in {self.timeout:g} s")
        return None

    def task(self, task: int) -> None:
        """A task the platform was given (``/a/car_drive``): counts the called-off landings."""
        if task == TASK_LAND:
            self.landing = True
        elif task == TASK_TRACK and self.landing:
            self.reinitiated += 1
            self.landing = False

    def _end(self, outcome: str, detail: str) -> str:
        self.outcome, self.detail = outcome, detail
        return outcome

    @property
    def success(self) -> bool:
        if self.scenario in AVOID_LANDING:
            return self.outcome in ("timeout",)
        return self.outcome == "landed"


@dataclass
class World:
    """Platform, UAV, wind and referee of one trial, stepped at :data:`DT`."""

    scenario: str
    seed: int
    timeout: float = 120.0
    t: float = 0.0
    rng: random.Random = field(init=False)
    platform: Platform = field(init=False)
    uav: Uav = field(init=False)
    wind: Wind = field(init=False)
    referee: Referee = field(init=False)
    command: Command = field(default_factory=Command)
    onset: float | None = None
    """When the scenario's fault first acted on the system (simulated s; None: not yet, or
    no fault): see :meth:`_fault_acts`."""
    outwash: tuple[float, float] = (0.0, 0.0)
    """The rotors' downwash coming back off the surface under the UAV (its own random
    draws: the other scenarios' draws are unchanged): :data:`GROUND_EFFECT_AIR`."""
    air: random.Random = field(init=False)

    def __post_init__(self) -> None:
        if self.scenario not in SCENARIOS:
            raise ValueError(f"unknown scenario {self.scenario!r}; one of {', '.join(SCENARIOS)}")
        self.rng = random.Random(self.seed)
        self.platform = Platform.start(self.rng)
        self.platform.present = self.scenario != "false_airport"
        while True:
            x, y = self.rng.uniform(-3.0, 3.0), self.rng.uniform(-3.0, 3.0)
            if math.hypot(x - self.platform.x, y - self.platform.y) > 1.5:
                break
        self.uav = Uav(x=x, y=y)
        self.wind = Wind(self.rng, enabled=self.scenario == "wind")
        if self.scenario == "fragile":  # drawn last: the other scenarios' draws are unchanged
            self.platform.safe = (self.rng.choice((-1, 1)), self.rng.choice((-1, 1)))
        self.referee = Referee(self.scenario, self.timeout)
        self.air = random.Random(self.seed + 7_919)

    @property
    def occupied(self) -> bool:
        return self.scenario == "occupied"

    def drive(self, task: int) -> None:
        """A task for the platform (``/a/car_drive``, what ``/a/execute_task`` passes on):
        3 (stop) stops it where it is; 0 and 1 (wander, track: the controller tracks it
        again after a landing it called off, or the monitor's safe task) send it on its
        vacuum pattern again, from a standstill; 2 (land) changes nothing."""
        if task == TASK_STOP:
            self.platform.moving = False
        elif task in (TASK_WANDER, TASK_TRACK):
            self.platform.moving = True
        self.referee.task(task)

    def step(self) -> str | None:
        """One physics step; the run's outcome once it is over."""
        self.t += DT
        self.wind.step(DT)
        self.platform.step(DT)
        wind = self.wind.at(self.uav.x, self.uav.y)
        self.uav.step(DT, self.command, self._ground_effect(wind), self.platform, self.occupied)
        if self.scenario == "fragile":
            self._load_fragile_platform()
        if self.onset is None and self._fault_acts():
            self.onset = self.t
        return self.referee.step(self.t, self.uav, self.command.motors)

    def _ground_effect(self, wind: tuple[float, float]) -> tuple[float, float]:
        """The air around the UAV: the wind, and near a surface the rotors' outwash (an
        Ornstein-Uhlenbeck process, time constant 0.3 s, drawn every step)."""
        tau, (ox, oy) = 0.3, self.outwash
        kick = GROUND_EFFECT_AIR * math.sqrt(2.0 * DT / tau)
        ox += -ox * DT / tau + kick * self.air.gauss(0.0, 1.0)
        oy += -oy * DT / tau + kick * self.air.gauss(0.0, 1.0)
        self.outwash = (ox, oy)
        uav = self.uav
        height = uav.z - UAV_REST - uav.surface(self.platform, self.occupied)[0]
        if uav.resting is not None or not self.command.motors or height >= GROUND_EFFECT_HEIGHT:
            return wind
        near = 1.0 - max(height, 0.0) / GROUND_EFFECT_HEIGHT
        return wind[0] + near * ox, wind[1] + near * oy

    def _load_fragile_platform(self) -> None:
        """The fragile platform starts to tip when the UAV rests on it outside its safe
        quadrant (:attr:`Platform.safe`), towards where it rests, and rights itself once the
        UAV has lifted off."""
        platform = self.platform
        if self.uav.resting != "platform":
            platform.tipping = None
        elif platform.tipping is None:
            u, v = platform.local(self.uav.x, self.uav.y)
            if not (u * platform.safe[0] > 0.0 and v * platform.safe[1] > 0.0):
                platform.tipping = (
                    math.copysign(TIP_ANGLE, -v or 1.0),
                    math.copysign(TIP_ANGLE, u or 1.0),
                )

    def _fault_acts(self) -> bool:
        """Whether the scenario's fault acts on the system now: the first moment it changes
        what the nodes see or what the UAV does, not the moment it is set up. The wind when a
        gust of 8 km/h or more first blows on the airborne UAV; the occupied platform when
        the UAV touches the object (rests on it or crashes onto it); the fragile one when it
        starts to tip; the slowed link in its first slow stretch (``car.py``: 5 s in every
        10 s); the thief when the platform enters the upper half (``thief.py``); the false
        airport from the start (its pose is never the vehicle's)."""
        name = self.scenario
        if name == "wind":  # a gust of Table 5.1's 8 km/h or more on the airborne UAV
            return (
                self.uav.resting is None
                and math.hypot(*self.wind.at(self.uav.x, self.uav.y)) >= 2.2
            )
        if name == "occupied":  # resting on the object, or broken touching it
            return self.uav.resting == "object" or "object" in (self.uav.broken or "")
        if name == "fragile":
            return self.platform.tipping is not None
        if name == "slowed":
            return self.t % 10.0 >= 5.0
        if name == "stealing":
            return self.platform.y > 0.0
        return name == "false_airport"


def offline_trial(scenario: str, seed: int, timeout: float = 120.0) -> Referee:
    """One trial without ROS: the nodes' logic at their rates (controller 20 Hz, position
    loop 50 Hz, physics 100 Hz) on exact poses, without transport delays; the false airport's
    pose and the thief's as ``/a/car`` and ``/a/thief`` send them. For tests: the live system
    (``sim.py`` and the other nodes) adds the ROS graph's timing to the same code."""
    world = World(scenario, seed, timeout=timeout)
    control, loop = LandingController(), Attitude()
    rng = random.Random(seed + 17)
    fake = (rng.uniform(-2.5, 2.5), rng.uniform(-2.5, 2.5))
    state, waypoint, step = STARTUP, None, 0
    while True:
        step += 1
        uav, platform = world.uav, world.platform
        if step % 5 == 0:
            car = (platform.x, platform.y, PLATFORM_TOP, platform.heading)
            if scenario == "false_airport":
                control.see_car(world.t, fake[0], fake[1], PLATFORM_TOP, 0.0)
            elif scenario == "slowed" and world.t % 10.0 >= 5.0:
                if control.last_car is None or world.t - control.last_car[0] >= 2.0:
                    control.see_car(world.t, *car)
            else:
                control.see_car(world.t, *car)
                if scenario == "stealing" and platform.y > 0.0:  # mirrored, same heading
                    mirrored = (platform.x, -platform.y, PLATFORM_TOP, platform.heading)
                    control.see_car(world.t + 1e-3, *mirrored)
            state, waypoint, task = control.step(world.t, state, (uav.x, uav.y, uav.z), uav.vz)
            if waypoint is not None:
                loop.see_waypoint(world.t, *waypoint)
            if task is not None:
                world.drive(task)
        if step % 2 == 0:
            world.command = loop.command(
                state, waypoint, (uav.x, uav.y, uav.z), (uav.vx, uav.vy, uav.vz), world.t
            )
        if world.step() is not None:
            return world.referee
