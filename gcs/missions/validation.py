"""Checks of a mission request that depend on the settings: airframe limits, buoy spacing, range.

Errors are collected as (location, message) pairs and raised together as RequestInvalidError, which the app
renders in FastAPI's own 422 shape ({"detail": [{"loc": [...], "msg": ..., "type": ...}]}), so a client sees
one format whichever layer refused the request.
"""

from __future__ import annotations

import itertools

import numpy as np

from gcs.domain.planning import Plan
from gcs.domain.schemas import FenceZoneIn, PlanRequest, RallyPointIn
from gcs.settings import Limits
from planner.distances import euclidean_matrix
from uavcore.geodesy import LocalFrame
from uavcore.geofence import CircleZone, Geofence, PolygonZone

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
    if not request.buoys:
        errors.append((("body", "buoys"), "at least 1 buoy is needed: give buoys, or select some with `from_register`"))
    elif len(request.buoys) > limits.max_buoys:
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


def fence_from_request(zones: list[FenceZoneIn]) -> Geofence:
    """The request's zones as a uavcore Geofence."""
    built: list[PolygonZone | CircleZone] = []
    for zone in zones:
        # FenceZoneIn's validator gives a polygon its vertices, a circle its center and radius
        if zone.kind == "polygon":
            assert zone.vertices is not None
            built.append(PolygonZone(tuple((v.lat, v.lon) for v in zone.vertices), zone.inclusion))
        else:
            assert zone.center is not None and zone.radius_m is not None
            built.append(CircleZone((zone.center.lat, zone.center.lon), zone.radius_m, zone.inclusion))
    return Geofence(tuple(built))


def validate_fence_points(
    depot: tuple[float, float],
    buoys: list[tuple[float, float]],
    fence: Geofence,
    homes: dict[int, tuple[float, float]] | None = None,
) -> None:
    """The depot (a fleet's: each vehicle's home, `homes` {sysid: (lat, lon)}) and every buoy where the fence lets
    the vehicle be."""
    errors: list[tuple[Location, str]] = []
    if homes is None:
        zone = fence.violation(*depot)
        if zone is not None:
            errors.append((("body", "depot"), f"the depot breaks the geofence's {zone.kind}"))
    for sysid, home in (homes or {}).items():
        zone = fence.violation(*home)
        if zone is not None:
            errors.append((("body", "geofence"), f"vehicle {sysid}'s home breaks the geofence's {zone.kind}"))
    for i, (lat, lon) in enumerate(buoys):
        zone = fence.violation(lat, lon)
        if zone is not None:
            errors.append((("body", "buoys", i), f"buoy {i} breaks the geofence's {zone.kind}"))
    if errors:
        raise RequestInvalidError(errors)


def validate_rally_points(points: list[RallyPointIn], fence: Geofence | None, limits: Limits) -> None:
    """Each rally point at an altitude the airframe flies, and where the fence lets the vehicle be (a vehicle
    returning to it must not breach the fence it was given)."""
    errors: list[tuple[Location, str]] = []
    low, high = limits.altitude_m
    for i, point in enumerate(points):
        if not low <= point.alt_m <= high:
            errors.append(
                (
                    ("body", "rally_points", i, "alt_m"),
                    f"{point.alt_m:g} m is outside the airframe's limits [{low:g}, {high:g}] m",
                )
            )
        zone = None if fence is None else fence.violation(point.lat, point.lon)
        if zone is not None:
            errors.append((("body", "rally_points", i), f"rally point {i} breaks the geofence's {zone.kind}"))
    if errors:
        raise RequestInvalidError(errors)


def validate_fenced_route(plan: Plan, fenced: dict[tuple[int, int], str]) -> None:
    """A planned tour that still uses a leg the fence forbids (no tour avoids it): 422 naming the buoy pair."""
    legs = [leg for sortie in plan.sortie_orders() for leg in itertools.pairwise([0, *(i + 1 for i in sortie), 0])]
    names = ["the depot", *plan.buoy_ids]
    errors: list[tuple[Location, str]] = []
    for a, b in legs:
        kind = fenced.get((min(a, b), max(a, b)))
        if kind is not None:
            errors.append(
                (
                    ("body", "geofence"),
                    f"the leg {names[a]} -> {names[b]} breaks the geofence's {kind}, and no route avoids it",
                )
            )
    if errors:
        raise RequestInvalidError(errors)
