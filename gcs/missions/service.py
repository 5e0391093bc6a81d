"""The mission service: the one object the routes call. A thin facade over the pieces that do the work:

- planning: `plan` validates a request and plans it (gcs.missions.validation, gcs.domain.planning);
- the flight lifecycle: `launch`, `abort`, the operator's `command` (hold, return, land) and `resume`, the live
  view (gcs.missions.lifecycle, which records with gcs.missions.recorder);
- queries over what is stored: missions, telemetry, mission files, reports (gcs.storage, gcs.reports.report);
- ownership of the vehicle link (gcs.missions.ownership): with several instances on one database, only the owner starts
  the link and flies; a stand-by answers reads and refuses the rest (NotOwnerError) until it takes over;
- the AIS feed (gcs.ais): the AtoN reports heard from the --ais sources, owner and stand-by alike (it only listens);
- the buoy register (gcs.missions.register, `register`): charts imported, buoys' histories and defects, alarms.

The routes see no storage, link or lifecycle: only the methods here.
"""

from __future__ import annotations

import asyncio
import contextlib
import shutil
from collections.abc import Sequence
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

import numpy as np

from gcs.ais.feed import AisFeed
from gcs.domain.ais import AisSourceOut, AtonsOut
from gcs.domain.inspection import gather_fleet_inspections
from gcs.domain.listing import CursorError, MissionFilter, decode_cursor
from gcs.domain.planning import BuoyMark, FlightParams, Plan, fenced_legs, make_plan, mission_items, sorties_plan
from gcs.domain.schemas import FenceZoneIn, InspectionOut, MissionRequest, OperatorCommand, PlanRequest
from gcs.domain.status import TERMINAL, MissionStatus
from gcs.missions.energy_planning import battery_plan, energy_plan
from gcs.missions.fleet_missions import FleetCoordinator, fleet_vehicles, may_depart, shares_progress
from gcs.missions.fleet_planning import METHOD, plan_fleet_mission
from gcs.missions.fleet_shares import constrained_fleet_plan
from gcs.missions.fleet_vehicle import FleetVehicle
from gcs.missions.inspector import FrameAnalysis
from gcs.missions.lifecycle import ABORTED_BEFORE_TAKEOFF, MissionConflictError
from gcs.missions.ownership import Ownership, ownership_for
from gcs.missions.read_cache import VersionedCache
from gcs.missions.register import Register
from gcs.missions.validation import (
    RequestInvalidError,
    fence_from_request,
    validate_fence_points,
    validate_fenced_route,
    validate_rally_points,
    validate_request,
    validate_route_length,
)
from gcs.reports import report, views
from gcs.settings import Settings
from gcs.storage import MissionRecord
from gcs.storage.off_loop import AsyncStorage
from gcs.vehicle.link import LinkManager
from planner.energy import EnergyModel
from uavcore.ais_stream import StreamLimits
from uavcore.battery_pack import PackSpec
from uavcore.buoy_world import DEFAULT_SWING_RADIUS_M
from uavcore.geofence import Geofence
from uavcore.mission import MissionItem


def _named_buoys(request: PlanRequest) -> tuple[list[str], list[tuple[float, float]]]:
    """The request's buoy ids (B<index> for an unnamed one) and (lat, lon) points, in input order."""
    ids = [b.id or f"B{i + 1}" for i, b in enumerate(request.buoys)]
    return ids, [(b.lat, b.lon) for b in request.buoys]


def _marks(request: PlanRequest, region: str) -> list[BuoyMark]:
    """What the request charts of each buoy (kind, light, swing radius, ...), in input order; `region`: the IALA
    region of a buoy that names none."""
    return [
        BuoyMark(
            b.kind,
            b.light,
            DEFAULT_SWING_RADIUS_M if b.swing_radius_m is None else b.swing_radius_m,
            b.register_id,
            None if b.charted is None else (b.charted.lat, b.charted.lon),
            b.region or region,
        )
        for b in request.buoys
    ]


def _flight(request: PlanRequest, **changes: Any) -> FlightParams:
    """The request's flight parameters (`changes` replacing some)."""
    flight = FlightParams(request.altitude_m, request.speed_m_s, request.dwell_s, request.acceptance_radius_m,
                          inspect=request.inspect, inspection_range_m=request.inspection_range_m)  # fmt: skip
    return replace(flight, **changes)


def _uploaded_lists(request: PlanRequest) -> dict[str, Any]:
    """What a plan carries to upload to its vehicle besides the mission: the request's fence and rally points
    (Plan.fence, Plan.rally_points; None: the vehicle keeps its own)."""
    rally = None if request.rally_points is None else [[p.lat, p.lon, p.alt_m] for p in request.rally_points]
    return {"fence": request.geofence, "rally_points": rally}


# a fleet mission's part as stored: its flight (at its layer), its plan (its share), its vehicle's system id
FleetPart = tuple[FlightParams, Plan, int]


@dataclass(frozen=True)
class MissionFile:
    """What a mission file (QGC .plan, WPL 110) is written from."""

    items: list[MissionItem]
    home: tuple[float, float, float]
    flight: FlightParams
    fence: list[FenceZoneIn]
    rally_points: list[list[float]]


class MissionNotFoundError(KeyError):
    pass


class FrameNotFoundError(KeyError):
    pass


class FlightLogNotFoundError(KeyError):
    """The mission has no flight log: it never flew, its log is still being fetched, or the download failed (the
    message then gives the note recorded with the mission)."""


class VehicleNotFoundError(KeyError):
    pass


class MissionService:
    """Plans, stores and flies missions over one LinkManager; answers what is stored."""

    def __init__(
        self,
        settings: Settings,
        storage: AsyncStorage,
        link: LinkManager,
        ownership: Ownership | None = None,
        fleet: Sequence[LinkManager] = (),
    ) -> None:
        """`link`: the service's vehicle (a fleet's first: GET /vehicle, missions that name no vehicle); `fleet`:
        the other vehicles' links. A fleet's vehicles are known by their system ids (Settings.vehicles)."""
        self.settings = settings
        self._storage = storage
        self.energy_model = EnergyModel.load()  # planner/energy_params.json: the calibrated route energy model
        first_key = link.sysid if fleet else None  # a lone vehicle's missions are stored without one, as ever
        self._analysis = FrameAnalysis(settings.inspection_workers)  # the camera frames' analysis, every vehicle's
        self._vehicles = [FleetVehicle(first_key, link, settings, storage, self.energy_model, self._analysis)]
        self._vehicles += [
            FleetVehicle(other.sysid, other, settings, storage, self.energy_model, self._analysis) for other in fleet
        ]
        self._link, self._flights = link, self._vehicles[0].flights  # the first vehicle's, for its views
        self._fleets = FleetCoordinator(
            storage,
            lambda sysid: self._vehicle(sysid).link,
            lambda part, plan: self._vehicle_of(part).flights.replan(part.id, plan),
            lambda part: self._vehicle_of(part).flights.launch(part),
            instance=settings.instance_name,
        )
        self._ownership = ownership or ownership_for(settings)
        # the read routes' encoded documents by version (gcs.missions.read_cache); GET /missions' pages apart, so a
        # client walking through every page of a long history never evicts the mission documents being polled
        self.documents: VersionedCache[bytes] = VersionedCache()
        self.mission_pages: VersionedCache[views.MissionsPage] = VersionedCache(max_entries=64, max_bytes=16 * 2**20)
        limits = StreamLimits(rate_lines_s=settings.ais_max_lines_s, burst_lines=2 * settings.ais_max_lines_s)
        self.ais = AisFeed(settings.ais_sources, settings.ais_stale_s, limits)
        self.register = Register(storage, self.ais)  # the buoy register: the /buoys and /alarms routes' methods

    async def start(self) -> None:
        """Own the vehicle link now, or stand by until the owner is gone (then take it over in the background).
        The AIS feed listens either way."""
        await self.ais.start()
        await self._ownership.start(self._take_link)

    async def _take_link(self) -> None:
        """As the links' new owner: start them and re-attach each vehicle's mission left flying, as after a restart."""
        # read before this run can start any mission
        unfinished = [await self._storage.unfinished_missions(vehicle.sysid) for vehicle in self._vehicles]
        fleets = [fleet_id for fleet_id in await self._storage.unfinished_fleets() if await self._flies(fleet_id)]
        for vehicle in self._vehicles:
            await vehicle.link.start()
        for vehicle, missions in zip(self._vehicles, unfinished, strict=True):
            await vehicle.flights.reattach(missions)
        for fleet_id in fleets:
            self._fleets.follow(fleet_id)

    async def _flies(self, fleet_id: int) -> bool:
        """Whether every part of the fleet mission flies on a vehicle of this instance (whose leases it holds, all or
        none: gcs.missions.ownership); an instance owning other vehicles on the same database leaves it alone."""
        ours = {vehicle.sysid for vehicle in self._vehicles}
        return all(part.vehicle_sysid in ours for part in await self._storage.fleet_parts(fleet_id))

    async def stop(self) -> None:
        """Stop. On a shared database a mission in flight is handed over, not failed: a stand-by takes the link
        as soon as this instance releases the lease (and this instance, restarted, would re-attach it)."""
        await self._ownership.stop()
        await self._fleets.stop()
        for vehicle in self._vehicles:
            await vehicle.flights.stop(hand_over=self._ownership.shared)
        for vehicle in self._vehicles:
            await vehicle.link.stop()
        await self._ownership.release()  # only now may a stand-by talk to the vehicle
        self._analysis.shutdown()
        await self.ais.stop()

    def _vehicle(self, sysid: int | None) -> FleetVehicle:
        """The vehicle a request names (None: the first); raises RequestInvalidError at body.vehicle."""
        if sysid is None:
            return self._vehicles[0]
        with contextlib.suppress(VehicleNotFoundError):
            return self._known_vehicle(sysid)
        known = ", ".join(str(v.system_id) for v in self._vehicles if v.system_id is not None) or "none heard yet"
        raise RequestInvalidError([(("body", "vehicle"), f"no vehicle with system id {sysid} (the fleet's: {known})")])

    def _known_vehicle(self, sysid: int) -> FleetVehicle:
        """The fleet's vehicle with this system id; raises VehicleNotFoundError."""
        found = next((vehicle for vehicle in self._vehicles if vehicle.system_id == sysid), None)
        if found is None:
            raise VehicleNotFoundError(sysid)
        return found

    def _vehicle_of(self, record: MissionRecord) -> FleetVehicle:
        """The vehicle a stored mission flies on (a mission stored without one: the first)."""
        return next((v for v in self._vehicles if v.sysid == record.vehicle_sysid), self._vehicles[0])

    # ----- planning
    def default_depot(self) -> tuple[float, float]:
        return self._vehicles[0].depot()

    async def plan(self, request: PlanRequest) -> tuple[Plan, FlightParams]:
        """Validate and plan for the vehicle the request names (default: the first) against the request's
        geofence, else the one the vehicle holds (read now), and with battery options against the vehicle's pack
        (read now); a fleet request (`vehicles`) shares the buoys among its vehicles (`Plan.fleet`). Raises
        RequestInvalidError or InputError."""
        if request.vehicles is not None:
            plan, flight, _ = await self._plan_fleet(request, self._fleet_sysids(request))
            return plan, flight
        vehicle = self._vehicle(request.vehicle)
        request = await self.register.resolve(request)
        fence = fence_from_request(request.geofence) if request.geofence else await vehicle.fence()
        pack = await vehicle.pack() if request.battery is not None else None
        return await asyncio.to_thread(self._plan, request, vehicle.depot(), fence, pack)

    def _plan(
        self, request: PlanRequest, home: tuple[float, float], fence: Geofence | None, pack: PackSpec | None
    ) -> tuple[Plan, FlightParams]:
        """The CPU-bound part of `plan` (runs in a worker thread); `home`: the depot when the request names none."""
        depot = (request.depot.lat, request.depot.lon) if request.depot else home
        validate_request(request, depot, self.settings.limits)
        ids, buoys = _named_buoys(request)
        fenced = {}
        if fence is not None and not fence.empty:
            validate_fence_points(depot, buoys, fence)
            fenced = fenced_legs(depot, np.asarray(buoys), fence)
        validate_rally_points(request.rally_points or [], fence, self.settings.limits)
        flight = _flight(request)
        options = request.planner
        if request.battery is None:
            plan = make_plan(depot, buoys, ids, options.method, options.seed, options.time_limit_s, fenced)
            validate_route_length(plan.length_m, self.settings.limits)
        else:
            battery = battery_plan(request, pack, self.energy_model)
            plan = energy_plan(depot, buoys, ids, flight, battery, options.seed, options.time_limit_s, fenced,
                               options.method, self.energy_model)  # fmt: skip
        validate_fenced_route(plan, fenced)
        return replace(plan, marks=_marks(request, self.settings.iala_region), **_uploaded_lists(request)), flight

    # ----- the lifecycle
    def active_mission(self) -> int | None:
        return self._flights.active_mission()

    async def create(self, request: MissionRequest) -> int:
        """Plan and store a mission on the vehicle it names (default: the first); with start=true, also fly it
        in the background."""
        self._ownership.ensure_owner()
        if request.vehicles is not None:
            return await self._create_fleet_mission(request)
        vehicle = self._vehicle(request.vehicle)
        if request.start:
            vehicle.flights.ensure_vehicle_free()
        plan, flight = await self.plan(request)
        flight = replace(flight, override=request.override)
        mission_id = await self._storage.create_mission(flight, plan, vehicle_sysid=vehicle.sysid)
        if request.start:
            try:
                await self.launch(mission_id)
            except MissionConflictError as error:  # another mission started while this one was planned
                raise MissionConflictError(
                    f"{error}; mission {mission_id} is stored as planned: POST /missions/{mission_id}/start later"
                ) from None
        return mission_id

    async def _create_fleet_mission(self, request: MissionRequest) -> int:
        """Share the buoys among the vehicles named (gcs.missions.fleet_planning), store the fleet mission and a part
        mission per vehicle given buoys, in one transaction; with start=true, fly every part."""
        sysids = self._fleet_sysids(request)
        if request.start:
            for sysid in sysids:
                self._vehicle(sysid).flights.ensure_vehicle_free()
        overview, flight, parts = await self._plan_fleet(request, sysids, override=request.override)
        fleet_id, _ = await self._storage.create_fleet_mission(flight, overview, parts)
        fleet = await self.get(fleet_id)
        # its shares' part missions, as the answer names them (the coordinator keeps this progress from here)
        await self._storage.set_progress(fleet_id, shares_progress(fleet, await self._storage.fleet_parts(fleet_id)))
        if request.start:
            await self._launch_fleet(fleet)
        return fleet_id

    def _fleet_sysids(self, request: PlanRequest) -> list[int]:
        known = [v.system_id for v in self._vehicles if v.system_id is not None]
        return fleet_vehicles(request, known, self.settings.limits)

    async def _plan_fleet(
        self, request: PlanRequest, sysids: list[int], override: bool = False
    ) -> tuple[Plan, FlightParams, list[FleetPart]]:
        """A fleet request's plan on the vehicles `sysids` (`_fleet_sysids`): the overview (its `fleet` section has
        the shares), the flight (`override`: a mission's, recorded), and each share's part (its flight at its
        layer, its plan, its vehicle's system id)."""
        homes = {sysid: self._vehicle(sysid).depot() for sysid in sysids}
        first_home = homes[sysids[0]]
        request = await self.register.resolve(request)
        validate_request(request, first_home, self.settings.limits)
        ids, buoys = _named_buoys(request)
        options = request.planner
        # the request's fence and battery, as a single mission's (gcs.missions.fleet_shares): every vehicle's home
        # and every buoy inside the fence, each vehicle's own pack
        fence = fence_from_request(request.geofence) if request.geofence else None
        if fence is not None and not fence.empty:
            validate_fence_points(first_home, buoys, fence, homes=homes)
        validate_rally_points(request.rally_points or [], fence, self.settings.limits)
        batteries = None
        if request.battery is not None:
            batteries = {sysid: battery_plan(request, await self._vehicle(sysid).pack(), self.energy_model)
                         for sysid in sysids}  # fmt: skip
        planned = await asyncio.to_thread(
            plan_fleet_mission, homes, buoys, ids, request.altitude_m, request.layer_gap_m, request.speed_m_s,
            request.dwell_s, options.seed, options.time_limit_s, request.separation_m, self.energy_model,
        )  # fmt: skip
        flight = _flight(request, override=override)
        # each share inside its vehicle's fence: the request's, else the one it holds (read now), as a single mission
        fences = {sysid: fence if request.geofence else await self._vehicle(sysid).fence() for sysid in sysids}
        planned = await asyncio.to_thread(
            constrained_fleet_plan, planned, homes, buoys, ids, flight, fences, batteries, options, self.energy_model
        )
        marks = _marks(request, self.settings.iala_region)
        lists = _uploaded_lists(request)
        overview = sorties_plan(first_home, buoys, ids, [[b for s in planned.shares for b in s.buoys]], METHOD,
                                planned.elapsed_s)  # fmt: skip
        overview = replace(
            overview, length_m=sum(s.plan.length_m for s in planned.shares), fleet=planned.plan_section(), marks=marks,
            **lists,
        )  # fmt: skip
        parts = [
            (replace(flight, altitude_m=share.altitude_m, final_hold_s=share.final_hold_s),
             replace(share.plan, marks=[marks[b] for b in share.buoys], **lists), share.sysid)
            for share in planned.shares
        ]  # fmt: skip
        return overview, flight, parts

    async def _launch_fleet(self, fleet: MissionRecord) -> None:
        """Fly every part of a planned fleet mission (each vehicle must be free), and follow them."""
        if fleet.status != MissionStatus.PLANNED:
            raise MissionConflictError(f"mission {fleet.id} is {fleet.status}; only a planned mission can start")
        parts = await self._storage.fleet_parts(fleet.id)
        # from here to the launches nothing is awaited: no other request can take a vehicle in between
        for part in parts:
            self._vehicle_of(part).flights.ensure_vehicle_free()
        for part in parts:  # the first of each depot; the others when their turn comes (FleetCoordinator)
            if may_depart(fleet, part, parts, lambda sysid: self._vehicle(sysid).link):
                self._vehicle_of(part).flights.launch(part)
        self._fleets.follow(fleet.id)

    async def launch(self, mission_id: int) -> None:
        self._ownership.ensure_owner()
        record = await self.get(mission_id)
        if record.is_fleet:
            await self._launch_fleet(record)
            return
        flights = self._vehicle_of(record).flights
        flights.ensure_vehicle_free()
        flights.launch(record)

    async def abort(self, mission_id: int) -> None:
        """Abort a mission; a fleet mission's every part not yet ended (the fleet mission then ends aborted)."""
        self._ownership.ensure_owner()
        record = await self.get(mission_id)
        if not record.is_fleet:
            await self._vehicle_of(record).flights.abort(record)
            return
        if record.status in TERMINAL:
            raise MissionConflictError(f"mission {mission_id} is {record.status}; nothing to abort")
        for part in await self._storage.fleet_parts(mission_id):
            if part.status not in TERMINAL:
                await self._vehicle_of(part).flights.abort(part)
        if not self._fleets.active(mission_id):  # never launched: its parts ended as they were aborted
            await self._storage.set_status(mission_id, MissionStatus.ABORTED, ABORTED_BEFORE_TAKEOFF)

    async def command(self, mission_id: int, command: OperatorCommand) -> None:
        """The operator's hold, return or land on a flying mission (gcs.missions.lifecycle.FlightLifecycle.command).
        Raises MissionConflictError (not flying, a fleet mission, the vehicle refused) or VehicleCommandError."""
        record = await self._commandable(mission_id, command)
        await self._vehicle_of(record).flights.command(record, command)

    async def resume(self, mission_id: int) -> None:
        """A held or returning mission flies on from its first buoy not visited (FlightLifecycle.resume). Raises as
        `command`."""
        record = await self._commandable(mission_id, "resume")
        await self._vehicle_of(record).flights.resume(record)

    async def _commandable(self, mission_id: int, command: str) -> MissionRecord:
        """A mission one vehicle flies. A fleet mission's parts fly on their own vehicles, each at its own point of
        its route, so a command is for one of them, by its part mission id (the 409 names them)."""
        self._ownership.ensure_owner()
        record = await self.get(mission_id)
        if record.is_fleet:
            parts = ", ".join(str(part.id) for part in await self._storage.fleet_parts(mission_id)) or "none"
            raise MissionConflictError(
                f"mission {mission_id} is a fleet mission: a fleet's parts are commanded one by one, by their part "
                f"mission id (POST /missions/{{part}}/{command}; its parts: {parts})"
            )
        return record

    async def battery_swapped(self, sysid: int | None, charge_pct: float) -> dict[str, Any]:
        """The operator swapped the pack of a vehicle (None: the first): the vehicle is told (gcs.missions.lifecycle
        .FlightLifecycle.battery_swapped) and a mission waiting for the swap goes on. Raises VehicleNotFoundError,
        MissionConflictError (a mission flies on it)."""
        self._ownership.ensure_owner()
        vehicle = self._vehicles[0] if sysid is None else self._known_vehicle(sysid)
        waiting = vehicle.flights.waiting_for_battery()
        answer = await vehicle.flights.battery_swapped(charge_pct)
        return {
            "vehicle": answer,
            "battery_remaining_pct": vehicle.link.status.battery_remaining_pct,
            "waiting_mission": waiting,
        }

    # ----- views
    def live(self) -> dict[str, Any]:
        """What /ws pushes: the (first) vehicle, every vehicle of the fleet as GET /vehicles lists them (one live
        path for a fleet's positions: the page polls nothing for them), and the first vehicle's active mission's
        status, progress and latest sample."""
        vehicle = self._link.status.as_dict() | self._ownership.as_dict()
        return {
            "type": "state",
            "vehicle": vehicle,
            "vehicles": self.vehicles(),
            "mission": self._flights.live_mission(),
        }

    def vehicle(self) -> dict[str, Any]:
        """The link's view of the vehicle, with the depot a plan would use and the mission flying, if any, and
        who owns the link (`role` owner or standby, this `instance`, the `owner`'s name)."""
        data = self._link.status.as_dict() | self._ownership.as_dict()
        data["depot"] = dict(zip(("lat", "lon"), self.default_depot(), strict=True))
        data["active_mission"] = self.active_mission()
        return data

    def vehicles(self) -> list[dict[str, Any]]:
        """Every vehicle of the fleet (gcs.missions.fleet_vehicle.FleetVehicle.describe), with who owns the links."""
        return [self._described(vehicle) for vehicle in self._vehicles]

    def fleet_vehicle(self, sysid: int) -> dict[str, Any]:
        """One vehicle of the fleet by system id; raises VehicleNotFoundError."""
        return self._described(self._known_vehicle(sysid))

    def _described(self, vehicle: FleetVehicle) -> dict[str, Any]:
        return vehicle.describe() | {"role": self._ownership.as_dict()["role"]}

    # ----- the AIS feed
    def ais_atons(self) -> AtonsOut:
        """Each AtoN's latest report, its age and flags, and the MMSIs several AtoNs report."""
        return self.ais.atons()

    def ais_sources(self) -> list[AisSourceOut]:
        """Each AIS source's state and counts."""
        return self.ais.sources()

    # ----- queries over what is stored (each storage call awaited in a thread: gcs.storage.off_loop)
    async def get(self, mission_id: int) -> MissionRecord:
        record = await self._storage.get_mission(mission_id)
        if record is None:
            raise MissionNotFoundError(mission_id)
        return record

    async def _version(self, mission_id: int) -> int:
        version = await self._storage.mission_version(mission_id)
        if version is None:
            raise MissionNotFoundError(mission_id)
        return version

    # The documents the read routes serve, encoded: built once per version of the mission (or, for the list, of
    # the newest change to any mission) and served as bytes while the storage's version is unchanged.
    async def mission_json(self, mission_id: int) -> bytes:
        """GET /missions/{id}: the MissionOut document."""

        async def build() -> bytes:
            return views.mission_json(await self.get(mission_id))

        return await self.documents.get(("mission", mission_id), await self._version(mission_id), build)

    async def missions_page(
        self, limit: int, where: MissionFilter | None = None, cursor: str | None = None
    ) -> views.MissionsPage:
        """GET /missions: the latest `limit` MissionSummary documents that pass `where`, newest first, after the
        page whose next-page `cursor` this is (None: the first page), with the next page's cursor. Raises
        RequestInvalidError at query.cursor for a cursor this service did not give, at query.until for an
        `until` not after `since`.

        Every page, filtered or not, is cached under the newest change to any mission (`latest_version`): any
        write to a mission can change which missions a query lists, and no other write can. The page polled
        (the plain GET /missions, the map page's history) is so served as bytes, one indexed query a request."""
        where = where or MissionFilter()
        try:
            after = None if cursor is None else decode_cursor(cursor)
        except CursorError as error:
            raise RequestInvalidError([(("query", "cursor"), str(error))]) from None
        if where.empty_window:
            window = f"as instants, {where.until} is not after {where.since}"
            raise RequestInvalidError([(("query", "until"), f"until must be after since ({window})")])

        async def build() -> views.MissionsPage:
            # one mission more than the page: whether another page follows, without counting them
            return views.missions_page(await self._storage.list_missions(limit + 1, where, after), limit)

        key = ("missions", limit, where, after)
        return await self.mission_pages.get(key, await self._storage.latest_version(), build)

    async def track_json(self, mission_id: int, max_points: int) -> bytes:
        """GET /missions/{id}/track: the flown track cut to `max_points` for display (TrackOut). Samples are
        stored without moving the mission's version, so the track's version also counts them. Built in a worker
        thread: it reads every sample."""
        version = (await self._version(mission_id), await self._storage.telemetry_count(mission_id))
        storage = self._storage.blocking  # read from the worker thread

        async def build() -> bytes:
            record = await self.get(mission_id)
            return await asyncio.to_thread(
                lambda: views.track_json(
                    record,
                    storage.track_columns(mission_id),
                    lambda times: storage.telemetry_at(mission_id, times),
                    max_points,
                )
            )

        return await self.documents.get(("track", mission_id, max_points), version, build)

    async def telemetry(self, mission_id: int, limit: int | None = None) -> list[dict[str, Any]]:
        """A mission's recorded samples (TelemetrySample documents), oldest first."""
        await self._version(mission_id)  # 404 for no such mission: the one-row index lookup, not the whole record
        return await self._storage.telemetry(mission_id, limit)

    async def mission_file(self, mission_id: int) -> MissionFile:
        """What a mission file needs: the mission's items, its home (the depot, on the ground), its flight, and the
        fence and rally points uploaded with it (empty where the vehicle kept its own)."""
        record = await self.get(mission_id)
        home = (record.plan.depot[0], record.plan.depot[1], 0.0)
        return MissionFile(
            mission_items(record.plan, record.flight), home, record.flight,
            record.plan.fence or [], record.plan.rally_points or [],
        )  # fmt: skip

    # ----- inspections
    async def inspections(self, mission_id: int) -> list[InspectionOut]:
        """Each buoy's inspection record so far, by input index; a fleet mission's gathered from its parts
        (gather_fleet_inspections; a buoy re-shared in flight: the record of the vehicle that inspected it, else of
        the one that could not), each naming its part's frames."""
        record = await self.get(mission_id)
        if not record.is_fleet:
            return [views.inspection_out(mission_id, r) for r in await self._storage.inspections(mission_id)]
        parts = [
            (part.id, part.plan, await self._storage.inspections(part.id))
            for part in await self._storage.fleet_parts(mission_id)
        ]
        return [views.inspection_out(part_id, r) for part_id, r in gather_fleet_inspections(record.plan, parts)]

    async def frame(self, mission_id: int, frame_id: int) -> bytes:
        """A stored camera frame's bytes; raises MissionNotFoundError (no such mission) or FrameNotFoundError."""
        await self.get(mission_id)
        data = await self._storage.frame_data(mission_id, frame_id)
        if data is None:
            raise FrameNotFoundError(f"mission {mission_id} has no frame {frame_id}")
        return data

    async def flight_log(self, mission_id: int) -> bytes:
        """The mission's flight log (ULog); raises MissionNotFoundError or FlightLogNotFoundError (with the note
        recorded when its download failed)."""
        await self.get(mission_id)
        data = await self._storage.flight_log_data(mission_id)
        if data is not None:
            return data
        stored = await self._storage.flight_log(mission_id)
        if stored is None:
            raise FlightLogNotFoundError(f"mission {mission_id} has no flight log (not flown, or still being fetched)")
        raise FlightLogNotFoundError(f"mission {mission_id} has no flight log: {stored.note}")

    async def delete(self, mission_id: int) -> None:
        """Remove a mission with its telemetry, frames, inspections, flight log and report (a fleet mission: its parts
        too).
        Raises MissionConflictError while it (or a part) is being flown: abort it first."""
        self._ownership.ensure_owner()
        record = await self.get(mission_id)
        parts = await self._storage.fleet_parts(mission_id) if record.is_fleet else []
        for mission in (record, *parts):
            if mission.status not in TERMINAL and mission.status != MissionStatus.PLANNED:
                raise MissionConflictError(f"mission {mission.id} is {mission.status}: abort it before deleting it")
            if self._vehicle_of(mission).flights.active_mission() == mission.id:
                raise MissionConflictError(f"mission {mission.id} is starting: abort it before deleting it")
        await self._storage.delete_mission(mission_id)
        for mission in (record, *parts):
            await asyncio.to_thread(shutil.rmtree, self.settings.reports_dir / f"mission-{mission.id}", True)

    async def report_index(self, mission_id: int) -> Path:
        """The mission's report (drawn, or the cached drawing when the mission has not changed): its index.html.
        Drawn with matplotlib in a worker thread."""
        await self.get(mission_id)
        return await asyncio.to_thread(
            report.cached_report, self._storage.blocking, mission_id, self.settings.reports_dir
        )
