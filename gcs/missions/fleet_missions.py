"""Fleet missions, followed: a mission whose buoys are shared among vehicles (gcs.missions.fleet_planning) flies as one
part mission per vehicle, each an ordinary mission flown and recorded by its vehicle's lifecycle. Here the fleet
mission follows its parts: its status (flying once launched; completed when every part completed, else failed or
aborted naming the vehicles and the buoys not inspected), its progress (each share's status and inspected
buoys), and a separation monitor records how close any two vehicles came while both were in the air.
"""

from __future__ import annotations

import asyncio
import contextlib
import itertools
import logging
import math
from collections.abc import Callable
from dataclasses import asdict, dataclass, replace
from typing import Any

import numpy as np

from gcs.domain.planning import Plan, sorties_plan
from gcs.domain.records import MissionProgress, MissionResults, ShareProgress
from gcs.domain.schemas import PlanRequest, SeparationOut
from gcs.domain.status import TERMINAL, MissionStatus
from gcs.missions.fleet_planning import reshare
from gcs.missions.lifecycle import MissionConflictError
from gcs.missions.validation import RequestInvalidError
from gcs.settings import Limits
from gcs.storage import MissionRecord
from gcs.storage.off_loop import AsyncStorage
from gcs.vehicle.link import LinkManager
from uavcore.geodesy import LocalFrame

log = logging.getLogger(__name__)

POLL_S = 0.5  # wall seconds between reads of the parts' state
AIRBORNE_M = 1.0  # above home: a vehicle higher than this counts as in the air for the separation


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
    aborted = any(part.status == MissionStatus.ABORTED for part in parts)
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
    for field_name in ("battery", "geofence", "depot"):
        if getattr(request, field_name) is not None:
            why = "a fleet flies from its vehicles' homes" if field_name == "depot" else "not with a fleet (yet)"
            errors.append((("body", field_name), why))
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
    ) -> None:
        """link_of(sysid): a vehicle's link; replan(part, plan): fly a part on with a new plan, in flight (raises
        MissionConflictError when that part is not flying); launch(part): fly a planned part (its turn to take off
        has come: `may_depart`; raises MissionConflictError when its vehicle is busy)."""
        self.storage, self._link_of, self._replan, self._launch = storage, link_of, replan, launch
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
        frame = fleet.plan.frame
        monitor = SeparationMonitor(frame, {sysid: self._link_of(sysid) for sysid in map(_vehicle_of, parts)})
        monitor.start()
        if fleet.status != MissionStatus.FLYING:
            await self.storage.set_status(fleet_id, MissionStatus.FLYING)
        stored: MissionProgress | None = None
        lost: set[int] = {p.id for p in parts if p.status == MissionStatus.FAILED}  # before a restart: handled
        started: set[int] = set()  # parts this task started in their turn (stored `planned` until their flight begins)
        try:
            while True:
                parts = await self.storage.fleet_parts(fleet_id)
                for part in parts:
                    waiting = part.status == MissionStatus.PLANNED and part.id not in started  # its status lags
                    if waiting and may_depart(fleet, part, parts, self._link_of):
                        started.add(part.id)
                        await self._depart(fleet, part)
                    if part.status == MissionStatus.FAILED and part.id not in lost:
                        lost.add(part.id)
                        fleet = await self._reshare(fleet, part, parts)
                progress = shares_progress(fleet, parts)
                if progress != stored:
                    await self.storage.set_progress(fleet_id, progress)
                    stored = progress
                if all(part.status in TERMINAL for part in parts):
                    break
                await asyncio.sleep(POLL_S)
        finally:
            monitor.stop()
        ids = fleet.plan.buoy_ids
        inspected_by = {ids[b]: share.sysid for share in progress.shares for b in share.visited}
        separation = SeparationOut.model_validate(asdict(monitor.separation))
        await self.storage.set_results(fleet_id, MissionResults(separation=separation, inspected_by=inspected_by))
        status, reason = fleet_ending(fleet, parts)
        await self.storage.set_status(fleet_id, status, reason)
        log.info("fleet mission %s %s%s", fleet_id, status, f": {reason}" if reason else "")

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
        shares = {share.sysid: share for share in plan.fleet.shares}  # changed in place, stored at the end
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
            if part.status != MissionStatus.FLYING or not flying:
                continue
            part_plan, done = part.plan, set(part.progress.visited_buoys)
            left = [i for i in part_plan.order if i not in done]
            share = shares[sysid]
            here, home = plan.frame.project(np.array([[status.lat, status.lon], share.home], dtype=float))
            receivers[sysid] = (part, part_plan, left)
            positions[sysid] = (here, points[[share.buoys[i] for i in left]].reshape(-1, 2), home)
        handed: dict[int, list[int]] = {}
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
                new_plan = sorties_plan(
                    part_plan.depot,
                    [*part_plan.buoys_lat_lon, *(plan.buoys_lat_lon[b] for b in added)],
                    [*part_plan.buoy_ids, *(plan.buoy_ids[b] for b in added)],
                    [new_order],
                    part_plan.method,
                    part_plan.elapsed_s,
                )
                new_plan = replace(new_plan, marks=[*map(part_plan.mark, range(len(part_plan.buoy_ids))),
                                                    *map(plan.mark, added)])  # fmt: skip
                try:
                    self._replan(part, new_plan)
                except MissionConflictError:  # it landed or ended meanwhile: the buoys stay not inspected
                    continue
                shares[sysid].buoys = [*shares[sysid].buoys, *added]
                handed[sysid] = added
        lost_share.handed_over = {str(sysid): buoys for sysid, buoys in handed.items()}
        await self.storage.set_plan(fleet.id, plan)
        names = {sysid: ", ".join(plan.buoy_ids[b] for b in buoys) for sysid, buoys in handed.items()}
        given = "; ".join(f"{names[sysid]} to vehicle {sysid}" for sysid in names) or "nobody left to take its buoys"
        why = f" ({lost_part.reason})" if lost_part.reason else ""
        await self.storage.set_status(
            fleet.id, MissionStatus.FLYING, f"vehicle {lost_part.vehicle_sysid} lost{why}: {given}"
        )
        log.warning("fleet mission %s: vehicle %s lost; %s", fleet.id, lost_part.vehicle_sysid, given)
        return await self.storage.existing_mission(fleet.id)
