"""A fleet mission's plan: the buoys shared among the vehicles, each vehicle's share an ordinary plan from its own
home, at its own altitude layer.

The sharing is planner.fleet.plan_fleet (min-max: the time until the last vehicle is home, then the total time),
on the vehicles' homes and the buoys projected into one frame (the first vehicle's home at the origin), with the
request's cruise speed and dwell and the planner's take-off and landing time. Each share keeps plan_fleet's
flying order and becomes a `Plan` of its own (gcs.domain.planning.sorties_plan), so a vehicle flies, records and reports
its share exactly as it would a mission of its own. Layers: the k-th vehicle of the request flies at
altitude_m + k x layer_gap_m, so two vehicles crossing paths are a layer apart.
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass

import numpy as np

from gcs.domain.planning import Plan, sorties_plan
from gcs.domain.records import PlanFleet, PlannedShare
from planner.fleet import DEFAULT_TAKEOFF_LANDING_S, plan_fleet
from uavcore.geodesy import LocalFrame

METHOD = "fleet (min-max)"


@dataclass(frozen=True)
class FleetShare:
    """One vehicle's share: its buoys (indices into the request's buoys) in flying order, as a plan from its home."""

    sysid: int
    buoys: list[int]
    plan: Plan  # over its own buoys only (plan.buoy_ids name them); depot = the vehicle's home
    altitude_m: float
    predicted_time_s: float  # take-off, legs at cruise speed, dwells, landing (0: no buoy for it)


@dataclass(frozen=True)
class FleetMissionPlan:
    shares: list[FleetShare]  # the vehicles given buoys, in the request's order
    makespan_s: float  # predicted: when the last vehicle is home
    total_time_s: float
    elapsed_s: float
    layer_gap_m: float

    def plan_section(self) -> PlanFleet:
        """The fleet section of the fleet mission's plan (`Plan.fleet`: the plan itself has the buoys, their ids,
        the method and the planner's time; each part stores its own plan)."""
        return PlanFleet(
            makespan_s=self.makespan_s,
            total_time_s=self.total_time_s,
            layer_gap_m=self.layer_gap_m,
            shares=[
                PlannedShare(
                    sysid=s.sysid,
                    home=list(s.plan.depot),
                    buoys=s.buoys,
                    altitude_m=s.altitude_m,
                    predicted_time_s=s.predicted_time_s,
                    length_m=s.plan.length_m,
                )
                for s in self.shares
            ],
        )


def plan_fleet_mission(
    homes: dict[int, tuple[float, float]],
    buoys: list[tuple[float, float]],
    buoy_ids: list[str],
    altitude_m: float,
    layer_gap_m: float,
    speed_m_s: float,
    dwell_s: float,
    seed: int = 0,
    time_limit_s: float = 2.0,
) -> FleetMissionPlan:
    """Share `buoys` (lat, lon) among the vehicles `homes` ({sysid: (lat, lon)}, in layer order). Raises
    planner.errors.InputError for what plan_fleet refuses."""
    sysids = list(homes)
    origin = homes[sysids[0]]
    frame = LocalFrame(origin[0], origin[1], 0.0)
    depot_points = frame.project(np.array([homes[s] for s in sysids], dtype=float))
    buoy_points = frame.project(np.array(buoys, dtype=float))
    # one node per distinct home (vehicles on one pad share it), then the buoys
    unique, depot_of_vehicle = np.unique(np.round(depot_points, 3), axis=0, return_inverse=True)
    points = np.vstack([unique, buoy_points])
    first_buoy = len(unique)
    result = plan_fleet(
        points,
        [int(d) for d in np.ravel(depot_of_vehicle)],
        speed_m_s,
        dwell_s,
        DEFAULT_TAKEOFF_LANDING_S,
        seed,
        time_limit_s,
    )
    shares = []
    for layer, (sysid, route) in enumerate(zip(sysids, result.routes, strict=True)):
        order = [node - first_buoy for node in route.buoys]
        if not order:
            continue  # nothing for it to do: it stays on the ground (the answer lists the shares only)
        own = [buoys[i] for i in order]
        plan = sorties_plan(
            homes[sysid], own, [buoy_ids[i] for i in order], [list(range(len(order)))], METHOD, result.elapsed_s
        )
        shares.append(FleetShare(sysid, order, plan, altitude_m + layer * layer_gap_m, float(route.time_s)))
    return FleetMissionPlan(
        shares,
        float(result.makespan_s),
        float(result.total_time_s),
        float(result.elapsed_s),
        layer_gap_m,
    )


def reshare(
    flying: dict[int, tuple[np.ndarray, np.ndarray, np.ndarray]],
    lost: np.ndarray,
    speed_m_s: float,
    dwell_s: float,
) -> dict[int, list[int]]:
    """A lost vehicle's buoys shared among the vehicles still flying, without landing them: each lost buoy (points
    in one planar frame, metres) goes where it lengthens the longest remaining flight least (cheapest insertion
    under the min-max objective, then the least added time). `flying`: {sysid: (its position now, its remaining
    buoys in flying order (k, 2), its home)}; `lost`: (m, 2). Returns {sysid: its new remaining order}, as
    indices: 0..k-1 its own remaining buoys, k.. the lost ones (k + j for lost[j])."""
    routes = {sysid: list(range(len(own))) for sysid, (_, own, _) in flying.items()}

    def point(sysid: int, node: int) -> np.ndarray:
        own = flying[sysid][1]
        return own[node] if node < len(own) else lost[node - len(own)]

    def remaining_s(sysid: int, order: list[int]) -> float:
        here, _, home = flying[sysid]
        stops = [here, *(point(sysid, n) for n in order), home]
        legs = sum(float(np.hypot(*(b - a))) for a, b in itertools.pairwise(stops))
        return legs / speed_m_s + dwell_s * len(order)

    times = {sysid: remaining_s(sysid, order) for sysid, order in routes.items()}
    # the farthest from every flying vehicle first: it constrains the makespan most
    nearest = [min(float(np.hypot(*(b - flying[s][0]))) for s in flying) for b in lost]
    for j in sorted(range(len(lost)), key=lambda j: -nearest[j]):
        best: tuple[tuple[float, float], int, list[int], float] | None = None  # (key, sysid, order, its time)
        for sysid, order in routes.items():
            node = len(flying[sysid][1]) + j
            for at in range(len(order) + 1):
                trial = [*order[:at], node, *order[at:]]
                t = remaining_s(sysid, trial)
                makespan = max([t, *(times[o] for o in routes if o != sysid)])  # one flying: its own
                key = (makespan, t - times[sysid])
                if best is None or key < best[0]:
                    best = (key, sysid, trial, t)
        assert best is not None  # `nearest` needed a flying vehicle, and each offers at least one place
        _, sysid, trial, t = best
        routes[sysid], times[sysid] = trial, t
    return routes
