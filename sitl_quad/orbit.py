"""MAV_CMD_DO_ORBIT's circle as a reference for the position loop, as PX4's FlightTaskOrbit flies it.

An orbit is a horizontal circle (centre, radius, altitude) flown at a tangential speed, clockwise seen from
above for a positive radius, with the heading chosen by ORBIT_YAW_BEHAVIOUR. The navigator first flies a
straight leg to the nearest point of the circle (sitl_quad.navigator), then appends an `OrbitSegment`, which
never ends: the orbit lasts until another mode or command replaces it.

On the circle the angle from the centre is theta = atan2(east, north), so clockwise is increasing theta. The
tangential speed ramps up from rest at a constant tangential acceleration, then stays; with s(t) the arc length
flown, the reference is (NED, centre c, radius r, direction d = +1 clockwise, -1 counter-clockwise):

    p = c + r (cos theta, sin theta),  theta = theta0 + d s / r
    v = d s' (-sin theta, cos theta)
    a = d s'' (-sin theta, cos theta) - (s'^2 / r) (cos theta, sin theta)   (tangential + centripetal)

and the speed is capped so that the centripetal acceleration s'^2 / r stays within the horizontal acceleration
limit (`max_orbit_speed`). Pure computation.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from enum import IntEnum

from sitl_quad.trajectory import ZERO3, ReferenceSample, Vector3
from uavcore.rotation import wrap_pi

DEFAULT_RADIUS_M = 10.0  # a DO_ORBIT without a radius (NaN) and no orbit under way
DEFAULT_SPEED_M_S = 1.0  # a DO_ORBIT without a velocity (NaN) and no orbit under way
MIN_RADIUS_M = 1.0  # PX4's FlightTaskOrbit refuses tighter circles
MAX_RADIUS_M = 1000.0  # PX4's MC_ORBIT_RAD_MAX default


class OrbitYaw(IntEnum):
    """ORBIT_YAW_BEHAVIOUR (DO_ORBIT param3)."""

    HOLD_FRONT_TO_CIRCLE_CENTER = 0
    HOLD_INITIAL_HEADING = 1
    UNCONTROLLED = 2
    HOLD_FRONT_TANGENT_TO_CIRCLE = 3
    RC_CONTROLLED = 4
    UNCHANGED = 5


@dataclass(frozen=True)
class Orbit:
    """One circle to fly: centre (north, east m), altitude (down, m), radius, tangential speed, direction."""

    center: tuple[float, float]
    down: float
    radius: float
    speed: float
    clockwise: bool
    yaw: OrbitYaw = OrbitYaw.HOLD_FRONT_TO_CIRCLE_CENTER

    @property
    def direction(self) -> float:
        return 1.0 if self.clockwise else -1.0

    def angle_of(self, north: float, east: float) -> float:
        """The angle from the centre toward a point (0 at the centre itself)."""
        dn, de = north - self.center[0], east - self.center[1]
        return math.atan2(de, dn) if math.hypot(dn, de) > 1e-9 else 0.0

    def point_at(self, angle: float) -> Vector3:
        return (
            self.center[0] + self.radius * math.cos(angle),
            self.center[1] + self.radius * math.sin(angle),
            self.down,
        )

    def heading_at(self, angle: float, initial_heading: float) -> float:
        """The yaw the behaviour asks for at an angle on the circle."""
        if self.yaw == OrbitYaw.HOLD_FRONT_TO_CIRCLE_CENTER:
            return wrap_pi(angle + math.pi)
        if self.yaw == OrbitYaw.HOLD_FRONT_TANGENT_TO_CIRCLE:
            return wrap_pi(angle + self.direction * math.pi / 2)
        return wrap_pi(initial_heading)  # initial heading; without RC, "uncontrolled" and "RC" hold it too


def max_orbit_speed(radius: float, acceleration: float) -> float:
    """The fastest tangential speed whose centripetal acceleration v^2 / r stays within `acceleration`."""
    return math.sqrt(radius * acceleration)


class OrbitSegment:
    """The circle from `start_angle`, speeding up from rest at `acceleration` (m/s^2 along the circle); it has
    no end (duration infinite)."""

    duration = math.inf

    def __init__(self, orbit: Orbit, start_angle: float, initial_heading: float, acceleration: float) -> None:
        self.orbit = orbit
        self.start_angle = start_angle
        self.initial_heading = initial_heading
        self.acceleration = acceleration
        self.ramp_time = orbit.speed / acceleration
        self.end_position = orbit.point_at(start_angle)  # where it starts: a trajectory's "end" is its last goal
        self.end_yaw = orbit.heading_at(start_angle, initial_heading)

    def _arc(self, t: float) -> tuple[float, float, float]:
        """Arc length, speed and tangential acceleration t seconds after the start."""
        if t < self.ramp_time:
            return 0.5 * self.acceleration * t * t, self.acceleration * t, self.acceleration
        ramp_arc = 0.5 * self.acceleration * self.ramp_time**2
        return ramp_arc + self.orbit.speed * (t - self.ramp_time), self.orbit.speed, 0.0

    def sample(self, t: float) -> ReferenceSample:
        orbit = self.orbit
        d, r = orbit.direction, orbit.radius
        arc, speed, tangential = self._arc(t)
        angle = self.start_angle + d * arc / r
        c, s = math.cos(angle), math.sin(angle)
        centripetal = speed * speed / r
        position = orbit.point_at(angle)
        velocity = (-d * speed * s, d * speed * c, 0.0)
        acceleration = (-d * tangential * s - centripetal * c, d * tangential * c - centripetal * s, 0.0)
        turning = orbit.yaw in (OrbitYaw.HOLD_FRONT_TO_CIRCLE_CENTER, OrbitYaw.HOLD_FRONT_TANGENT_TO_CIRCLE)
        yaw_rate = d * speed / r if turning else 0.0
        yaw = orbit.heading_at(angle, self.initial_heading)
        return ReferenceSample(position, velocity if speed > 0 else ZERO3, acceleration, yaw, yaw_rate)


def orbit_from_command(
    current: Orbit | None,
    here: Vector3,
    radius: float,
    speed: float,
    yaw: float,
    center: tuple[float, float] | None,
    down: float | None,
    max_acceleration: float,
    max_speed: float,
) -> Orbit:
    """The circle a DO_ORBIT asks for, its NaN parameters filled as MAVLink says: the orbit under way's radius,
    speed, yaw behaviour and centre when there is one (`current`), else the defaults and the vehicle's own
    position `here` (NED) as centre; `center` / `down` None are NaN. The speed is capped by `max_speed` and by
    the centripetal limit. Raises ValueError for a radius outside [MIN_RADIUS_M, MAX_RADIUS_M] or an unknown
    yaw behaviour."""
    clockwise = current.clockwise if current is not None else True
    if math.isfinite(radius):
        clockwise = radius > 0
        radius = abs(radius)
    else:
        radius = current.radius if current is not None else DEFAULT_RADIUS_M
    if not MIN_RADIUS_M <= radius <= MAX_RADIUS_M:
        raise ValueError(f"orbit radius {radius} m is outside [{MIN_RADIUS_M}, {MAX_RADIUS_M}]")
    if math.isfinite(speed) and speed != 0:
        clockwise = clockwise == (speed > 0)  # a negative velocity reverses the direction, as in PX4
        speed = abs(speed)
    else:
        speed = current.speed if current is not None else DEFAULT_SPEED_M_S
    speed = min(speed, max_speed, max_orbit_speed(radius, max_acceleration))
    behaviour = OrbitYaw(int(yaw)) if math.isfinite(yaw) else OrbitYaw.HOLD_FRONT_TO_CIRCLE_CENTER
    if behaviour == OrbitYaw.UNCHANGED:
        behaviour = current.yaw if current is not None else OrbitYaw.HOLD_FRONT_TO_CIRCLE_CENTER
    if center is None:
        center = current.center if current is not None else (here[0], here[1])
    if down is None:
        down = current.down if current is not None else here[2]
    return Orbit(center, down, radius, speed, clockwise, behaviour)
