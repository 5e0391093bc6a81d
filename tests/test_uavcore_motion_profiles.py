"""The constant-jerk spans the navigator flies and the energy model prices (uavcore.motion_profiles): their
kinematics straight from the spans (Profile1D snaps its end, so its own tests cannot see a span chain that falls
short), and Profile1D agreeing with them."""

from __future__ import annotations

import math

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from sitl_quad.trajectory import Profile1D
from uavcore.motion_profiles import (
    MIN_DISTANCE_M,
    Span,
    descent_spans,
    ramp_distance,
    ramp_duration,
    ramp_spans,
    rest_to_rest_spans,
)

REL = 1e-9


def state_at(spans: list[Span], t: float, v0: float = 0.0) -> tuple[float, float, float]:
    """(distance, speed, acceleration) at time t, integrating span by span (after the end: the end state)."""
    s, v, a = 0.0, v0, 0.0
    for duration, a0, jerk in spans:
        tau = min(max(t, 0.0), duration)
        s, v, a = s + v * tau + a0 * tau**2 / 2 + jerk * tau**3 / 6, v + a0 * tau + jerk * tau**2 / 2, a0 + jerk * tau
        if t <= duration:
            return s, v, a
        t -= duration
    return s, v, 0.0


def grid(spans: list[Span], per_span: int = 40, v0: float = 0.0) -> list[tuple[float, float, float]]:
    """The state at per_span + 1 points through each span (each span is a low-order polynomial)."""
    starts = [sum(span[0] for span in spans[:i]) for i in range(len(spans))]
    return [
        state_at(spans, start + duration * k / per_span, v0)
        for start, (duration, _, _) in zip(starts, spans, strict=True)
        for k in range(per_span + 1)
    ]


def duration_of(spans: list[Span]) -> float:
    return sum(span[0] for span in spans)


def assert_rest_to_rest(spans: list[Span], distance: float, speed: float, acceleration: float, jerk: float) -> None:
    """Covers exactly `distance`, from rest to rest, within the limits, never backwards."""
    assert all(duration >= 0.0 for duration, _, _ in spans)
    end = state_at(spans, math.inf)
    assert end[0] == pytest.approx(distance, rel=REL)
    assert end[1] == pytest.approx(0.0, abs=1e-9 * speed)
    states = grid(spans)
    assert max(v for _, v, _ in states) <= speed * (1 + REL)
    assert min(v for _, v, _ in states) >= -1e-9 * speed
    assert max(abs(a) for _, _, a in states) <= acceleration * (1 + REL)
    assert all(abs(j) <= jerk for _, _, j in spans)
    if math.isfinite(jerk):  # the acceleration ramps from and back to zero
        assert states[0][2] == 0.0
        assert states[-1][2] == pytest.approx(0.0, abs=1e-9 * acceleration)


@pytest.mark.parametrize(("v_from", "v_to"), [(0.0, 10.0), (10.0, 0.0), (1.5, 0.7), (0.7, 1.5), (0.0, 0.5)])
@pytest.mark.parametrize("jerk", [4.0, 40.0, math.inf])
def test_a_ramp_changes_the_speed_within_the_limits_over_its_distance(v_from: float, v_to: float, jerk: float):
    spans = ramp_spans(v_from, v_to, 3.0, jerk)
    s, v, _ = state_at(spans, math.inf, v0=v_from)
    assert v == pytest.approx(v_to, abs=1e-12)
    assert s == pytest.approx(ramp_distance(v_from, v_to, 3.0, jerk), rel=1e-12)
    assert duration_of(spans) == pytest.approx(ramp_duration(abs(v_to - v_from), 3.0, jerk), rel=1e-15)
    assert max(abs(a) for _, _, a in grid(spans, v0=v_from)) <= 3.0 * (1 + REL)
    assert ramp_spans(2.0, 2.0, 3.0, jerk) == []


@pytest.mark.parametrize("distance", [2e-6, 0.05, 1.0, 3.0, 12.0, 20.0, 33.3, 150.0, 1000.0])
@pytest.mark.parametrize("jerk", [0.5, 4.0, 40.0, math.inf])
def test_rest_to_rest_covers_exactly_the_distance_within_the_limits(distance: float, jerk: float):
    assert_rest_to_rest(rest_to_rest_spans(distance, 10.0, 3.0, jerk), distance, 10.0, 3.0, jerk)


@settings(max_examples=80, deadline=None)
@given(
    distance=st.floats(1e-5, 2000.0),
    speed=st.floats(0.2, 20.0),
    acceleration=st.floats(0.5, 8.0),
    jerk=st.one_of(st.just(math.inf), st.floats(0.5, 40.0)),
)
def test_rest_to_rest_property(distance: float, speed: float, acceleration: float, jerk: float):
    assert_rest_to_rest(rest_to_rest_spans(distance, speed, acceleration, jerk), distance, speed, acceleration, jerk)


@pytest.mark.parametrize("jerk", [0.5, 4.0, math.inf])
@pytest.mark.parametrize("distance", [0.05, 1.0, 5.0, 30.0])
def test_a_short_move_peaks_below_the_speed_with_no_cruise(distance: float, jerk: float):
    """Too short to reach the speed: it peaks at the speed whose two ramps alone cover the distance."""
    speed = 20.0
    spans = rest_to_rest_spans(distance, speed, 3.0, jerk)
    peak = max(v for _, v, _ in grid(spans))
    assert peak < speed
    assert 2.0 * ramp_distance(0.0, peak, 3.0, jerk) == pytest.approx(distance, rel=1e-9)
    cruise = [duration for duration, a0, j in spans if a0 == 0.0 and j == 0.0]
    assert cruise == [pytest.approx(0.0, abs=1e-9)]


def test_no_move_has_no_spans():
    assert rest_to_rest_spans(MIN_DISTANCE_M, 10.0, 3.0, 4.0) == []
    assert rest_to_rest_spans(0.0, 10.0, 3.0, 4.0) == []
    assert rest_to_rest_spans(-1.0, 10.0, 3.0, 4.0) == []


@pytest.mark.parametrize("jerk", [4.0, math.inf])
def test_a_descent_runs_fast_then_slow_below_the_slow_down_height_to_rest_under_the_ground(jerk: float):
    height, depth, fast, slow, slow_below = 20.0, 0.5, 1.5, 0.7, 5.0
    spans = descent_spans(height, depth, fast, slow, slow_below, 3.0, jerk)
    assert_rest_to_rest(spans, height + depth, fast, 3.0, jerk)
    states = grid(spans)
    assert max(v for _, v, _ in states) == pytest.approx(fast)
    below = [v for s, v, _ in states if s >= height - slow_below]
    assert max(below) <= slow * (1 + REL)
    assert min(v for s, v, _ in states if height - slow_below <= s <= height) == pytest.approx(slow)


@pytest.mark.parametrize("height", [-1.0, 0.0, 3.0, 5.5])
def test_a_low_descent_is_a_rest_to_rest_move_at_the_slow_speed(height: float):
    spans = descent_spans(height, 0.5, 1.5, 0.7, 5.0, 3.0, 4.0)
    assert spans == rest_to_rest_spans(max(height, 0.0) + 0.5, 0.7, 3.0, 4.0)


@pytest.mark.parametrize("height", [3.0, 20.0])
def test_a_descent_to_touchdown_stops_where_the_reference_reaches_the_ground(height: float):
    args = (height, 0.5, 1.5, 0.7, 5.0, 3.0, 4.0)
    full, cut = descent_spans(*args), descent_spans(*args, to_touchdown=True)
    assert cut[:-1] == full[: len(cut) - 1]
    assert cut[-1][0] <= full[len(cut) - 1][0]
    distance, speed, _ = state_at(cut, math.inf)
    assert distance == pytest.approx(height, rel=1e-12)
    assert speed == pytest.approx(0.7, rel=1e-9)  # touching down at the land speed, still descending


CASES = [
    (Profile1D.rest_to_rest, (0.05, 10.0, 3.0, 4.0), rest_to_rest_spans),
    (Profile1D.rest_to_rest, (12.0, 10.0, 3.0, 4.0), rest_to_rest_spans),
    (Profile1D.rest_to_rest, (1000.0, 10.0, 3.0, 4.0), rest_to_rest_spans),
    (Profile1D.rest_to_rest, (7.0, 2.0, 1.0, math.inf), rest_to_rest_spans),
    (Profile1D.descent, (20.0, 0.5, 1.5, 0.7, 5.0, 3.0, 4.0), descent_spans),
    (Profile1D.descent, (3.0, 0.5, 1.5, 0.7, 5.0, 3.0, 4.0), descent_spans),
]


@pytest.mark.parametrize(("build_profile", "args", "build_spans"), CASES)
def test_profile1d_flies_the_spans(build_profile, args, build_spans):
    """The vehicle's reference is the spans the energy model prices: same duration, same state at every time,
    its end snapped onto the spans' end."""
    profile, spans = build_profile(*args), build_spans(*args)
    assert profile.duration == pytest.approx(duration_of(spans), rel=1e-15)
    for k in range(1000):  # before the end: at the end a trapezoid's acceleration steps to zero
        t = profile.duration * k / 1000
        for ours, theirs in zip(profile.sample(t), state_at(spans, t), strict=True):
            assert ours == pytest.approx(theirs, rel=1e-12, abs=1e-12)
    end_distance, end_speed, _ = state_at(spans, math.inf)
    assert profile.sample(profile.duration) == (profile.distance, 0.0, 0.0)
    assert profile.distance == pytest.approx(end_distance, rel=1e-12)
    assert end_speed == pytest.approx(0.0, abs=1e-12)
