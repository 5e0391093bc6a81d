"""The navigator's motions as chains of constant-jerk spans, for the energy model (planner.energy).

A span is (duration s, acceleration at its start, jerk): speed and distance carry over from one span to the next,
as in the vehicle's own reference generator (sitl_quad.trajectory.Profile1D, which the planner may not import).
Every motion starts and ends at rest: legs and climbs are time-optimal S-curves under speed, acceleration and
jerk limits (planner.scenario.rest_to_rest_s gives their durations), turns are trapezoids in yaw (jerk = inf),
the landing descends fast to the slow-down height and slowly below it.
"""

from __future__ import annotations

import math

import numpy as np

Span = tuple[float, float, float]


def ramp_spans(v_from: float, v_to: float, acceleration: float, jerk: float) -> list[Span]:
    """Spans taking the speed from v_from to v_to, the acceleration starting and ending at zero."""
    dv = abs(v_to - v_from)
    if dv <= 0.0:
        return []
    sign = 1.0 if v_to > v_from else -1.0
    if math.isinf(jerk):
        return [(dv / acceleration, sign * acceleration, 0.0)]
    if dv >= acceleration * acceleration / jerk:  # reaches the acceleration limit: jerk up, hold, jerk down
        ramp = acceleration / jerk
        hold = (dv / acceleration - ramp, sign * acceleration, 0.0)
        return [(ramp, 0.0, sign * jerk), hold, (ramp, sign * acceleration, -sign * jerk)]
    ramp = math.sqrt(dv / jerk)  # a triangle in acceleration
    return [(ramp, 0.0, sign * jerk), (ramp, sign * jerk * ramp, -sign * jerk)]


def ramp_distance(v_from: float, v_to: float, acceleration: float, jerk: float) -> float:
    """Distance covered by ramp_spans (the ramp is symmetric: mean speed times duration)."""
    return 0.5 * (v_from + v_to) * sum(span[0] for span in ramp_spans(v_from, v_to, acceleration, jerk))


def rest_to_rest_spans(distance: float, speed: float, acceleration: float, jerk: float) -> list[Span]:
    """The time-optimal S-curve over `distance` from rest to rest: ramp up, cruise, ramp down; a move too short
    to reach `speed` peaks at the speed whose two ramps just cover it (found by bisection)."""
    if distance <= 1e-6:
        return []
    if 2.0 * ramp_distance(0.0, speed, acceleration, jerk) > distance:
        low, high = 0.0, speed
        for _ in range(60):
            mid = 0.5 * (low + high)
            fits = 2.0 * ramp_distance(0.0, mid, acceleration, jerk) <= distance
            low, high = (mid, high) if fits else (low, mid)
        speed = low
    cruise = (distance - 2.0 * ramp_distance(0.0, speed, acceleration, jerk)) / speed
    return [
        *ramp_spans(0.0, speed, acceleration, jerk),
        (cruise, 0.0, 0.0),
        *ramp_spans(speed, 0.0, acceleration, jerk),
    ]


def descent_spans(
    height: float,
    depth: float,
    fast_speed: float,
    slow_speed: float,
    slow_below: float,
    acceleration: float,
    jerk: float,
) -> list[Span]:
    """A landing (Profile1D.descent): fast_speed down to `slow_below` metres, then slow_speed on toward `depth`
    under the ground; cut where the reference reaches the ground, where the vehicle touches down."""
    a, j = acceleration, jerk
    spans = None
    if height > slow_below and fast_speed > slow_speed:
        fast_cruise = (
            height - slow_below - ramp_distance(0.0, fast_speed, a, j) - ramp_distance(fast_speed, slow_speed, a, j)
        )
        slow_cruise = slow_below + depth - ramp_distance(slow_speed, 0.0, a, j)
        if fast_cruise >= 0.0 and slow_cruise >= 0.0:
            spans = [
                *ramp_spans(0.0, fast_speed, a, j),
                (fast_cruise / fast_speed, 0.0, 0.0),
                *ramp_spans(fast_speed, slow_speed, a, j),
                (slow_cruise / slow_speed, 0.0, 0.0),
                *ramp_spans(slow_speed, 0.0, a, j),
            ]
    if spans is None:
        spans = rest_to_rest_spans(max(height, 0.0) + depth, slow_speed, a, j)
    return cut_at_distance(spans, max(height, 0.0))


def cut_at_distance(spans: list[Span], distance: float) -> list[Span]:
    """The spans up to the instant the distance covered reaches `distance`."""
    out, s, v = [], 0.0, 0.0
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


def sample_spans(spans: list[Span], step_s: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(dt, speed, acceleration) at the midpoints of a grid over the spans (midpoint rule): a constant-speed span
    as one sample (exact), the others every step_s at most."""
    dts, speeds, accels = [np.zeros(0)], [np.zeros(0)], [np.zeros(0)]
    v = 0.0
    for duration, a0, jerk in spans:
        if duration <= 0.0:
            continue
        steps = 1 if a0 == 0.0 and jerk == 0.0 else max(1, math.ceil(duration / step_s))
        h = duration / steps
        t = (np.arange(steps) + 0.5) * h
        dts.append(np.full(steps, h))
        speeds.append(v + a0 * t + jerk * t * t / 2.0)
        accels.append(a0 + jerk * t)
        v += a0 * duration + jerk * duration**2 / 2.0
    return np.concatenate(dts), np.concatenate(speeds), np.concatenate(accels)
