"""A recorded flight's results: its tracking figures and per-buoy figures against the plan (pure).

Stored with the mission when it ends (MissionRecord.results) and shown by GET /missions/{id} and the report.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from gcs import tracking
from gcs.planning import FlightParams, Plan, leg_of_seq
from uavcore.mavlink import mavlink


def _airborne(sample: dict[str, Any]) -> bool:
    """The vehicle's own landed state when it reports one, else more than half a metre above home."""
    landed = sample.get("landed_state")
    if landed is not None and landed != mavlink.MAV_LANDED_STATE_UNDEFINED:
        return landed != mavlink.MAV_LANDED_STATE_ON_GROUND
    return (sample.get("alt_m") or 0.0) > 0.5


def flight_results(plan: Plan, flight: FlightParams, samples: list[dict[str, Any]], progress: dict[str, Any]) -> dict:
    """Tracking and per-buoy figures of a recorded flight (pure given its inputs)."""
    located = [s for s in samples if s.get("lat") is not None]
    en = plan.frame.project(np.array([[s["lat"], s["lon"]] for s in located]).reshape(-1, 2))
    track = [
        tracking.TrackPoint(
            t_s=s["t_s"],
            east=float(e),
            north=float(n),
            airborne=_airborne(s),
            leg=leg_of_seq(s.get("mission_seq"), len(plan.order)),
        )
        for s, (e, n) in zip(located, en, strict=True)
    ]
    reached_at = {int(k): float(v) for k, v in (progress.get("reached_at") or {}).items()}
    buoys = tracking.buoy_figures(
        np.asarray(plan.buoys_local), [flight.acceptance_radius_m] * len(plan.buoys_local), track, reached_at
    )
    for result in buoys:
        result["id"] = plan.buoy_ids[result["index"]]
    return {"tracking": tracking.tracking_figures(plan.route_local(), plan.length_m, track), "buoys": buoys}
