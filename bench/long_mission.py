"""A long stored mission for the read-side benchmark and tests: the reference scenario's route flown for two hours,
72 000 samples at 10 Hz, written through the service's own storage as the recorder would have written them.

No vehicle flies two hours in a test; the samples are synthesised: the route at a constant ground speed with a
dwell at each buoy, a lateral wobble (0.4 m, 15 s period, as a gusty crosswind leaves it) and position noise
(5 cm), so a simplification has real detail to keep or drop. Seeded: the same call stores the same mission.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from gcs.domain.planning import FlightParams, Plan, make_plan
from gcs.domain.records import MissionProgress
from gcs.domain.schemas import TelemetrySample
from gcs.domain.status import MissionStatus
from gcs.storage import Storage
from planner.scenario import reference_scenario

SAMPLES = 72_000  # two hours at 10 Hz
PERIOD_S = 0.1
DWELL_S = 30.0
WOBBLE_M, WOBBLE_PERIOD_S, NOISE_M = 0.4, 15.0, 0.05
ALTITUDE_M = 5.0


def reference_plan() -> Plan:
    scenario = reference_scenario(1)
    buoys = [(float(lat), float(lon)) for lat, lon in scenario.buoys_lat_lon]
    return make_plan(scenario.home[:2], buoys, [f"B{i + 1}" for i in range(len(buoys))], "exact")


def flight_samples(plan: Plan, n: int = SAMPLES, seed: int = 0) -> tuple[list[dict[str, Any]], dict[int, float]]:
    """n TelemetrySample documents of a flight along the plan's route, and the buoy arrivals (progress'
    reached_at: buoy index -> vehicle time)."""
    rng = np.random.default_rng(seed)
    route = plan.route_local()
    legs = np.diff(route, axis=0)
    leg_lengths = np.hypot(*legs.T)
    n_buoys = len(plan.order)
    t = np.arange(n) * PERIOD_S
    speed = leg_lengths.sum() / (t[-1] - DWELL_S * n_buoys)  # ground speed that fills the flight time
    # time at which each leg starts: legs flown at `speed`, a dwell after each buoy (every leg's end but the last)
    leg_times = leg_lengths / speed
    starts = np.concatenate([[0.0], np.cumsum(leg_times + DWELL_S)[:-1]])
    leg = np.clip(np.searchsorted(starts, t, side="right") - 1, 0, len(legs) - 1)
    along = np.clip((t - starts[leg]) * speed, 0.0, leg_lengths[leg])  # stays at the leg's end while dwelling
    direction = legs[leg] / leg_lengths[leg][:, None]
    normal = np.column_stack([-direction[:, 1], direction[:, 0]])
    offset = WOBBLE_M * np.sin(2 * np.pi * t / WOBBLE_PERIOD_S)
    local = route[leg] + direction * along[:, None] + normal * offset[:, None] + rng.normal(0.0, NOISE_M, (n, 2))
    lat_lon = plan.frame.unproject(local)
    yaw = np.arctan2(direction[:, 0], direction[:, 1])
    samples = [
        TelemetrySample(
            t_s=float(t[i]),
            lat=float(lat_lon[i, 0]),
            lon=float(lat_lon[i, 1]),
            alt_m=ALTITUDE_M,
            north=float(local[i, 1]),
            east=float(local[i, 0]),
            down=-ALTITUDE_M,
            vn=float(direction[i, 1] * speed),
            ve=float(direction[i, 0] * speed),
            vd=0.0,
            roll=0.0,
            pitch=0.0,
            yaw=float(yaw[i]),
            ref_north=float(local[i, 1] - normal[i, 1] * offset[i]),
            ref_east=float(local[i, 0] - normal[i, 0] * offset[i]),
            ref_down=-ALTITUDE_M,
            ref_yaw=float(yaw[i]),
            mission_seq=int(leg[i]) + 2,
            landed_state=2,
            armed=True,
            eso=None,
            cross_track_m=float(abs(offset[i])),
        ).model_dump()
        for i in range(n)
    ]
    reached_at = {plan.order[k]: float(starts[k] + leg_times[k]) for k in range(n_buoys)}
    return samples, reached_at


def store_long_mission(storage: Storage, n: int = SAMPLES) -> int:
    """Store a completed mission of n samples (default: two hours at 10 Hz); its id."""
    plan = reference_plan()
    flight = FlightParams(ALTITUDE_M, 10.0, DWELL_S, 2.0)
    mission_id = storage.create_mission(flight, plan)
    samples, reached_at = flight_samples(plan, n)
    storage.add_telemetry(mission_id, samples)
    visited = len(reached_at)
    storage.set_progress(mission_id, MissionProgress(reached_at=reached_at, visited=visited, buoys=visited))
    storage.set_status(mission_id, MissionStatus.COMPLETED)
    return mission_id
