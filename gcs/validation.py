"""Checks of a mission request that depend on the settings: airframe limits, buoy spacing, range.

Errors are collected as (location, message) pairs and raised together as RequestInvalidError, which the app
renders in FastAPI's own 422 shape ({"detail": [{"loc": [...], "msg": ..., "type": ...}]}), so a client sees
one format whichever layer refused the request.
"""

from __future__ import annotations

import numpy as np

from gcs.schemas import PlanRequest
from gcs.settings import Limits
from planner.distances import euclidean_matrix
from uavcore.geodesy import LocalFrame

Location = tuple[str | int, ...]


class RequestInvalidError(ValueError):
    """A request that parsed but cannot be flown. `errors` lists (location, message)."""

    def __init__(self, errors: list[tuple[Location, str]]) -> None:
        self.errors = errors
        super().__init__("; ".join(f"{'.'.join(map(str, loc))}: {msg}" for loc, msg in errors))


def _in_range(errors: list, name: str, value: float, bounds: tuple[float, float], unit: str) -> None:
    low, high = bounds
    if not low <= value <= high:
        errors.append((("body", name), f"{value:g} {unit} is outside the airframe's limits [{low:g}, {high:g}] {unit}"))


def validate_request(request: PlanRequest, depot: tuple[float, float], limits: Limits) -> None:
    """Raise RequestInvalidError naming every field that breaks a limit."""
    errors: list[tuple[Location, str]] = []
    _in_range(errors, "altitude_m", request.altitude_m, limits.altitude_m, "m")
    _in_range(errors, "speed_m_s", request.speed_m_s, limits.speed_m_s, "m/s")
    _in_range(errors, "dwell_s", request.dwell_s, limits.dwell_s, "s")
    _in_range(errors, "acceptance_radius_m", request.acceptance_radius_m, limits.acceptance_radius_m, "m")
    if request.planner.time_limit_s > limits.max_time_limit_s:
        errors.append(
            (
                ("body", "planner", "time_limit_s"),
                f"{request.planner.time_limit_s:g} s exceeds {limits.max_time_limit_s:g} s",
            )
        )
    if len(request.buoys) > limits.max_buoys:
        errors.append((("body", "buoys"), f"{len(request.buoys)} buoys; at most {limits.max_buoys}"))
    else:
        _check_geometry(errors, request, depot, limits)
    if errors:
        raise RequestInvalidError(errors)


def _check_geometry(errors: list, request: PlanRequest, depot: tuple[float, float], limits: Limits) -> None:
    frame = LocalFrame(depot[0], depot[1], 0.0)
    local = frame.project(np.array([[b.lat, b.lon] for b in request.buoys], dtype=float))
    from_depot = np.hypot(local[:, 0], local[:, 1])
    for i in np.flatnonzero(from_depot > limits.max_distance_from_depot_m)[:5]:
        errors.append(
            (
                ("body", "buoys", int(i)),
                f"{from_depot[i]:.0f} m from the depot; the maximum range is {limits.max_distance_from_depot_m:g} m",
            )
        )
    for i in np.flatnonzero(from_depot < limits.min_buoy_spacing_m)[:5]:
        errors.append(
            (
                ("body", "buoys", int(i)),
                f"{from_depot[i]:.2f} m from the depot; buoys must be at least {limits.min_buoy_spacing_m:g} m from it",
            )
        )
    distance = euclidean_matrix(local)
    np.fill_diagonal(distance, np.inf)
    close_i, close_j = np.nonzero(np.triu(distance < limits.min_buoy_spacing_m))
    for i, j in list(zip(close_i.tolist(), close_j.tolist(), strict=True))[:5]:
        errors.append(
            (
                ("body", "buoys", j),
                f"{distance[i, j]:.2f} m from buoy {i}; buoys must be at least {limits.min_buoy_spacing_m:g} m apart",
            )
        )


def validate_route_length(length_m: float, limits: Limits) -> None:
    """The battery check, once the tour is known."""
    if length_m > limits.max_route_length_m:
        raise RequestInvalidError(
            [
                (
                    ("body", "buoys"),
                    f"the planned route is {length_m:.0f} m; the maximum range is {limits.max_route_length_m:g} m",
                )
            ]
        )
