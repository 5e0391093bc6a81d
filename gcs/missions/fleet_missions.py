"""Fleet missions, followed: a mission whose buoys are shared among vehicles (gcs.missions.fleet_planning) flies as one
part mission per vehicle, each an ordinary mission flown and recorded by its vehicle's lifecycle. Here the fleet
mission follows its parts: its status (flying once launched; completed when every part completed, else failed or
aborted naming the vehicles and the buoys not inspected), its progress (each share's status and inspected
buoys), and a separation monitor records how close any two vehicles came while both were in the air.

What it needs to carry on after a restart, or when a stand-by instance takes the fleet's vehicles over
(gcs.missions.ownership), is in the database as it changes (gcs.domain.fleet_coordination): the separation so far,
and each re-share, stored with the fleet mission's plan in one transaction before the receiving parts are told. The
next coordinator so re-shares a loss nobody handled, and delivers a decided re-share whose receivers did not get
their new plans.
"""

from __future__ import annotations

import asyncio
import contextlib
import itertools
import logging
import math
from collections.abc import Callable
from dataclasses import asdict, dataclass, replace
from datetime import UTC, datetime
from typing import Any

import numpy as np

from gcs.domain.fleet_coordination import Reshare
from gcs.domain.listing import stored_time
from gcs.domain.planning import Plan
from gcs.domain.records import MissionProgress, MissionResults, ShareProgress
from gcs.domain.schemas import PlanRequest, SeparationOut
from gcs.domain.status import TERMINAL, MissionStatus
from gcs.missions.fleet_planning import reshare
from gcs.missions.fleet_takeover import grown_plan, handled_losses, undelivered_plans
from gcs.missions.lifecycle import MissionConflictError, ended_by_the_vehicle
from gcs.missions.validation import RequestInvalidError
from gcs.settings import Limits
from gcs.storage import MissionRecord
from gcs.storage.off_loop import AsyncStorage
from gcs.vehicle.link import LinkManager
from uavcore.geodesy import LocalFrame

log = logging.getLogger(__name__)

POLL_S = 0.5  # wall seconds between reads of the parts' state
AIRBORNE_M = 1.0  # above home: a vehicle higher than this counts as in the air for the separation
# the fleet mission's event when a coordinator (after a restart, or a stand-by that took over) follows it again
FOLLOWED_AGAIN = "GCS restarted or taken over; following the fleet mission again"


@dataclass
class Separation:
    """The closest approach of any two vehicles in the air: horizontal, vertical and 3-D, each its own minimum."""

    min_horizontal_m: float | None = None
    min_vertical_m: float | None = None
    min_distance_m: float | None = None

    def fold(self, positions: dict[int, tuple[float, float, float]]) -> None:
        """Take in one instant's positions (north, east, up in metres, one frame) of the vehicles in the air."""
        for a, b in itertools.combinations(sorted(positions), 2):
            (na, ea, ua), (nb, eb, ub) = positions[a], positions[b]
            horizontal, vertical = math.hypot(na - nb, ea - eb), abs(ua - ub)
            self.min_horizontal_m = _lower(self.min_horizontal_m, horizontal)
            self.min_vertical_m = _lower(self.min_vertical_m, vertical)
            self.min_distance_m = _lower(self.min_distance_m, math.hypot(horizontal, vertical))


def _lower(current: float | None, value: float) -> float:
    return value if current is None else min(current, value)


class SeparationMonitor:
    """Folds the vehicles' latest positions into a Separation each time one of them reports its position
    (GLOBAL_POSITION_INT): every pair is compared at the rate the positions come, 10 Hz per vehicle."""

    def __init__(self, frame: LocalFrame, links: dict[int, LinkManager]) -> None:
        self.frame, self.links = frame, links
        self.separation = Separation()
        self._positions: dict[int, tuple[float, float, float]] = {}
        self._listeners = {sysid: self._listener(sysid) for sysid in links}

    def _listener(self, sysid: int) -> Callable[[Any], None]:
        def heard(message: Any) -> None:
            if message.get_type() == "GLOBAL_POSITION_INT":
                self._update(sysid)

        return heard

    def start(self) -> None:
        for sysid, link in self.links.items():
            link.add_listener(self._listeners[sysid])

    def stop(self) -> None:
        for sysid, link in self.links.items():
            link.remove_listener(self._listeners[sysid])

    def _update(self, sysid: int) -> None:
        for other, link in self.links.items():  # a vehicle whose link fell silent is nowhere known any more
            if not link.status.connected:
                self._positions.pop(other, None)
        status = self.links[sysid].status
        if status.lat is None or status.lon is None or status.alt_m is None or status.alt_m < AIRBORNE_M:
            self._positions.pop(sysid, None)
            return
        east, north = self.frame.project([[status.lat, status.lon]])[0]  # the homes share one altitude
        self._positions[sysid] = (float(north), float(east), float(status.alt_m))
        if len(self._positions) > 1:
            self.separation.fold(self._positions)


def _vehicle_of(part: MissionRecord) -> int:
    """The system id a fleet mission's part flies on: every part is stored with its vehicle's."""
    assert part.vehicle_sysid is not None
    return part.vehicle_sysid


def _separation_out(separation: Separation) -> SeparationOut:
    return SeparationOut.model_validate(asdict(separation))


def shares_progress(fleet: MissionRecord, parts: list[MissionRecord]) -> MissionProgress:
    """Each share's part mission, status and inspected buoys (input indices of the fleet mission)."""
    assert fleet.plan.fleet is not None  # a fleet mission's plan has its fleet section
    shares = [
        ShareProgress(
            sysid=share.sysid,
            mission_id=part.id,
            status=part.status,
            visited=[share.buoys[i] for i in part.progress.visited_buoys],
        )
        for share, part in zip(fleet.plan.fleet.shares, parts, strict=True)
    ]
    return MissionProgress(
        shares=shares,
        visited=sum(len(s.visited) for s in shares),
        buoys=len(fleet.plan.buoy_ids),
        visited_buoys=sorted(b for s in shares for b in s.visited),
    )


def fleet_ending(fleet: MissionRecord, parts: list[MissionRecord]) -> tuple[MissionStatus, str | None]:
    """The fleet mission's end from its parts': aborted when the operator aborted a part; completed when every
    buoy was inspected by someone (a lost vehicle's share re-shared to the others counts: the loss is in the
    events and the shares); else failed, naming each vehicle that did not complete and the buoys not inspected."""
    progress = shares_progress(fleet, parts)
    ids = fleet.plan.buoy_ids
    missed = [ids[b] for b in range(len(ids)) if b not in set(progress.visited_buoys)]
    # a part its vehicle's battery failsafe ended aborted was lost, as one that failed: the operator aborted none
    aborted = any(part.status == MissionStatus.ABORTED and not ended_by_the_vehicle(part.status, part.reason)
                  for part in parts)  # fmt: skip
    if not missed and not aborted:
        return MissionStatus.COMPLETED, None
    problems = [
        f"vehicle {share.sysid} {part.status}" + (f" ({part.reason})" if part.reason else "")
        for share, part in zip(progress.shares, parts, strict=True)
        if part.status != MissionStatus.COMPLETED
    ]
    reason = "; ".join(problems) + (f"; not inspected: {', '.join(missed)}" if missed else "")
    return (MissionStatus.ABORTED if aborted else MissionStatus.FAILED), reason


def fleet_vehicles(request: PlanRequest, known: list[int], limits: Limits) -> list[int]:
    """The system ids a fleet mission request flies (in layer order), or RequestInvalidError naming each field
    that cannot be flown as a fleet."""
    errors: list[tuple[tuple[str | int, ...], str]] = []
    wanted = list(known) if request.vehicles == "fleet" else list(request.vehicles or [])
    if request.vehicle is not None:
        errors.append((("body", "vehicle"), "a fleet mission names its vehicles in `vehicles` only"))
    if request.depot is not None:
        errors.append((("body", "depot"), "a fleet flies from its vehicles' homes"))
    for i, sysid in enumerate(wanted):
        if sysid not in known:
            errors.append((("body", "vehicles", i), f"no vehicle with system id {sysid} (the fleet's: {known})"))
        elif sysid in wanted[:i]:
            errors.append((("body", "vehicles", i), f"vehicle {sysid} is named twice"))
    if not wanted:
        errors.append((("body", "vehicles"), "no vehicle to fly"))
    top = request.altitude_m + (len(wanted) - 1) * request.layer_gap_m
    if wanted and top > limits.altitude_m[1]:
        errors.append(
            (("body", "layer_gap_m"), f"the top layer, {top:g} m, is above the airframe's {limits.altitude_m[1]:g} m")
        )
    if errors:
        raise RequestInvalidError(errors)
    return wanted


def may_depart(
    fleet: MissionRecord, part: MissionRecord, parts: list[MissionRecord], link_of: Callable[[int], LinkManager]
) -> bool:
    """Whether a planned part may start now (planner.fleet_schedule: one vehicle at a time in a depot's zone): it
    waits for nobody, or the vehicle it waits for has left the zone (its position is farther from the zone's
    centre than the radius: then at least separation_m from every pad) or its part has ended."""
    assert fleet.plan.fleet is not None  # a fleet mission's plan has its fleet section
    share = fleet.plan.fleet.share_of(_vehicle_of(part))
    ahead = next((p for p in parts if _vehicle_of(p) == share.depart_after), None)
    if share.depart_after is None or ahead is None or ahead.status in TERMINAL:
        return True
    status = link_of(share.depart_after).status
    if ahead.status == MissionStatus.PLANNED or share.zone_centre is None or status.lat is None or status.lon is None:
        return False
    zone = LocalFrame(share.zone_centre[0], share.zone_centre[1], 0.0)
    east, north = zone.project([[status.lat, status.lon]])[0]
    return math.hypot(east, north) > (share.zone_radius_m or 0.0)


class FleetCoordinator:
    """Follows each fleet mission in flight (one task per fleet mission) until its parts have ended."""

    def __init__(
        self,
        storage: AsyncStorage,
        link_of: Callable[[int], LinkManager],
        replan: Callable[[MissionRecord, Plan], None],
        launch: Callable[[MissionRecord], None],
        *,
        instance: str = "",
    ) -> None:
        """link_of(sysid): a vehicle's link; replan(part, plan): fly a part on with a new plan, in flight (raises
        MissionConflictError when that part is not flying); launch(part): fly a planned part (its turn to take off
        has come: `may_depart`; raises MissionConflictError when its vehicle is busy); instance: this service
        instance's name, stored as the fleet missions' coordinator."""
        self.storage, self._link_of, self._replan, self._launch = storage, link_of, replan, launch
        self.instance = instance
        self._tasks: dict[int, asyncio.Task] = {}

    def follow(self, fleet_id: int) -> None:
        """Follow a fleet mission whose parts were launched (or, after a restart, re-attached)."""
        if fleet_id not in self._tasks or self._tasks[fleet_id].done():
            self._tasks[fleet_id] = asyncio.create_task(self._follow(fleet_id), name=f"fleet-{fleet_id}")

    def active(self, fleet_id: int) -> bool:
        task = self._tasks.get(fleet_id)
        return task is not None and not task.done()

    async def stop(self) -> None:
        """Stop following (the parts are the lifecycles' to stop; a fleet left flying is followed again on
        restart, from `Storage.unfinished_fleets`)."""
        for task in self._tasks.values():
            task.cancel()
        for task in self._tasks.values():
            with contextlib.suppress(asyncio.CancelledError):
                await task

    async def _follow(self, fleet_id: int) -> None:
        try:
            await self._follow_parts(fleet_id)
        except asyncio.CancelledError:
            raise  # the service stops: the fleet mission is followed again when it restarts
        except Exception as error:  # never leave a fleet mission flying with nobody following it
            log.exception("fleet mission %s", fleet_id)
            await self.storage.set_status(
                fleet_id, MissionStatus.FAILED, f"internal error: {type(error).__name__}: {error}"
            )

    async def _follow_parts(self, fleet_id: int) -> None:
        fleet = await self.storage.existing_mission(fleet_id)
        parts = await self.storage.fleet_parts(fleet_id)
        state = await self.storage.claim_fleet(fleet_id, self.instance)
        frame = fleet.plan.frame
        monitor = SeparationMonitor(frame, {sysid: self._link_of(sysid) for sysid in map(_vehicle_of, parts)})
        monitor.separation = Separation(**state.separation.model_dump())  # the closest approach before, if any
        monitor.start()
        # a fleet mission already flying was followed by a coordinator before this one: carry on from its state
        undelivered = undelivered_plans(fleet, parts, state) if fleet.status == MissionStatus.FLYING else {}
        await self.storage.set_status(
            fleet_id, MissionStatus.FLYING, FOLLOWED_AGAIN if fleet.status == MissionStatus.FLYING else None
        )
        stored: MissionProgress | None = None
        stored_separation = replace(monitor.separation)
        # the lost parts whose buoys went to others (by this coordinator or one before it)
        lost = handled_losses(fleet, parts)
        started: set[int] = set()  # parts this task started in their turn (stored `planned` until their flight begins)
        try:
            while True:
                parts = await self.storage.fleet_parts(fleet_id)
                undelivered = self._deliver(parts, undelivered)
                for part in parts:
                    waiting = part.status == MissionStatus.PLANNED and part.id not in started  # its status lags
                    if waiting and may_depart(fleet, part, parts, self._link_of):
                        started.add(part.id)
                        await self._depart(fleet, part)
                    # lost: its link, a reboot, or a failsafe (battery, geofence) brought it down
                    if ended_by_the_vehicle(part.status, part.reason) and part.id not in lost:
                        lost.add(part.id)
                        fleet = await self._reshare(fleet, part, parts)
                progress = shares_progress(fleet, parts)
                if progress != stored:
                    await self.storage.set_progress(fleet_id, progress)
                    stored = progress
                if monitor.separation != stored_separation:
                    stored_separation = replace(monitor.separation)
                    await self.storage.set_fleet_separation(fleet_id, _separation_out(stored_separation))
                if all(part.status in TERMINAL for part in parts):
                    break
                await asyncio.sleep(POLL_S)
        finally:
            monitor.stop()
        ids = fleet.plan.buoy_ids
        inspected_by = {ids[b]: share.sysid for share in progress.shares for b in share.visited}
        separation = _separation_out(monitor.separation)
        await self.storage.set_fleet_separation(fleet_id, separation)
        await self.storage.set_results(fleet_id, MissionResults(separation=separation, inspected_by=inspected_by))
        status, reason = fleet_ending(fleet, parts)
        await self.storage.set_status(fleet_id, status, reason)
        log.info("fleet mission %s %s%s", fleet_id, status, f": {reason}" if reason else "")

    def _deliver(self, parts: list[MissionRecord], undelivered: dict[int, Plan]) -> dict[int, Plan]:
        """Tell each receiver of an earlier re-share its new plan once its part flies here again (re-attached);
        returns those still waiting. A part that ended meanwhile keeps its buoys not inspected (the end names them)."""
        waiting = {}
        for part in parts:
            if (plan := undelivered.get(part.id)) is None or part.status in TERMINAL:
                continue
            try:
                self._replan(part, plan)
            except MissionConflictError:  # not re-attached yet: at the next poll
                waiting[part.id] = plan
                continue
            log.warning("fleet mission: part %s flies the re-share decided before the take-over", part.id)
        return waiting

    def _clock_s(self, sysid: int) -> float | None:
        """A vehicle's time as last heard (time_boot_ms / 1000)."""
        boot_ms = self._link_of(sysid).status.time_boot_ms
        return None if boot_ms is None else boot_ms / 1000.0

    async def _depart(self, fleet: MissionRecord, part: MissionRecord) -> None:
        """Start a part whose turn to take off has come, noting both vehicles' clocks; a vehicle taken meanwhile
        fails the part (its buoys are then re-shared like a lost vehicle's)."""
        try:
            self._launch(part)
        except MissionConflictError as error:
            await self.storage.set_status(part.id, MissionStatus.FAILED, f"not started in its turn: {error}")
            return
        assert fleet.plan.fleet is not None  # a fleet mission's plan has its fleet section
        share = fleet.plan.fleet.share_of(_vehicle_of(part))
        share.started_t_s = self._clock_s(share.sysid)
        if share.depart_after is not None:
            share.ahead_t_s = self._clock_s(share.depart_after)
        await self.storage.set_plan(fleet.id, fleet.plan)

    async def _reshare(
        self, fleet: MissionRecord, lost_part: MissionRecord, parts: list[MissionRecord]
    ) -> MissionRecord:
        """A part ended failed (its vehicle lost, or a failsafe brought it down): its buoys not inspected go to the
        vehicles still flying their shares (gcs.missions.fleet_planning.reshare), each uploaded in flight as its part's
        new plan. The fleet mission's plan records who took what; its events say so. Returns the fleet re-read."""
        plan = fleet.plan
        assert plan.fleet is not None  # a fleet mission's plan has its fleet section
        shares = {share.sysid: share for share in plan.fleet.shares}  # changed in place, stored with the re-share
        lost_share = shares[_vehicle_of(lost_part)]
        visited = set(lost_part.progress.visited_buoys)
        orphans = [b for i, b in enumerate(lost_share.buoys) if i not in visited]
        lost_share.lost = lost_part.reason or "failed"
        # every buoy in the fleet's frame (the overview plan's: the first vehicle's home); a share's buoy i is
        # buoy share.buoys[i] there
        points = np.asarray(plan.buoys_local)
        receivers: dict[int, tuple[MissionRecord, Plan, list[int]]] = {}  # sysid -> part, its plan, buoys left
        # sysid -> (where it is, its buoys left, its home) for reshare
        positions: dict[int, tuple[np.ndarray, np.ndarray, np.ndarray]] = {}
        for part in parts:
            sysid = _vehicle_of(part)
            status = self._link_of(sysid).status
            flying = status.connected and status.armed and not status.mission_complete and status.lat is not None
            # a part flying sorties within its battery takes nothing in flight: more buoys could overrun the pack
            if part.status != MissionStatus.FLYING or not flying or part.plan.energy is not None:
                continue
            part_plan, done = part.plan, set(part.progress.visited_buoys)
            left = [i for i in part_plan.order if i not in done]
            share = shares[sysid]
            here, home = plan.frame.project(np.array([[status.lat, status.lon], share.home], dtype=float))
            receivers[sysid] = (part, part_plan, left)
            positions[sysid] = (here, points[[share.buoys[i] for i in left]].reshape(-1, 2), home)
        handed: dict[int, list[int]] = {}
        told: dict[int, tuple[MissionRecord, Plan]] = {}  # sysid -> its part and its new plan, once stored
        orders: dict[str, list[int]] = {}
        if orphans and receivers:
            routes = reshare(positions, points[orphans], fleet.flight.speed_m_s, fleet.flight.dwell_s)
            for sysid, (part, part_plan, left) in receivers.items():
                new_order, added = [], []  # in the part's buoy indices; the lost buoys it takes, appended
                for node in routes[sysid]:
                    if node < len(left):
                        new_order.append(left[node])
                    else:
                        added.append(orphans[node - len(left)])
                        new_order.append(len(part_plan.buoy_ids) + len(added) - 1)
                if not added:
                    continue
                told[sysid] = (part, grown_plan(plan, part_plan, added, new_order))
                shares[sysid].buoys = [*shares[sysid].buoys, *added]
                handed[sysid], orders[str(sysid)] = added, new_order
        lost_share.handed_over = {str(sysid): buoys for sysid, buoys in handed.items()}
        names = {sysid: ", ".join(plan.buoy_ids[b] for b in buoys) for sysid, buoys in handed.items()}
        given = "; ".join(f"{names[sysid]} to vehicle {sysid}" for sysid in names) or "nobody left to take its buoys"
        why = f" ({lost_part.reason})" if lost_part.reason else ""
        decided = Reshare(
            part_id=lost_part.id,
            sysid=_vehicle_of(lost_part),
            reason=lost_part.reason,
            handed_over=lost_share.handed_over,
            orders=orders,
            at=stored_time(datetime.now(UTC)),
        )
        # decided and stored before any receiver is told: a coordinator killed in between leaves a decision its
        # successor delivers (`undelivered_plans`), never buoys told to a vehicle the fleet mission does not know of
        await self.storage.record_reshare(
            fleet.id, plan, decided, f"vehicle {lost_part.vehicle_sysid} lost{why}: {given}"
        )
        log.warning("fleet mission %s: vehicle %s lost; %s", fleet.id, lost_part.vehicle_sysid, given)
        refused = []
        for sysid, (part, new_plan) in told.items():
            try:
                self._replan(part, new_plan)
            except MissionConflictError:  # it landed or ended meanwhile: the buoys stay not inspected
                refused.append(sysid)
        if refused:  # the fleet mission's plan says who really took what
            for sysid in refused:
                shares[sysid].buoys = shares[sysid].buoys[: -len(handed[sysid])]
                del lost_share.handed_over[str(sysid)]
            await self.storage.set_plan(fleet.id, plan)
            ended = ", ".join(map(str, refused))
            await self.storage.set_status(
                fleet.id, MissionStatus.FLYING, f"vehicle(s) {ended} ended before taking their buoys: not re-shared"
            )
        return await self.storage.existing_mission(fleet.id)
