"""The navigator's motions as the energy model (planner.energy) integrates them: constant-jerk spans, the
landing's cut at touchdown, sampled on a grid.

The spans themselves are uavcore.motion_profiles', the same the vehicle's reference generator
(sitl_quad.trajectory.Profile1D) flies: legs and climbs are time-optimal S-curves under speed, acceleration and
jerk limits (planner.scenario.rest_to_rest_s gives their durations), turns are trapezoids in yaw (jerk = inf),
the landing descends fast to the slow-down height and slowly below it.
"""

from __future__ import annotations

import math
from functools import partial

import numpy as np

from uavcore import motion_profiles
from uavcore.motion_profiles import Span, ramp_duration, rest_to_rest_spans

__all__ = ["Span", "descent_spans", "ramp_duration", "rest_to_rest_spans", "sample_spans"]

# The landing as the energy model prices it: up to touchdown (the reference goes on under the ground).
descent_spans = partial(motion_profiles.descent_spans, to_touchdown=True)


def sample_spans(spans: list[Span], step_s: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(dt, speed, acceleration) at the midpoints of a grid over the spans (midpoint rule): a constant-speed span
    as one sample (exact), the others every step_s at most."""
    dts: list[np.ndarray] = [np.zeros(0)]
    speeds: list[np.ndarray] = [np.zeros(0)]
    accels: list[np.ndarray] = [np.zeros(0)]
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
