"""Straight motions as chains of constant-jerk spans: the shapes the navigator flies.

A span is (duration s, acceleration at its start, jerk); speed and distance carry over from one span to the
next, so the distance covered is a cubic in time within each span. Every speed change here ramps the
acceleration up from zero and back down under an acceleration and a jerk limit; with jerk = math.inf the ramps
are acceleration steps and a rest-to-rest move is a trapezoid in speed. Units are the caller's: metres for a leg,
radians for a yaw turn.

Two users build on these spans: the vehicle's reference generator (sitl_quad.trajectory.Profile1D evaluates them
in closed form) and the route energy model (planner.energy integrates power over them), so the planner prices
exactly the motions the vehicle flies.
"""

from __future__ import annotations

import math

Span = tuple[float, float, float]

# A move shorter than this is no motion at all (no spans).
MIN_DISTANCE_M = 1e-6


def ramp_spans(v_from: float, v_to: float, acceleration: float, jerk: float) -> list[Span]:
    """Spans taking the speed from v_from to v_to, the acceleration starting and ending at zero.

    The acceleration never exceeds `acceleration`; the profile is symmetric, so the distance covered is the mean
    speed times the duration (ramp_distance).
    """
    dv = abs(v_to - v_from)
    if dv <= 0.0:
        return []
    sign = 1.0 if v_to > v_from else -1.0
    if math.isinf(jerk):
        return [(dv / acceleration, sign * acceleration, 0.0)]
    if dv >= acceleration * acceleration / jerk:
        # reaches the acceleration limit: jerk up, hold, jerk down
        jerk_time = acceleration / jerk
        hold_time = dv / acceleration - jerk_time
        spans = [(jerk_time, 0.0, sign * jerk)]
        if hold_time > 0.0:
            spans.append((hold_time, sign * acceleration, 0.0))
        spans.append((jerk_time, sign * acceleration, -sign * jerk))
        return spans
    # too small a change to reach the acceleration limit: a triangle in acceleration
    jerk_time = math.sqrt(dv / jerk)
    peak = jerk * jerk_time
    return [(jerk_time, 0.0, sign * jerk), (jerk_time, sign * peak, -sign * jerk)]


def ramp_duration(dv: float, acceleration: float, jerk: float) -> float:
    """Duration of a speed change of |dv| (ramp_spans)."""
    return sum(span[0] for span in ramp_spans(0.0, dv, acceleration, jerk))


def ramp_distance(v_from: float, v_to: float, acceleration: float, jerk: float) -> float:
    """Distance covered by ramp_spans(v_from, v_to, ...): the mean speed times the duration."""
    return 0.5 * (v_from + v_to) * ramp_duration(abs(v_to - v_from), acceleration, jerk)


def rest_to_rest_spans(distance: float, max_speed: float, acceleration: float, jerk: float) -> list[Span]:
    """The time-optimal S-curve over `distance` from rest to rest: ramp up, cruise, ramp down (seven spans:
    jerk +J, 0, -J, cruise, -J, 0, +J). A move too short to reach max_speed peaks at the speed whose two ramps
    exactly cover it; a move of at most MIN_DISTANCE_M has no spans."""
    if distance <= MIN_DISTANCE_M:
        return []
    peak = max_speed
    if peak * ramp_duration(peak, acceleration, jerk) > distance:
        # cannot reach max_speed: the peak speed v whose up and down ramps (v/A + A/J each) exactly cover it
        a2_over_j = 0.0 if math.isinf(jerk) else acceleration * acceleration / jerk
        # the distance at which the ramps just touch the acceleration limit (v = A^2/J): 2 A^3 / J^2
        if distance >= 2.0 * a2_over_j * a2_over_j / acceleration:
            # v^2/A + v A/J = distance  (ramps reach the acceleration limit)
            peak = (-a2_over_j + math.sqrt(a2_over_j * a2_over_j + 4.0 * acceleration * distance)) / 2.0
        else:
            # v * 2 sqrt(v/J) = distance  (acceleration triangles)
            peak = (distance * math.sqrt(jerk) / 2.0) ** (2.0 / 3.0)
    ramp = ramp_spans(0.0, peak, acceleration, jerk)
    # a short move's closed-form peak can overshoot by a rounding: no cruise then, never a negative span
    cruise = max((distance - peak * sum(span[0] for span in ramp)) / peak, 0.0)
    return [*ramp, (cruise, 0.0, 0.0), *ramp_spans(peak, 0.0, acceleration, jerk)]


def descent_spans(
    height: float,
    depth: float,
    fast_speed: float,
    slow_speed: float,
    slow_below: float,
    acceleration: float,
    jerk: float,
    *,
    to_touchdown: bool = False,
) -> list[Span]:
    """A landing from `height` metres: fast_speed down to `slow_below` metres, then slow_speed on to `depth`
    under the ground, where it comes to rest (max(height, 0) + depth in all): the reference aims under the
    ground so that the vehicle touches down still descending. With to_touchdown, the spans stop where the
    reference reaches the ground, where the vehicle touches down.

    Never stops at the slow-down height: the speed ramps from fast to slow on the way. If the height is too
    small for the fast part, the whole descent is a rest-to-rest move at slow_speed.
    """
    spans = None
    if height > slow_below and fast_speed > slow_speed:
        fast_cruise = (
            height
            - slow_below
            - ramp_distance(0.0, fast_speed, acceleration, jerk)
            - ramp_distance(fast_speed, slow_speed, acceleration, jerk)
        )
        slow_cruise = slow_below + depth - ramp_distance(slow_speed, 0.0, acceleration, jerk)
        if fast_cruise >= 0.0 and slow_cruise >= 0.0:
            spans = [
                *ramp_spans(0.0, fast_speed, acceleration, jerk),
                (fast_cruise / fast_speed, 0.0, 0.0),
                *ramp_spans(fast_speed, slow_speed, acceleration, jerk),
                (slow_cruise / slow_speed, 0.0, 0.0),
                *ramp_spans(slow_speed, 0.0, acceleration, jerk),
            ]
    if spans is None:
        spans = rest_to_rest_spans(max(height, 0.0) + depth, slow_speed, acceleration, jerk)
    return cut_at_distance(spans, max(height, 0.0)) if to_touchdown else spans


def cut_at_distance(spans: list[Span], distance: float) -> list[Span]:
    """The spans up to the instant the distance covered reaches `distance`."""
    out: list[Span] = []
    s, v = 0.0, 0.0
    for duration, a0, jerk in spans:

        def covered(t: float, s=s, v=v, a0=a0, jerk=jerk) -> float:
            return s + v * t + a0 * t * t / 2.0 + jerk * t**3 / 6.0

        if covered(duration) >= distance:
            low, high = 0.0, duration
            for _ in range(60):
                mid = 0.5 * (low + high)
                low, high = (mid, high) if covered(mid) < distance else (low, mid)
            return [*out, (high, a0, jerk)]
        out.append((duration, a0, jerk))
        s, v = covered(duration), v + a0 * duration + jerk * duration**2 / 2.0
    return out
