"""Reference trajectories for the navigator: smooth, speed-, acceleration- and jerk-limited straight motion.

The navigator strings pieces together into a `Trajectory`: a yaw turn while hovering, a straight leg between
two points that starts and ends at rest, a vertical landing descent, and a brake to rest when a mode change
interrupts a moving reference. Each piece is precomputed once and evaluated in closed form at any time, with
plain floats: the vehicle samples the reference at 50 Hz and must run many times faster than real time.

The one-dimensional motion along a piece is a `Profile1D`: a chain of constant-jerk spans, so position is a
cubic in time. The spans come from uavcore.motion_profiles, which the route energy model (planner.energy) shares.
A rest-to-rest leg is the classic seven-span jerk-limited S-curve (jerk +J, 0, -J, cruise, -J, 0, +J); with an
infinite jerk limit the same code gives a trapezoidal velocity profile. Frames are NED metres
(z down) and yaw is atan2(east, north) in [-pi, pi), as in uavcore.state.
"""

from __future__ import annotations

import math
from bisect import bisect_right
from dataclasses import dataclass
from typing import NamedTuple, Protocol

from uavcore.motion_profiles import MIN_DISTANCE_M, Span, descent_spans, rest_to_rest_spans
from uavcore.rotation import wrap_pi

Vector3 = tuple[float, float, float]
ZERO3: Vector3 = (0.0, 0.0, 0.0)

# Below this length a leg is "no motion" and below this horizontal length a leg has no heading to turn to.
MIN_LEG_LENGTH_M = MIN_DISTANCE_M
MIN_HEADING_LENGTH_M = 0.5


class NavigationError(ValueError):
    """A limit or request the navigator cannot fly (non-positive speed, unknown item, no mission, ...)."""


class ReferenceSample(NamedTuple):
    """The reference at one instant: what becomes POSITION_TARGET_LOCAL_NED."""

    position: Vector3
    velocity: Vector3
    acceleration: Vector3
    yaw: float
    yaw_rate: float


@dataclass(frozen=True)
class MotionLimits:
    """Limits of a straight-line motion; jerk may be math.inf for a trapezoidal velocity profile."""

    horizontal_speed: float
    climb_speed: float
    descent_speed: float
    acceleration: float
    jerk: float

    def speed_along(self, direction: Vector3) -> float:
        """The fastest speed along a unit direction that keeps each component within its own limit."""
        horizontal = math.hypot(direction[0], direction[1])
        vertical = direction[2]
        speed = math.inf
        if horizontal > 1e-12:
            speed = self.horizontal_speed / horizontal
        if vertical < -1e-12:  # up is -z
            speed = min(speed, self.climb_speed / -vertical)
        elif vertical > 1e-12:
            speed = min(speed, self.descent_speed / vertical)
        return speed


class Profile1D:
    """Distance along a path as a function of time: a chain of constant-jerk spans, evaluated in closed form.

    Each span is (duration, acceleration at its start, jerk); speed and distance carry over from one span to
    the next. After the last span the profile holds its final distance and speed (zero for every profile the
    navigator builds).
    """

    def __init__(
        self,
        spans: list[Span],
        initial_speed: float = 0.0,
        distance: float | None = None,
    ) -> None:
        self._spans = [span for span in spans if span[0] > 0.0]
        self._starts: list[float] = []
        self._states: list[tuple[float, float]] = []  # (distance, speed) at each span's start
        t, s, v = 0.0, 0.0, initial_speed
        for duration, a0, jerk in self._spans:
            self._starts.append(t)
            self._states.append((s, v))
            s += v * duration + a0 * duration**2 / 2 + jerk * duration**3 / 6
            v += a0 * duration + jerk * duration**2 / 2
            t += duration
        self.duration = t
        # The closing speed is zero up to rounding: snap it, and the distance when the caller knows it.
        self.final_speed = 0.0 if abs(v) < 1e-9 else v
        self.distance = s if distance is None else distance

    @classmethod
    def rest_to_rest(cls, distance: float, max_speed: float, acceleration: float, jerk: float) -> Profile1D:
        """The time-optimal jerk-limited S-curve covering `distance` from rest to rest."""
        return cls(rest_to_rest_spans(distance, max_speed, acceleration, jerk), distance=max(distance, 0.0))

    @classmethod
    def brake(cls, speed: float, acceleration: float) -> Profile1D:
        """From `speed` to rest at full deceleration (an acceleration step: only to interrupt a motion)."""
        return cls([(speed / acceleration, -acceleration, 0.0)], initial_speed=speed)

    @classmethod
    def descent(
        cls,
        height: float,
        depth: float,
        fast_speed: float,
        slow_speed: float,
        slow_below: float,
        acceleration: float,
        jerk: float,
    ) -> Profile1D:
        """A landing: fast_speed down to `slow_below` metres, then slow_speed on to `depth` under the ground,
        never stopping on the way (uavcore.motion_profiles.descent_spans)."""
        total = max(height, 0.0) + depth
        spans = descent_spans(height, depth, fast_speed, slow_speed, slow_below, acceleration, jerk)
        return cls(spans, distance=max(total, 0.0))

    def sample(self, t: float) -> tuple[float, float, float]:
        """(distance, speed, acceleration) at time t from the profile's start."""
        if t >= self.duration:
            return self.distance, self.final_speed, 0.0
        if t <= 0.0:
            return (
                0.0,
                (self._states[0][1] if self._states else 0.0),
                (self._spans[0][1] if self._spans else 0.0),
            )
        i = bisect_right(self._starts, t) - 1
        _duration, a0, jerk = self._spans[i]
        s0, v0 = self._states[i]
        tau = t - self._starts[i]
        return (
            s0 + v0 * tau + a0 * tau * tau / 2 + jerk * tau**3 / 6,
            v0 + a0 * tau + jerk * tau * tau / 2,
            a0 + jerk * tau,
        )

    def time_at(self, distance: float) -> float:
        """The first time the profile has covered `distance` (bisection: profiles never move backwards)."""
        if distance <= 0.0:
            return 0.0
        if distance >= self.distance:
            return self.duration
        low, high = 0.0, self.duration
        for _ in range(60):
            middle = (low + high) / 2
            if self.sample(middle)[0] < distance:
                low = middle
            else:
                high = middle
        return high


class Segment(Protocol):
    duration: float
    end_position: Vector3
    end_yaw: float

    def sample(self, t: float) -> ReferenceSample:
        """The reference at time t from the segment's start (0 <= t <= duration)."""
        ...


class LineSegment:
    """Motion from `start` along a unit `direction`, the distance given by a profile; yaw fixed."""

    def __init__(
        self, start: Vector3, direction: Vector3, profile: Profile1D, yaw: float, end: Vector3 | None = None
    ) -> None:
        self.start, self.direction, self.profile, self.yaw = start, direction, profile, yaw
        self.duration = profile.duration
        self.end_position = end if end is not None else _along(start, direction, profile.distance)
        self.end_yaw = yaw

    def sample(self, t: float) -> ReferenceSample:
        if t >= self.duration:
            return ReferenceSample(self.end_position, ZERO3, ZERO3, self.yaw, 0.0)
        s, v, a = self.profile.sample(t)
        ux, uy, uz = self.direction
        return ReferenceSample(
            _along(self.start, self.direction, s),
            (ux * v, uy * v, uz * v),
            (ux * a, uy * a, uz * a),
            self.yaw,
            0.0,
        )


class YawTurn:
    """Hovering at a point while yaw turns the short way round at a limited rate and acceleration."""

    def __init__(self, position: Vector3, yaw_from: float, yaw_to: float, rate: float, acceleration: float) -> None:
        delta = wrap_pi(yaw_to - yaw_from)
        self.position, self.yaw_from = position, yaw_from
        self.sign = 1.0 if delta >= 0 else -1.0
        # jerk is unlimited for yaw: the yaw rate ramps linearly (a trapezoid); the attitude loop follows it
        self.profile = Profile1D.rest_to_rest(abs(delta), rate, acceleration, math.inf)
        self.duration = self.profile.duration
        self.end_position = position
        self.end_yaw = wrap_pi(yaw_to)

    def sample(self, t: float) -> ReferenceSample:
        if t >= self.duration:
            return ReferenceSample(self.position, ZERO3, ZERO3, self.end_yaw, 0.0)
        angle, rate, _ = self.profile.sample(t)
        return ReferenceSample(
            self.position, ZERO3, ZERO3, wrap_pi(self.yaw_from + self.sign * angle), self.sign * rate
        )


def _along(start: Vector3, direction: Vector3, s: float) -> Vector3:
    return (start[0] + direction[0] * s, start[1] + direction[1] * s, start[2] + direction[2] * s)


def bearing(start: Vector3, end: Vector3) -> float | None:
    """Yaw from start toward end in NED (atan2(east, north)), or None when they are horizontally too close."""
    north, east = end[0] - start[0], end[1] - start[1]
    if math.hypot(north, east) < MIN_HEADING_LENGTH_M:
        return None
    return math.atan2(east, north)


class Trajectory:
    """A chain of segments starting at time t0; holds the last segment's end state once they are all flown."""

    def __init__(self, t0: float, position: Vector3, yaw: float) -> None:
        self.start_time = t0
        self.end_time = t0
        self.end_position = position
        self.end_yaw = wrap_pi(yaw)
        self._segments: list[Segment] = []
        self._starts: list[float] = []

    def _append(self, segment: Segment) -> float:
        """Add a segment; returns the absolute time it starts."""
        start = self.end_time
        if segment.duration > 0.0:
            self._segments.append(segment)
            self._starts.append(start)
            self.end_time = start + segment.duration
        self.end_position = segment.end_position
        self.end_yaw = segment.end_yaw
        return start

    def append(self, segment: Segment) -> None:
        """Add a segment of another kind (e.g. sitl_quad.orbit's endless circle) after the chain."""
        self._append(segment)

    def turn_to(self, yaw: float, rate: float, acceleration: float) -> None:
        """Turn on the spot to `yaw` (the short way)."""
        self._append(YawTurn(self.end_position, self.end_yaw, yaw, rate, acceleration))

    def line_to(self, target: Vector3, limits: MotionLimits) -> None:
        """Fly a straight line to `target`, from rest to rest, yaw unchanged."""
        start = self.end_position
        delta = (target[0] - start[0], target[1] - start[1], target[2] - start[2])
        length = math.sqrt(delta[0] ** 2 + delta[1] ** 2 + delta[2] ** 2)
        if length <= MIN_LEG_LENGTH_M:
            self.end_position = target
            return
        direction = (delta[0] / length, delta[1] / length, delta[2] / length)
        profile = Profile1D.rest_to_rest(length, limits.speed_along(direction), limits.acceleration, limits.jerk)
        self._append(LineSegment(start, direction, profile, self.end_yaw, end=target))

    def brake(self, velocity: Vector3, acceleration: float) -> None:
        """Come to rest from `velocity` along its own direction."""
        speed = math.sqrt(velocity[0] ** 2 + velocity[1] ** 2 + velocity[2] ** 2)
        if speed <= 1e-9:
            return
        direction = (velocity[0] / speed, velocity[1] / speed, velocity[2] / speed)
        self._append(LineSegment(self.end_position, direction, Profile1D.brake(speed, acceleration), self.end_yaw))

    def descend(
        self,
        ground_down: float,
        depth: float,
        fast_speed: float,
        slow_speed: float,
        slow_below: float,
        acceleration: float,
        jerk: float,
    ) -> tuple[float, float]:
        """Descend vertically to `depth` metres below the ground at z = ground_down.

        Returns (the absolute time the descent starts, the time its reference reaches the ground).
        """
        start = self.end_position
        height = ground_down - start[2]
        profile = Profile1D.descent(height, depth, fast_speed, slow_speed, slow_below, acceleration, jerk)
        begin = self._append(LineSegment(start, (0.0, 0.0, 1.0), profile, self.end_yaw))
        return begin, begin + profile.time_at(max(height, 0.0))

    def sample(self, t: float) -> ReferenceSample:
        if not self._segments or t >= self.end_time:
            return ReferenceSample(self.end_position, ZERO3, ZERO3, self.end_yaw, 0.0)
        i = max(bisect_right(self._starts, t) - 1, 0)
        return self._segments[i].sample(t - self._starts[i])

    def finished(self, t: float) -> bool:
        return t >= self.end_time
