"""A fleet mission carried on by the next coordinator (after a restart, or a stand-by instance that took the fleet's
vehicles over: gcs.missions.ownership), from what the coordinator before it stored (gcs.domain.fleet_coordination):
which losses were re-shared already, and which decided re-shares their receivers never flew. Pure: plans from
stored records."""

from __future__ import annotations

from dataclasses import replace

from gcs.domain.fleet_coordination import FleetCoordination
from gcs.domain.planning import Plan, sorties_plan
from gcs.domain.status import TERMINAL
from gcs.storage import MissionRecord


def _sysid(part: MissionRecord) -> int:
    assert part.vehicle_sysid is not None  # every part is stored with its vehicle's system id
    return part.vehicle_sysid


def grown_plan(fleet_plan: Plan, part_plan: Plan, added: list[int], order: list[int]) -> Plan:
    """A part's plan grown by the fleet mission's buoys `added` (numbered after its own), flown in `order` (the
    part's buoy indices still to fly)."""
    plan = sorties_plan(
        part_plan.depot,
        [*part_plan.buoys_lat_lon, *(fleet_plan.buoys_lat_lon[b] for b in added)],
        [*part_plan.buoy_ids, *(fleet_plan.buoy_ids[b] for b in added)],
        [order],
        part_plan.method,
        part_plan.elapsed_s,
    )
    marks = [*map(part_plan.mark, range(len(part_plan.buoy_ids))), *map(fleet_plan.mark, added)]
    # the part's fence and rally points stay its own (the request's, uploaded before the mission)
    return replace(plan, marks=marks, fence=part_plan.fence, rally_points=part_plan.rally_points)


def handled_losses(fleet: MissionRecord, parts: list[MissionRecord]) -> set[int]:
    """The lost parts whose buoys were re-shared (their shares marked lost, in the transaction of the re-share)."""
    assert fleet.plan.fleet is not None  # a fleet mission's plan has its fleet section
    shares = fleet.plan.fleet
    return {part.id for part in parts if shares.share_of(_sysid(part)).lost is not None}


def undelivered_plans(fleet: MissionRecord, parts: list[MissionRecord], state: FleetCoordination) -> dict[int, Plan]:
    """The new plans a coordinator before this one decided (its re-shares, stored) and its receivers never flew:
    part id -> its plan grown by the buoys its share gained. A share longer than its part's stored plan is one (a
    part stores its new plan once it has uploaded it to its vehicle)."""
    assert fleet.plan.fleet is not None
    orders: dict[str, list[int]] = {}
    for decided in state.reshares:  # the latest order for each receiver
        orders.update(decided.orders)
    plans = {}
    for part in parts:
        sysid = _sysid(part)
        share, have = fleet.plan.fleet.share_of(sysid), len(part.plan.buoy_ids)
        if part.status in TERMINAL or len(share.buoys) <= have:
            continue
        added, done = share.buoys[have:], set(part.progress.visited_buoys)
        order = [i for i in orders.get(str(sysid), []) if i < have + len(added) and i not in done]
        order += [i for i in range(have + len(added)) if i not in order and i not in done]
        plans[part.id] = grown_plan(fleet.plan, part.plan, added, order)
    return plans
