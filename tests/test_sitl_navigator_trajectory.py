"""The navigator's building blocks: jerk-limited profiles, yaw turns, landing descents, trajectories."""

from __future__ import annotations

import itertools
import math

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from sitl_quad.trajectory import MotionLimits, Profile1D, Trajectory, YawTurn

DT = 0.001


def sampled(profile: Profile1D, dt: float = DT) -> list[tuple[float, float, float]]:
    steps = int(profile.duration / dt) + 2
    return [profile.sample(k * dt) for k in range(steps)]


def assert_within_limits(profile: Profile1D, max_speed: float, acceleration: float, jerk: float) -> None:
    samples = sampled(profile)
    assert max(v for _, v, _ in samples) <= max_speed * (1 + 1e-9)
    assert min(v for _, v, _ in samples) >= -1e-9, "the profile never moves backwards"
    assert max(abs(a) for _, _, a in samples) <= acceleration * (1 + 1e-9)
    if math.isfinite(jerk):
        jerks = [abs(b[2] - a[2]) / DT for a, b in itertools.pairwise(samples)]
        assert max(jerks) <= jerk * (1 + 1e-6)


@pytest.mark.parametrize("distance", [0.05, 1.0, 3.0, 20.0, 150.0, 1000.0])
@pytest.mark.parametrize("jerk", [4.0, math.inf])
def test_rest_to_rest_stays_within_limits_and_ends_at_rest_on_target(distance: float, jerk: float) -> None:
    profile = Profile1D.rest_to_rest(distance, 10.0, 3.0, jerk)
    assert_within_limits(profile, 10.0, 3.0, jerk)
    assert profile.sample(0.0)[:2] == (0.0, 0.0)
    assert profile.sample(profile.duration) == (distance, 0.0, 0.0)
    # just before the end it is already almost there and almost stopped: no jump at the end
    s, v, _ = profile.sample(profile.duration - 1e-6)
    assert s == pytest.approx(distance, abs=1e-6)
    assert v == pytest.approx(0.0, abs=1e-5)


def test_rest_to_rest_derivatives_are_consistent() -> None:
    profile = Profile1D.rest_to_rest(80.0, 10.0, 3.0, 4.0)
    h = 1e-4
    for k in range(1, 200):
        t = profile.duration * k / 200
        s_before, v_before, _ = profile.sample(t - h)
        s_after, v_after, _ = profile.sample(t + h)
        _, v, a = profile.sample(t)
        assert (s_after - s_before) / (2 * h) == pytest.approx(v, abs=1e-6)
        assert (v_after - v_before) / (2 * h) == pytest.approx(a, abs=1e-3)


def test_long_leg_takes_the_closed_form_s_curve_time() -> None:
    # cruise reached with the acceleration limit reached: T = D/V + V/A + A/J
    distance, speed, acceleration, jerk = 500.0, 10.0, 3.0, 4.0
    profile = Profile1D.rest_to_rest(distance, speed, acceleration, jerk)
    assert profile.duration == pytest.approx(distance / speed + speed / acceleration + acceleration / jerk)
    trapezoid = Profile1D.rest_to_rest(distance, speed, acceleration, math.inf)
    assert trapezoid.duration == pytest.approx(distance / speed + speed / acceleration)


def test_short_leg_never_reaches_cruise_speed() -> None:
    profile = Profile1D.rest_to_rest(2.0, 10.0, 3.0, 4.0)
    peak = max(v for _, v, _ in sampled(profile))
    assert peak < 3.0
    # the peak is in the middle, by symmetry
    assert profile.sample(profile.duration / 2)[0] == pytest.approx(1.0, abs=1e-9)


@settings(max_examples=60, deadline=None)
@given(
    distance=st.floats(0.01, 2000.0),
    speed=st.floats(0.2, 20.0),
    acceleration=st.floats(0.5, 8.0),
    jerk=st.one_of(st.just(math.inf), st.floats(0.5, 40.0)),
)
def test_rest_to_rest_property(distance: float, speed: float, acceleration: float, jerk: float) -> None:
    profile = Profile1D.rest_to_rest(distance, speed, acceleration, jerk)
    assert profile.sample(profile.duration) == (distance, 0.0, 0.0)
    # coarse sampling suffices for the bounds: each span is a low-order polynomial checked at many points
    samples = [profile.sample(profile.duration * k / 400) for k in range(401)]
    assert max(v for _, v, _ in samples) <= speed * (1 + 1e-9)
    assert max(abs(a) for _, _, a in samples) <= acceleration * (1 + 1e-9)
    assert all(b[0] >= a[0] - 1e-9 for a, b in itertools.pairwise(samples))
    assert samples[-2][0] <= distance + 1e-9


def test_descent_runs_fast_high_up_and_at_land_speed_near_the_ground() -> None:
    height, depth = 20.0, 0.5
    profile = Profile1D.descent(height, depth, 1.5, 0.7, 5.0, 3.0, 4.0)
    assert_within_limits(profile, 1.5, 3.0, 4.0)
    assert profile.sample(profile.duration) == (height + depth, 0.0, 0.0)
    assert max(v for _, v, _ in sampled(profile)) == pytest.approx(1.5)
    # below the slow-down height (5 m above ground = 15 m down) it is at land speed, never stopping before
    for distance in (15.0, 17.0, height):
        _, v, _ = profile.sample(profile.time_at(distance))
        assert v == pytest.approx(0.7, abs=1e-6)
    assert min(v for s, v, _ in sampled(profile) if 0.5 < s < height) > 0.6


def test_low_descent_runs_at_land_speed_throughout() -> None:
    profile = Profile1D.descent(3.0, 0.5, 1.5, 0.7, 5.0, 3.0, 4.0)
    assert max(v for _, v, _ in sampled(profile)) == pytest.approx(0.7)
    assert profile.sample(profile.time_at(3.0))[1] == pytest.approx(0.7)


def test_limits_along_a_direction_respect_each_axis() -> None:
    limits = MotionLimits(horizontal_speed=10.0, climb_speed=2.5, descent_speed=1.5, acceleration=3.0, jerk=4.0)
    assert limits.speed_along((1.0, 0.0, 0.0)) == pytest.approx(10.0)
    assert limits.speed_along((0.0, 0.0, -1.0)) == pytest.approx(2.5)
    assert limits.speed_along((0.0, 0.0, 1.0)) == pytest.approx(1.5)
    diagonal = (math.sqrt(0.5), 0.0, -math.sqrt(0.5))  # 45 degrees up: the climb limit binds
    speed = limits.speed_along(diagonal)
    assert speed * math.sqrt(0.5) == pytest.approx(2.5)


@pytest.mark.parametrize(
    ("yaw_from", "yaw_to", "turn"),
    [
        (math.radians(170), math.radians(-170), math.radians(20)),
        (math.radians(-170), math.radians(170), math.radians(-20)),
        (0.0, math.radians(90), math.radians(90)),
        (math.radians(10), math.radians(-100), math.radians(-110)),
    ],
)
def test_yaw_turn_goes_the_short_way_and_wraps(yaw_from: float, yaw_to: float, turn: float) -> None:
    rate, acceleration = math.radians(60), math.radians(90)
    segment = YawTurn((1.0, 2.0, -5.0), yaw_from, yaw_to, rate, acceleration)
    assert segment.duration == pytest.approx(Profile1D.rest_to_rest(abs(turn), rate, acceleration, math.inf).duration)
    steps = int(segment.duration / 0.01) + 2
    yaws = [segment.sample(k * 0.01).yaw for k in range(steps)]
    assert all(-math.pi <= y < math.pi for y in yaws)
    swept = sum(math.remainder(b - a, math.tau) for a, b in itertools.pairwise(yaws))
    assert swept == pytest.approx(turn, abs=1e-9)
    assert max(abs(segment.sample(k * 0.01).yaw_rate) for k in range(steps)) <= rate * (1 + 1e-9)
    assert all(segment.sample(k * 0.01).position == (1.0, 2.0, -5.0) for k in range(steps))
    assert math.remainder(yaws[-1] - yaw_to, math.tau) == pytest.approx(0.0, abs=1e-12)


def test_trajectory_chains_segments_continuously_and_holds_at_the_end() -> None:
    limits = MotionLimits(10.0, 2.5, 1.5, 3.0, 4.0)
    trajectory = Trajectory(5.0, (0.0, 0.0, -5.0), 0.0)
    trajectory.turn_to(math.radians(90), math.radians(60), math.radians(90))
    trajectory.line_to((0.0, 50.0, -5.0), limits)
    trajectory.brake((0.0, 0.0, 0.0), 3.0)  # at rest: nothing to add
    samples = [trajectory.sample(5.0 + k * 0.01) for k in range(int((trajectory.end_time - 5.0) / 0.01) + 200)]
    for a, b in itertools.pairwise(samples):
        step = math.dist(a.position, b.position)
        assert step <= 10.0 * 0.01 + 1e-9
    assert samples[-1].position == (0.0, 50.0, -5.0)
    assert samples[-1].velocity == (0.0, 0.0, 0.0)
    assert trajectory.finished(trajectory.end_time) and not trajectory.finished(trajectory.end_time - 0.01)


def test_brake_stops_a_moving_reference_within_the_acceleration_limit() -> None:
    trajectory = Trajectory(0.0, (0.0, 0.0, -5.0), 0.0)
    trajectory.brake((6.0, 8.0, 0.0), 3.0)
    assert trajectory.end_time == pytest.approx(10.0 / 3.0)
    start = trajectory.sample(0.0)
    assert start.velocity == pytest.approx((6.0, 8.0, 0.0))
    assert math.hypot(*start.acceleration) == pytest.approx(3.0)
    end = trajectory.sample(trajectory.end_time)
    assert math.dist(end.position, (0.0, 0.0, -5.0)) == pytest.approx(10.0**2 / (2 * 3.0))
