"""Tracking figures of a flight against its plan. Pure: arrays and numbers in, numbers out.

Positions are horizontal [east, north] metres in the depot's tangent plane; times are the vehicle's simulated
time (time_boot_ms / 1000). Leg k runs from route point k to route point k + 1 (route = depot, buoys in visiting
order, depot). The cross-track error of a sample is its distance to the segment of the leg it was flying, the
measure of the paper's Figure 10 (designed against flown trajectory).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class TrackPoint:
    t_s: float
    east: float
    north: float
    airborne: bool
    leg: int | None  # the planned leg being flown, None while taking off, landing or on the ground


def distance_to_segment(points: np.ndarray, start: np.ndarray, end: np.ndarray) -> np.ndarray:
    """Distance of each (m, 2) point to the segment start-end (to the nearer end beyond its ends)."""
    points = np.atleast_2d(np.asarray(points, dtype=float))
    start, end = np.asarray(start, dtype=float), np.asarray(end, dtype=float)
    direction = end - start
    length_sq = float(direction @ direction)
    if length_sq == 0.0:
        return np.hypot(*(points - start).T)
    along = np.clip((points - start) @ direction / length_sq, 0.0, 1.0)
    nearest = start + along[:, None] * direction
    return np.hypot(*(points - nearest).T)


def cross_track_m(east: float, north: float, route: np.ndarray, leg: int) -> float:
    """One sample's cross-track error on a leg (used for the live display)."""
    return float(distance_to_segment(np.array([[east, north]]), route[leg], route[leg + 1])[0])


def _rms(values: np.ndarray) -> float | None:
    return float(np.sqrt(np.mean(values**2))) if len(values) else None


def _max(values: np.ndarray) -> float | None:
    return float(values.max()) if len(values) else None


def _leg_errors(route: np.ndarray, track: Sequence[TrackPoint]) -> list[np.ndarray]:
    route = np.asarray(route, dtype=float)
    errors = []
    for leg in range(len(route) - 1):
        on_leg = np.array([[p.east, p.north] for p in track if p.leg == leg and p.airborne]).reshape(-1, 2)
        errors.append(distance_to_segment(on_leg, route[leg], route[leg + 1]) if len(on_leg) else np.empty(0))
    return errors


def _leg_summary(leg: int, errors: np.ndarray) -> dict:
    """RMS and max cross-track error of one leg, over the airborne samples flying that leg."""
    return {"leg": leg, "samples": len(errors), "rms_cross_track_m": _rms(errors), "max_cross_track_m": _max(errors)}


def buoy_figures(
    buoys: np.ndarray, radii: Sequence[float], track: Sequence[TrackPoint], reached_at: dict[int, float]
) -> list[dict]:
    """Per buoy (input order): closest horizontal approach, whether it came within its acceptance radius, and
    the arrival time: the vehicle's own report when it made one (`reached_at`, by buoy index), else the first
    sample inside the radius."""
    buoys = np.asarray(buoys, dtype=float).reshape(-1, 2)
    positions = np.array([[p.east, p.north] for p in track]).reshape(-1, 2)
    times = np.array([p.t_s for p in track])
    out = []
    for index, (buoy, radius) in enumerate(zip(buoys, radii, strict=True)):
        if len(positions) == 0:
            out.append({"index": index, "closest_m": None, "reached": False, "arrival_s": reached_at.get(index)})
            continue
        distance = np.hypot(*(positions - buoy).T)
        inside = np.flatnonzero(distance <= radius)
        arrival = reached_at.get(index, float(times[inside[0]]) if len(inside) else None)
        out.append(
            {"index": index, "closest_m": float(distance.min()), "reached": bool(len(inside)), "arrival_s": arrival}
        )
    return out


def distance_flown_m(track: Sequence[TrackPoint]) -> float:
    """Horizontal path length over the airborne samples (comparable with the planned tour length)."""
    airborne = np.array([[p.east, p.north] for p in track if p.airborne]).reshape(-1, 2)
    if len(airborne) < 2:
        return 0.0
    return float(np.hypot(*np.diff(airborne, axis=0).T).sum())


def flight_time_s(track: Sequence[TrackPoint]) -> float | None:
    """From the first to the last airborne sample, in the vehicle's time."""
    times = [p.t_s for p in track if p.airborne]
    return float(times[-1] - times[0]) if len(times) >= 2 else None


def tracking_figures(route: np.ndarray, planned_length_m: float, track: Sequence[TrackPoint]) -> dict:
    """All per-mission flight figures except the per-buoy ones."""
    per_leg = _leg_errors(route, track)
    all_errors = np.concatenate(per_leg) if per_leg else np.empty(0)
    return {
        "legs": [_leg_summary(leg, e) for leg, e in enumerate(per_leg)],
        "rms_cross_track_m": _rms(all_errors),
        "max_cross_track_m": _max(all_errors),
        "distance_flown_m": distance_flown_m(track),
        "planned_length_m": float(planned_length_m),
        "flight_time_s": flight_time_s(track),
    }


# ----- a gust's effect (the paper's Figure 6): shared with the control benchmark (bench.control.metrics)
GUST_WINDOW_S = 10.0  # the error is looked at this long after the gust's onset
RECOVERED_M = 0.2  # back on track: the 3-D error stays under this


@dataclass(frozen=True)
class GustEffect:
    peak_m: float  # largest 3-D tracking error within GUST_WINDOW_S of the onset (NaN: no sample there)
    recovery_s: float  # from the onset until the error is under RECOVERED_M for good within the window:
    # 0 = it never left, GUST_WINDOW_S = not recovered within the window (NaN: no sample there)


def gust_effect(
    t_s: np.ndarray,
    error_m: np.ndarray,
    onset_s: float,
    window_s: float = GUST_WINDOW_S,
    recovered_m: float = RECOVERED_M,
) -> GustEffect:
    """The gust's effect on a tracking-error series: error_m[k] is |position - reference| at time t_s[k]
    (increasing; samples without an error, NaN, are left out). An error above recovered_m at sample k lasts
    until the next sample, so the recovery ends at the time of the sample after the last one above it."""
    t = np.asarray(t_s, dtype=float)
    error = np.asarray(error_m, dtype=float)
    in_window = (t >= onset_s) & (t <= onset_s + window_s) & np.isfinite(error)
    if not in_window.any():
        return GustEffect(float("nan"), float("nan"))
    above = np.flatnonzero(in_window & (error > recovered_m))
    if above.size == 0:
        return GustEffect(float(error[in_window].max()), 0.0)
    last = above[-1]
    back_on_track = t[last + 1] if last + 1 < t.size else float("inf")
    return GustEffect(float(error[in_window].max()), float(min(back_on_track - onset_s, window_s)))


def climb_start_s(t_s: np.ndarray, ref_down: np.ndarray, moved_m: float = 1e-4) -> float | None:
    """The vehicle time at which the flight's reference starts to climb: the last sample before the first one
    whose reference is higher than the sample before by more than moved_m (the reference holds still on the
    ground while the motors spool up). None if it never climbs."""
    rising = np.flatnonzero(np.diff(np.asarray(ref_down, dtype=float)) < -moved_m)
    return float(np.asarray(t_s, dtype=float)[rising[0]]) if rising.size else None
