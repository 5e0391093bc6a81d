"""A fleet mission's plan: the buoys shared among the vehicles, each vehicle's share an ordinary plan from its own
home, at its own altitude layer, its take-off and landing in turn with the vehicles of its depot.

The sharing is planner.fleet.plan_fleet (min-max: the time until the last vehicle is home, then the total time),
on the vehicles' homes and the buoys projected into one frame (the first vehicle's home at the origin), with the
calibrated model's times (planner.fleet_time: each leg's S-curve, the stop at each buoy, its dwell, turn and
hand-over, each vehicle's climb to its layer, its return and landing: the sortie planner's model) and the room
each vehicle must leave for the take-offs before its own and the landings after it (planner.fleet_schedule).
Each share keeps plan_fleet's flying order and becomes a `Plan` of its own (gcs.domain.planning.sorties_plan), so
a vehicle flies, records and reports its share exactly as it would a mission of its own. Layers: the k-th vehicle
of the request flies at altitude_m + k x layer_gap_m, so two vehicles crossing paths are a layer apart. Its
predicted time is its timeline with the real turns of its order (planner.fleet_time.share_timeline); the
makespan, the latest predicted start + flight, counts the staggered starts and the holds before the landings.
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass, replace

import numpy as np

from gcs.domain.planning import Plan, sorties_plan
from gcs.domain.records import PlanFleet, PlannedShare
from planner.energy import EnergyModel
from planner.fleet import plan_fleet
from planner.fleet_schedule import depot_zones, schedule, split_offsets
from planner.fleet_time import fleet_time_terms, share_timeline
from uavcore.geodesy import LocalFrame

METHOD = "fleet (min-max)"
DEFAULT_SEPARATION_M = 5.0  # between any two vehicles in the air, around the depot (the request's separation_m)


@dataclass(frozen=True)
class FleetShare:
    """One vehicle's share: its buoys (indices into the request's buoys) in flying order, as a plan from its home,
    and its turn at the depot (planner.fleet_schedule.Slot)."""

    sysid: int
    buoys: list[int]
    plan: Plan  # over its own buoys only (plan.buoy_ids name them); depot = the vehicle's home
    altitude_m: float
    predicted_time_s: float  # its flight, start command to disarm, the hold at its last buoy included
    start_s: float  # predicted mission start, seconds after the fleet's
    depart_after: int | None  # the vehicle whose leaving the depot zone starts it (None: at once)
    final_hold_s: float  # hover added at its last buoy, so that it lands in its turn
    zone_centre: tuple[float, float]  # (lat, lon) of its depot zone's centre
    zone_radius_m: float


@dataclass(frozen=True)
class FleetMissionPlan:
    shares: list[FleetShare]  # the vehicles given buoys, in the request's order
    makespan_s: float  # predicted: when the last vehicle is home
    total_time_s: float
    elapsed_s: float
    layer_gap_m: float
    separation_m: float

    def plan_section(self) -> PlanFleet:
        """The fleet section of the fleet mission's plan (`Plan.fleet`: the plan itself has the buoys, their ids,
        the method and the planner's time; each part stores its own plan)."""
        return PlanFleet(
            makespan_s=self.makespan_s,
            total_time_s=self.total_time_s,
            layer_gap_m=self.layer_gap_m,
            separation_m=self.separation_m,
            shares=[
                PlannedShare(
                    sysid=s.sysid,
                    home=list(s.plan.depot),
                    buoys=s.buoys,
                    altitude_m=s.altitude_m,
                    predicted_time_s=s.predicted_time_s,
                    length_m=s.plan.length_m,
                    start_s=s.start_s,
                    depart_after=s.depart_after,
                    final_hold_s=s.final_hold_s,
                    zone_centre=list(s.zone_centre),
                    zone_radius_m=s.zone_radius_m,
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
    separation_m: float = DEFAULT_SEPARATION_M,
    model: EnergyModel | None = None,
) -> FleetMissionPlan:
    """Share `buoys` (lat, lon) among the vehicles `homes` ({sysid: (lat, lon)}, in layer order: also the order
    in which the vehicles of a depot take off). Raises planner.errors.InputError for what plan_fleet refuses."""
    model = model or EnergyModel.load()
    sysids = list(homes)
    origin = homes[sysids[0]]
    frame = LocalFrame(origin[0], origin[1], 0.0)
    depot_points = frame.project(np.array([homes[s] for s in sysids], dtype=float)).reshape(-1, 2)
    buoy_points = frame.project(np.array(buoys, dtype=float)).reshape(-1, 2)
    # one node per distinct home (vehicles on one pad share it), then the buoys
    unique, inverse = np.unique(np.round(depot_points, 3), axis=0, return_inverse=True)
    depot_of_vehicle = [int(d) for d in np.ravel(inverse)]
    points = np.vstack([unique, buoy_points])
    first_buoy = len(unique)
    altitudes = [altitude_m + layer * layer_gap_m for layer in range(len(sysids))]
    zones = depot_zones(depot_points, separation_m)
    terms = fleet_time_terms(points, depot_of_vehicle, altitudes, speed_m_s, dwell_s, model)
    room = split_offsets(zones, depot_points, altitudes.__getitem__, speed_m_s, dwell_s, model)
    result = plan_fleet(
        points, depot_of_vehicle, speed_m_s, terms.dwell_s, terms.fixed_s + room, seed, time_limit_s,
        leg_time_s=terms.leg_time_s,
    )  # fmt: skip
    orders = {k: [node - first_buoy for node in route.buoys] for k, route in enumerate(result.routes) if route.buoys}
    shares = [  # a vehicle without buoys stays on the ground (the answer lists the shares only)
        FleetShare(
            sysids[k], order,
            sorties_plan(homes[sysids[k]], [buoys[i] for i in order], [buoy_ids[i] for i in order],
                         [list(range(len(order)))], METHOD, result.elapsed_s),
            altitudes[k], 0.0, 0.0, None, 0.0, homes[sysids[k]], 0.0,
        )
        for k, order in orders.items()
    ]  # fmt: skip
    return fleet_plan(in_turn(shares, homes, speed_m_s, dwell_s, separation_m, model), result.elapsed_s, layer_gap_m,
                      separation_m)  # fmt: skip


def in_turn(
    shares: list[FleetShare],
    homes: dict[int, tuple[float, float]],
    speed_m_s: float,
    dwell_s: float,
    separation_m: float,
    model: EnergyModel,
) -> list[FleetShare]:
    """The shares with their turns at their depots (planner.fleet_schedule) and predicted times, for their plans
    as they are (`homes` in departure order, as plan_fleet_mission's). A share flown in several sorties (within its
    battery) takes off in its turn, but its later landings and take-offs wait on the operator's pack swaps: it is
    given no hold, and its predicted time stays its sorties' flight time (swaps not counted)."""
    sysids = list(homes)
    frame = LocalFrame(*homes[sysids[0]], 0.0)
    homes_en = frame.project(np.array([homes[s] for s in sysids], dtype=float)).reshape(-1, 2)
    zones = depot_zones(homes_en, separation_m)
    index = {sysid: k for k, sysid in enumerate(sysids)}
    timelines = {}
    for share in shares:
        flown = [share.plan.buoys_lat_lon[i] for i in share.plan.order]
        route = frame.project(np.array(flown, dtype=float)).reshape(-1, 2)
        k = index[share.sysid]
        timelines[k] = share_timeline([homes_en[k], *route], share.altitude_m, speed_m_s, dwell_s, model)
    slots = schedule(zones, timelines, model, speed_m_s)
    zone_of = {k: zone for zone in zones for k in zone.vehicles}
    scheduled = []
    for share in shares:
        k = index[share.sysid]
        slot, zone = slots[k], zone_of[k]
        in_sorties = len(share.plan.sortie_orders()) > 1
        hold = 0.0 if in_sorties else slot.hold_s
        centre = frame.unproject(zone.centre_en.reshape(1, 2))[0]
        scheduled.append(
            replace(
                share,
                predicted_time_s=share.predicted_time_s if in_sorties else timelines[k].time_s + hold,
                start_s=slot.start_s,
                depart_after=None if slot.after is None else sysids[slot.after],
                final_hold_s=hold,
                zone_centre=(float(centre[0]), float(centre[1])),
                zone_radius_m=zone.radius_m,
            )
        )
    return scheduled


def fleet_plan(shares: list[FleetShare], elapsed_s: float, layer_gap_m: float, separation_m: float) -> FleetMissionPlan:
    """The fleet's plan from its scheduled shares: the makespan is the latest predicted start + flight."""
    return FleetMissionPlan(
        shares,
        max((s.start_s + s.predicted_time_s for s in shares), default=0.0),
        float(sum(s.predicted_time_s for s in shares)),
        float(elapsed_s),
        layer_gap_m,
        separation_m,
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
                makespan = max([t, *(times[o] for o in routes if o != sysid)])  # one vehicle left: its own
                key = (makespan, t - times[sysid])
                if best is None or key < best[0]:
                    best = (key, sysid, trial, t)
        assert best is not None  # `nearest` needed a flying vehicle, and each offers at least one place
        _, sysid, trial, t = best
        routes[sysid], times[sysid] = trial, t
    return routes
