"""A fleet mission's shares made flyable within a battery and a geofence, as a single mission is.

planner.fleet.plan_fleet shares the buoys by time alone (gcs.missions.fleet_planning). With `battery`, a share must
be flown in sorties that each fit its vehicle's pack: a buoy that no sortie from its vehicle's home can serve
(flying to it alone and back needs more than one battery, `UnreachableBuoyError`) goes to the vehicle that can serve
it and whose share grows least (cheapest insertion); one that no vehicle can serve is a 422 naming it. Each share is
then split into sorties by the single mission's machinery (gcs.missions.energy_planning.energy_plan: its vehicle's
pack and reserve, the forecast wind, its own layer's altitude), so every sortie of every share fits by the exact
prediction, and the share's predicted time is its sorties' flight time (the swaps between them are the operator's).
Each vehicle's fence (the request's `geofence`, else the one the vehicle holds, as a single mission's default): a
buoy outside it goes to a vehicle whose fence holds it (the same cheapest insertion), one outside every vehicle's
is a 422; each share is routed from its home around its fence's forbidden legs as a single tour is
(gcs.domain.planning.fenced_legs, make_plan or energy_plan), and a share that still needs a forbidden leg is a 422.

Pure computation (CPU-bound: the service runs it in a worker thread).
"""

from __future__ import annotations

import itertools
from dataclasses import replace

import numpy as np

from gcs.domain.planning import FlightParams, Plan, fenced_legs, local_nodes, make_plan
from gcs.domain.schemas import PlannerOptions
from gcs.missions.energy_planning import (
    BatteryPlan,
    budget,
    energy_plan,
    route_flight,
    sortie_energy,
    unreachable_errors,
)
from gcs.missions.fleet_planning import FleetMissionPlan, FleetShare, fleet_plan, in_turn
from gcs.missions.validation import RequestInvalidError, validate_fenced_route
from planner.energy import EnergyModel
from planner.errors import UnreachableBuoyError
from uavcore.geofence import Geofence

LatLon = tuple[float, float]


def out_and_back_wh(
    home: LatLon, buoys: list[LatLon], flight: FlightParams, battery: BatteryPlan, model: EnergyModel
) -> np.ndarray:
    """The energy (Wh) the model predicts for a sortie to each buoy alone from `home` and back: the least any
    sortie serving it can use."""
    points = np.vstack([[0.0, 0.0], local_nodes(home, buoys)[1]])
    return np.array(
        [sortie_energy(points, [j], route_flight(flight), battery.wind, model)[0] for j in range(len(buoys))]
    )


def _tour_m(points: np.ndarray, home: np.ndarray, order: list[int]) -> float:
    stops = [home, *(points[b] for b in order), home]
    return float(sum(np.hypot(*(b - a)) for a, b in itertools.pairwise(stops)))


def servable_shares(
    planned: FleetMissionPlan,
    homes: dict[int, LatLon],
    buoys: list[LatLon],
    buoy_ids: list[str],
    flight: FlightParams,
    fences: dict[int, Geofence | None],
    batteries: dict[int, BatteryPlan] | None,
    model: EnergyModel,
) -> dict[int, list[int]]:
    """Each vehicle's buoys (request indices, in plan_fleet's order) after moving every buoy its vehicle cannot
    serve (outside its fence, or beyond one battery from its home) to a vehicle that can, the one whose tour it
    lengthens least. Vehicles plan_fleet gave nothing are in the answer too (they may receive buoys). Raises
    RequestInvalidError naming each buoy no vehicle can serve, and why."""
    sysids = list(homes)
    given = {share.sysid: share for share in planned.shares}
    shares = {sysid: list(given[sysid].buoys) if sysid in given else [] for sysid in sysids}
    inside = {
        sysid: {j for j, (lat, lon) in enumerate(buoys) if fence is None or fence.contains(lat, lon)}
        for sysid, fence in fences.items()
    }
    allowed = {sysid: budget(batteries[sysid], model)["budget_wh"] for sysid in sysids} if batteries else {}

    def needs(sysid: int, indices: list[int]) -> dict[int, float]:
        """Its out-and-back energy to each of these buoys (none without energy planning)."""
        indices = [j for j in indices if j in inside[sysid]]
        if not indices or batteries is None:
            return {}
        share_flight = replace(flight, altitude_m=layer_altitude(planned, sysid, flight))
        wh = out_and_back_wh(homes[sysid], [buoys[j] for j in indices], share_flight, batteries[sysid], model)
        return dict(zip(indices, map(float, wh), strict=True))

    def serves(sysid: int, j: int) -> bool:
        return j in inside[sysid] and (batteries is None or need[sysid][j] <= allowed[sysid])

    # each buoy on its own vehicle first; the others' only for the buoys it cannot serve (a model evaluation each)
    need = {sysid: needs(sysid, shares[sysid]) for sysid in sysids}
    stranded = [j for sysid in sysids for j in shares[sysid] if not serves(sysid, j)]
    for sysid in sysids:
        need[sysid] |= needs(sysid, [j for j in stranded if j not in need[sysid]])
    errors: list[tuple[tuple, str]] = []
    for j in stranded:
        fenced_in = [s for s in sysids if j in inside[s]]
        if not fenced_in:
            errors.append((("body", "buoys", j), f"buoy {buoy_ids[j]} is outside the geofence of every vehicle"))
        elif not any(serves(s, j) for s in fenced_in):
            s = min(fenced_in, key=lambda s: need[s][j] - allowed[s])  # the least short of one battery
            errors += unreachable_errors(UnreachableBuoyError([j + 1], [need[s][j]], allowed[s]), buoy_ids)
    if errors:
        raise RequestInvalidError(errors)
    origin = homes[sysids[0]]
    _, points, _ = local_nodes(origin, buoys)
    home_points = {sysid: local_nodes(origin, [homes[sysid]])[1][0] for sysid in sysids}
    for sysid in sysids:
        for b in [b for b in shares[sysid] if not serves(sysid, b)]:
            shares[sysid].remove(b)
            best_key: tuple[float, int, int] | None = None  # (length after, vehicle, position)
            for other in (s for s in sysids if serves(s, b)):
                order = shares[other]
                for at in range(len(order) + 1):
                    length = _tour_m(points, home_points[other], [*order[:at], b, *order[at:]])
                    if best_key is None or length < best_key[0]:
                        best_key = (length, other, at)
            assert best_key is not None  # some vehicle can serve b: no error was raised
            _, other, at = best_key
            shares[other].insert(at, b)
    return shares


def layer_altitude(planned: FleetMissionPlan, sysid: int, flight: FlightParams) -> float:
    """The altitude a vehicle flies its share at (a vehicle without a share yet: the request's altitude plus the
    layers above, its place among the shares unknown: the highest layer, the dearest climb)."""
    share = next((s for s in planned.shares if s.sysid == sysid), None)
    if share is not None:
        return share.altitude_m
    return max((s.altitude_m for s in planned.shares), default=flight.altitude_m)


def constrained_fleet_plan(
    planned: FleetMissionPlan,
    homes: dict[int, LatLon],
    buoys: list[LatLon],
    buoy_ids: list[str],
    flight: FlightParams,
    fences: dict[int, Geofence | None],
    batteries: dict[int, BatteryPlan] | None,
    options: PlannerOptions,
    model: EnergyModel,
) -> FleetMissionPlan:
    """`planned` with each share flyable (module doc): in sorties within its vehicle's battery (`batteries`
    {sysid: BatteryPlan}, None: no energy planning) and inside and routed around its vehicle's fence (`fences`
    {sysid: the request's fence, or the one the vehicle holds; None: none}). Raises RequestInvalidError."""
    fences = {sysid: None if fence is None or fence.empty else fence for sysid, fence in fences.items()}
    if batteries is None and not any(fences.values()):
        return planned
    order = servable_shares(planned, homes, buoys, buoy_ids, flight, fences, batteries, model)
    layers = {share.sysid: share.altitude_m for share in planned.shares}
    top = max(layers.values(), default=flight.altitude_m)
    flying = [sysid for sysid in homes if order.get(sysid)]
    time_limit_s = options.time_limit_s / max(len(flying), 1)  # the request's time limit, shared
    shares: list[FleetShare] = []
    for sysid in flying:
        own = order[sysid]
        home, own_points, own_ids = homes[sysid], [buoys[b] for b in own], [buoy_ids[b] for b in own]
        share_flight = replace(flight, altitude_m=layers.get(sysid, top))
        fence = fences[sysid]
        fenced = {} if fence is None else fenced_legs(home, np.asarray(own_points), fence)
        plan: Plan
        if batteries is not None:
            try:
                plan = energy_plan(home, own_points, own_ids, share_flight, batteries[sysid], options.seed,
                                   time_limit_s, fenced, options.method, model)  # fmt: skip
            except RequestInvalidError as error:  # its buoys' indices are the share's: name the request's
                raise RequestInvalidError([_request_location(e, own) for e in error.errors]) from None
            assert plan.energy is not None  # energy_plan predicts every sortie
            time_s = sum(sortie.time_s for sortie in plan.energy.sorties)
        else:
            plan = make_plan(home, own_points, own_ids, options.method, options.seed, time_limit_s, fenced)
            time_s = 0.0  # one tour: in_turn prices its timeline (planner.fleet_time)
        validate_fenced_route(plan, fenced)
        # the share's buoys in flying order, and its plan over them in that order (as plan_fleet_mission gives)
        flown = [own[i] for i in plan.order]
        position = {i: k for k, i in enumerate(plan.order)}
        plan = _reindexed(plan, position)
        shares.append(_share(planned, sysid, flown, plan, share_flight.altitude_m, float(time_s)))
    # their turns at the depots again, for the routes and times as they are now (gcs.missions.fleet_planning.in_turn)
    scheduled = in_turn(shares, homes, flight.speed_m_s, flight.dwell_s, planned.separation_m, model)
    return fleet_plan(scheduled, planned.elapsed_s, planned.layer_gap_m, planned.separation_m)


def _share(planned: FleetMissionPlan, sysid: int, buoys: list[int], plan: Plan, altitude_m: float,
           time_s: float) -> FleetShare:  # fmt: skip
    """A share as re-planned here: the sharing's own share of that vehicle with its buoys, plan and time replaced
    (whatever else the sharing says of it kept), or a new one for a vehicle the sharing gave nothing."""
    own = next((share for share in planned.shares if share.sysid == sysid), None)
    if own is None:  # its turn at the depot is given by in_turn
        return FleetShare(sysid, buoys, plan, altitude_m, time_s, 0.0, None, 0.0, plan.depot, 0.0)
    return replace(own, buoys=buoys, plan=plan, predicted_time_s=time_s)


def _request_location(error: tuple[tuple, str], own: list[int]) -> tuple[tuple, str]:
    """An error of a share's plan at ("body", "buoys", i) (i the share's index) at the request's index."""
    location, message = error
    if location[:2] == ("body", "buoys") and len(location) > 2 and isinstance(location[2], int):
        location = ("body", "buoys", own[location[2]], *location[3:])
    return location, message


def _reindexed(plan: Plan, position: dict[int, int]) -> Plan:
    """The same plan with its buoys renumbered (buoy i becomes position[i]) and listed in that order."""
    inverse = sorted(position, key=position.__getitem__)
    sorties = None if plan.sorties is None else [[position[i] for i in s] for s in plan.sorties]
    return replace(
        plan,
        buoy_ids=[plan.buoy_ids[i] for i in inverse],
        buoys_lat_lon=[plan.buoys_lat_lon[i] for i in inverse],
        buoys_local=[plan.buoys_local[i] for i in inverse],
        order=[position[i] for i in plan.order],
        sorties=sorties,
    )
