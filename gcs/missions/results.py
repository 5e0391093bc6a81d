"""A recorded flight's results: its tracking figures and per-buoy figures against the plan (pure).

Stored with the mission when it ends (MissionRecord.results) and shown by GET /missions/{id} and the report.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from gcs.domain import tracking_metrics
from gcs.domain.planning import FlightParams, Plan, leg_of_seq
from gcs.domain.records import MissionProgress, MissionResults
from uavcore.mavlink import mavlink


def airborne(sample: dict[str, Any]) -> bool:
    """The vehicle's own landed state when it reports one, else more than half a metre above home."""
    landed = sample.get("landed_state")
    if landed is not None and landed != mavlink.MAV_LANDED_STATE_UNDEFINED:
        return landed != mavlink.MAV_LANDED_STATE_ON_GROUND
    return (sample.get("alt_m") or 0.0) > 0.5


def flight_results(
    plan: Plan, flight: FlightParams, samples: list[dict[str, Any]], progress: MissionProgress
) -> MissionResults:
    """Tracking and per-buoy figures of a recorded flight (pure given its inputs)."""
    located = [s for s in samples if s.get("lat") is not None]
    sortie_sizes = [len(order) for order in plan.sortie_orders()]
    en = plan.frame.project(np.array([[s["lat"], s["lon"]] for s in located]).reshape(-1, 2))
    track = [
        tracking_metrics.TrackPoint(
            t_s=s["t_s"],
            east=float(e),
            north=float(n),
            airborne=airborne(s),
            leg=_leg(plan, sortie_sizes, s.get("sortie") or 0, s.get("mission_seq"), progress.capture),
        )
        for s, (e, n) in zip(located, en, strict=True)
    ]
    buoys = tracking_metrics.buoy_figures(
        np.asarray(plan.buoys_local), [flight.acceptance_radius_m] * len(plan.buoys_local), track, progress.reached_at
    )
    for result in buoys:
        result["id"] = plan.buoy_ids[result["index"]]
    figures = tracking_metrics.tracking_figures(plan.route_local(), plan.length_m, track)
    # several sorties: the time on the ground between them is no flight time
    sortie_times = [
        tracking_metrics.flight_time_s([p for p, s in zip(track, located, strict=True) if (s.get("sortie") or 0) == k])
        for k in range(len(sortie_sizes))
    ]
    if len(sortie_sizes) > 1:
        figures["flight_time_s"] = sum(t for t in sortie_times if t is not None) if any(sortie_times) else None
    return MissionResults.model_validate({"tracking": figures, "buoys": buoys})


def _leg(plan: Plan, sortie_sizes: list[int], sortie: int, seq: int | None, inspected: bool) -> int | None:
    """The route's leg (Plan.route_local) a sample of `sortie` flew while item `seq` of that sortie was current
    (`inspected`: the sortie's items had an inspection group per buoy)."""
    if sortie >= len(sortie_sizes):
        return None
    leg = leg_of_seq(seq, sortie_sizes[sortie], inspected)
    return None if leg is None else plan.first_leg_of_sortie(sortie) + leg
