"""A fleet mission carried on by the next coordinator (gcs.missions.fleet_takeover): which losses were re-shared
already, and which re-shares, decided and stored, their receivers never flew; then the coordinator itself
(gcs.missions.fleet_missions.FleetCoordinator) on a real database left as a killed coordinator leaves it, its
vehicles' links never started (no vehicle in the air: the separation only carried over) and the parts' lifecycle
stood in for by the `replan` it is given (a part re-attached flies what it is told)."""

from __future__ import annotations

import asyncio
import dataclasses
import time

from stored_missions import FLIGHT

from gcs.domain.fleet_coordination import FleetCoordination, Reshare
from gcs.domain.planning import Plan, sorties_plan
from gcs.domain.records import MissionProgress, PlanFleet, PlannedShare
from gcs.domain.schemas import SeparationOut
from gcs.domain.status import TERMINAL, MissionStatus
from gcs.missions.fleet_missions import FOLLOWED_AGAIN, FleetCoordinator
from gcs.missions.fleet_takeover import grown_plan, handled_losses, undelivered_plans
from gcs.missions.lifecycle import MissionConflictError
from gcs.storage import MissionRecord, open_storage
from gcs.storage.off_loop import AsyncStorage
from gcs.vehicle.link import LinkManager

BACKSTOP_S = 60.0  # a wait's deadline: only reached when the behaviour is wrong

HOME = (55.0, 12.0)
# the fleet mission's four buoys: A, B (vehicle 1's share), C, D (vehicle 2's)
POINTS = [(55.0005, 12.0), (55.0005, 12.0008), (54.9995, 12.0), (54.9995, 12.0008)]
FLEET_PLAN = sorties_plan(HOME, POINTS, ["A", "B", "C", "D"], [[0, 1, 2, 3]], "test", 0.0)


def _part_plan(buoys: list[int]):
    return sorties_plan(HOME, [POINTS[b] for b in buoys], [FLEET_PLAN.buoy_ids[b] for b in buoys],
                        [list(range(len(buoys)))], "test", 0.0)  # fmt: skip


def _share(sysid: int, buoys: list[int], lost: str | None = None) -> PlannedShare:
    return PlannedShare(sysid=sysid, home=list(HOME), buoys=buoys, altitude_m=5.0, predicted_time_s=60.0,
                        length_m=1.0, lost=lost)  # fmt: skip


def _fleet(shares: list[PlannedShare]) -> MissionRecord:
    plan = dataclasses.replace(FLEET_PLAN, fleet=PlanFleet(makespan_s=60.0, total_time_s=120.0, layer_gap_m=3.0,
                                                           shares=shares))  # fmt: skip
    return MissionRecord(1, "t", "t", MissionStatus.FLYING, None, FLIGHT, plan, MissionProgress(), None, fleet_id=1)


def _part(mission_id: int, sysid: int, buoys: list[int], status: str, visited: list[int]) -> MissionRecord:
    return MissionRecord(
        mission_id, "t", "t", MissionStatus(status), None, FLIGHT, _part_plan(buoys),
        MissionProgress(visited_buoys=visited), None, vehicle_sysid=sysid, fleet_id=1,
    )  # fmt: skip


def _decided(orders: dict[str, list[int]]) -> FleetCoordination:
    reshare = Reshare(part_id=3, sysid=2, reason="link lost", handed_over={"1": [3]}, orders=orders, at="t")
    return FleetCoordination(fleet_id=1, reshares=[reshare])


def test_a_loss_is_handled_once_its_share_is_marked_lost_whatever_the_parts_status():
    fleet = _fleet([_share(1, [0, 1]), _share(2, [2, 3], lost="link lost")])
    parts = [_part(2, 1, [0, 1], "flying", []), _part(3, 2, [2, 3], "failed", [0])]
    assert handled_losses(fleet, parts) == {3}
    # failed, but its buoys not yet re-shared (the coordinator died first): the next one must re-share them
    fleet = _fleet([_share(1, [0, 1]), _share(2, [2, 3])])
    assert handled_losses(fleet, parts) == set()


def test_a_receiver_whose_part_never_got_its_share_grown_gets_it_in_the_order_decided_without_what_it_visited():
    # vehicle 2 lost after C: D (fleet buoy 3) decided for vehicle 1, in the order B, D; vehicle 1 visited A since
    fleet = _fleet([_share(1, [0, 1, 3]), _share(2, [2, 3], lost="link lost")])
    parts = [_part(2, 1, [0, 1], "flying", [0]), _part(3, 2, [2, 3], "failed", [0])]
    plans = undelivered_plans(fleet, parts, _decided({"1": [0, 1, 2]}))
    assert list(plans) == [2]
    plan = plans[2]
    assert plan.buoy_ids == ["A", "B", "D"] and plan.order == [1, 2]  # its own in the same indices, then D
    assert plan.buoys_lat_lon[2] == list(POINTS[3])
    assert plan == grown_plan(fleet.plan, parts[0].plan, [3], [1, 2])
    # no order stored (a coordinator of an earlier version): its own left, then the added, in index order
    assert undelivered_plans(fleet, parts, FleetCoordination(fleet_id=1))[2].order == [1, 2]


def test_nothing_is_delivered_again_to_a_part_that_flies_its_grown_plan_or_has_ended():
    fleet = _fleet([_share(1, [0, 1, 3]), _share(2, [2, 3], lost="link lost")])
    delivered = _part(2, 1, [0, 1, 3], "flying", [0])  # its plan stored once uploaded: it has D
    assert undelivered_plans(fleet, [delivered, _part(3, 2, [2, 3], "failed", [0])], _decided({"1": [1, 2]})) == {}
    ended = _part(2, 1, [0, 1], "completed", [0, 1])  # landed before anyone told it: D stays not inspected
    assert undelivered_plans(fleet, [ended, _part(3, 2, [2, 3], "failed", [0])], _decided({"1": [1, 2]})) == {}


def _left_by_a_killed_coordinator(path, shares, parts, reshares=()):
    """A database as a coordinator killed in flight left it: the fleet mission flying with `shares`, its parts
    ((sysid, buoys, status, visited) each), its state claimed by gcs-a with a closest approach and `reshares`."""
    storage = open_storage(path)
    fleet_plan = dataclasses.replace(
        FLEET_PLAN, fleet=PlanFleet(makespan_s=60.0, total_time_s=120.0, layer_gap_m=3.0, shares=shares)
    )
    fleet_id, ids = storage.create_fleet_mission(
        FLIGHT, fleet_plan, [(FLIGHT, _part_plan(buoys), sysid) for sysid, buoys, _, _ in parts]
    )
    storage.set_status(fleet_id, MissionStatus.FLYING)
    for part_id, (_, _, status, visited) in zip(ids, parts, strict=True):
        storage.set_status(part_id, MissionStatus(status))
        storage.set_progress(part_id, MissionProgress(visited_buoys=visited))
    storage.claim_fleet(fleet_id, "gcs-a")
    storage.set_fleet_separation(fleet_id, SEPARATION)
    for reshare in reshares:
        storage.record_reshare(fleet_id, fleet_plan, reshare, "vehicle 2 lost")
    return storage, fleet_id, ids


SEPARATION = SeparationOut(min_horizontal_m=2.9, min_vertical_m=0.1, min_distance_m=2.95)


def _no_launch(part: MissionRecord) -> None:
    raise AssertionError(f"part {part.id} started again: every part here was started by the coordinator before")


async def _follow_to_the_end(storage, fleet_id: int, replan) -> MissionRecord:
    """The next coordinator (instance gcs-b) follows the fleet mission until it ends."""
    links = {sysid: LinkManager(sysid=sysid) for sysid in (1, 2)}  # never started: nothing heard
    coordinator = FleetCoordinator(AsyncStorage(storage), links.__getitem__, replan, _no_launch, instance="gcs-b")
    coordinator.follow(fleet_id)
    deadline = time.monotonic() + BACKSTOP_S
    while storage.get_mission(fleet_id).status not in TERMINAL:
        assert time.monotonic() < deadline, storage.get_mission(fleet_id).events
        await asyncio.sleep(0.05)
    await coordinator.stop()
    return storage.get_mission(fleet_id)


def test_a_loss_the_killed_coordinator_never_re_shared_is_re_shared_by_the_next(tmp_path):
    """Vehicle 2's part failed while its coordinator was being killed: its share was never marked lost. The next
    coordinator re-shares it (here nobody is left flying to take D, so the fleet mission fails naming it); the
    closest approach stored before is the fleet mission's result."""
    storage, fleet_id, (_, lost) = _left_by_a_killed_coordinator(
        tmp_path / "gcs.sqlite",
        [_share(1, [0, 1]), _share(2, [2, 3])],
        [(1, [0, 1], "completed", [0, 1]), (2, [2, 3], "failed", [0])],
    )

    def replan(part: MissionRecord, plan: Plan) -> None:
        raise AssertionError(f"nobody flies: part {part.id} cannot be re-planned")

    fleet = asyncio.run(_follow_to_the_end(storage, fleet_id, replan))
    state = storage.fleet_coordination(fleet_id)
    assert state.coordinator == "gcs-b" and state.handled() == {lost}
    assert fleet.plan.fleet.share_of(2).lost == "failed" and fleet.plan.fleet.share_of(2).handed_over == {}
    reasons = [e.reason for e in fleet.events]
    assert FOLLOWED_AGAIN in reasons and "vehicle 2 lost: nobody left to take its buoys" in reasons
    assert (fleet.status, fleet.reason) == ("failed", "vehicle 2 failed; not inspected: D")
    assert fleet.results.separation == SEPARATION == state.separation
    storage.close()


def test_a_re_share_decided_before_the_kill_is_flown_by_its_receiver_once_re_attached_and_no_buoy_is_lost(tmp_path):
    """The killed coordinator decided and stored D for vehicle 1 (order B, D), then died before vehicle 1's part got
    its new plan. The next coordinator tells it once its part flies here again (the first try: not re-attached yet),
    and the fleet mission completes with every buoy."""
    decided = Reshare(part_id=3, sysid=2, reason=None, handed_over={"1": [3]}, orders={"1": [1, 2]}, at="t")
    storage, fleet_id, (receiver, _) = _left_by_a_killed_coordinator(
        tmp_path / "gcs.sqlite",
        [_share(1, [0, 1, 3]), _share(2, [2, 3], lost="failed")],
        [(1, [0, 1], "flying", [0]), (2, [2, 3], "failed", [0])],
        [decided],
    )
    told: list[tuple[int, Plan]] = []

    def replan(part: MissionRecord, plan: Plan) -> None:
        told.append((part.id, plan))
        if len(told) == 1:
            raise MissionConflictError(f"mission {part.id} is not flying here")  # not re-attached yet
        # the part flies it: stores it once uploaded, visits B and D, lands
        storage.set_plan(part.id, plan)
        storage.set_progress(part.id, MissionProgress(visited_buoys=[0, 1, 2]))
        storage.set_status(part.id, MissionStatus.COMPLETED)

    fleet = asyncio.run(_follow_to_the_end(storage, fleet_id, replan))
    assert [part_id for part_id, _ in told] == [receiver, receiver]
    assert told[1][1].buoy_ids == ["A", "B", "D"] and told[1][1].order == [1, 2]
    assert (fleet.status, fleet.reason) == ("completed", None)
    assert fleet.progress.visited_buoys == [0, 1, 2, 3]
    assert fleet.results.inspected_by == {"A": 1, "B": 1, "C": 2, "D": 1}
    assert storage.fleet_coordination(fleet_id).reshares == [decided]  # delivered, not decided again
    storage.close()
