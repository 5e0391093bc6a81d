"""The mission service: the one object the routes call. A thin facade over the pieces that do the work:

- planning: `plan` validates a request and plans it (gcs.validation, gcs.planning);
- the flight lifecycle: `launch`, `abort`, the live view (gcs.lifecycle, which records with gcs.recorder);
- queries over what is stored: missions, telemetry, mission files, reports (gcs.storage, gcs.report);
- ownership of the vehicle link (gcs.ownership): with several instances on one database, only the owner starts
  the link and flies; a stand-by answers reads and refuses the rest (NotOwnerError) until it takes over.

The routes see no storage, link or lifecycle: only the methods here.
"""

from __future__ import annotations

import asyncio
from collections.abc import Sequence
from dataclasses import asdict
from pathlib import Path
from typing import Any

import numpy as np

from gcs import report, views
from gcs.energy_planning import battery_plan, energy_plan
from gcs.lifecycle import FlightLifecycle, MissionConflictError
from gcs.link import LinkError, LinkManager
from gcs.mission_protocol import MissionTransferError
from gcs.ownership import Ownership, ownership_for
from gcs.planning import FlightParams, Plan, fenced_legs, make_plan, mission_items
from gcs.read_cache import VersionedCache
from gcs.schemas import MissionRequest, PlanRequest
from gcs.settings import Settings
from gcs.storage import MissionRecord, Storage
from gcs.validation import (
    fence_from_request,
    validate_fence_points,
    validate_fenced_route,
    validate_request,
    validate_route_length,
)
from planner.energy import EnergyModel
from uavcore.battery_pack import PACK_PARAMETERS, PackSpec
from uavcore.geofence import FenceError, Geofence
from uavcore.mission import MissionItem

FENCE_READ_TIMEOUT_S = 1.5  # wall clock for the vehicle's geofence before a plan


class MissionNotFoundError(KeyError):
    pass


class VehicleNotFoundError(KeyError):
    pass


class MissionService:
    """Plans, stores and flies missions over one LinkManager; answers what is stored."""

    def __init__(
        self,
        settings: Settings,
        storage: Storage,
        link: LinkManager,
        ownership: Ownership | None = None,
        fleet: Sequence[LinkManager] = (),
    ) -> None:
        """`link`: the vehicle missions fly on; `fleet`: the other vehicles' links (shown, not yet flown)."""
        self.settings = settings
        self._storage, self._link = storage, link
        self._fleet = list(fleet)
        self._ownership = ownership or ownership_for(settings)
        self._flights = FlightLifecycle(settings, storage, link)
        self._fence_unanswered: int | None = None  # the vehicle incarnation that did not answer a fence request
        self.energy_model = EnergyModel.load()  # planner/energy_params.json: the calibrated route energy model
        self.documents = VersionedCache()  # the read routes' encoded documents by version (gcs.read_cache)

    async def start(self) -> None:
        """Own the vehicle link now, or stand by until the owner is gone (then take it over in the background)."""
        await self._ownership.start(self._take_link)

    async def _take_link(self) -> None:
        """As the link's new owner: start it and re-attach a mission left flying, as after a restart."""
        unfinished = self._storage.unfinished_missions()  # read before this run can start any mission
        await self._link.start()
        for link in self._fleet:
            await link.start()
        self._flights.reattach(unfinished)

    async def stop(self) -> None:
        """Stop. On a shared database a mission in flight is handed over, not failed: a stand-by takes the link
        as soon as this instance releases the lease (and this instance, restarted, would re-attach it)."""
        await self._ownership.stop()
        await self._flights.stop(hand_over=self._ownership.shared)
        for link in (self._link, *self._fleet):
            await link.stop()
        await self._ownership.release()  # only now may a stand-by talk to the vehicle

    # ----- planning
    def default_depot(self) -> tuple[float, float]:
        home = self._link.status.home or self.settings.home
        return home[0], home[1]

    async def plan(self, request: PlanRequest) -> tuple[Plan, FlightParams]:
        """Validate and plan against the request's geofence, else the one the vehicle holds (read now), and with
        battery options against the vehicle's pack (read now). Raises RequestInvalidError or InputError."""
        fence = fence_from_request(request.geofence) if request.geofence else await self._vehicle_fence()
        pack = await self._vehicle_pack() if request.battery is not None else None
        return await asyncio.to_thread(self._plan, request, fence, pack)

    async def _vehicle_pack(self) -> PackSpec | None:
        """The vehicle's pack and warning thresholds from its parameters; None when it has no such parameters
        (an ArduPilot names them otherwise) or does not answer."""
        if not self._link.status.connected:
            return None
        try:
            return PackSpec.from_parameters(await self._link.read_parameters(list(PACK_PARAMETERS)))
        except (LinkError, TimeoutError, ValueError):
            return None

    async def _vehicle_fence(self) -> Geofence | None:
        """The vehicle's current geofence; what was read at connection if it does not answer in time (an
        autopilot without fences may never answer: it is not asked again until it reconnects or reboots)."""
        link = self._link
        if not link.status.connected or self._fence_unanswered == link.status.incarnation:
            return link.fence
        try:
            return await asyncio.wait_for(link.download_fence(), FENCE_READ_TIMEOUT_S)
        except (TimeoutError, LinkError, MissionTransferError, FenceError):
            self._fence_unanswered = link.status.incarnation
            return link.fence

    def _plan(self, request: PlanRequest, fence: Geofence | None, pack: PackSpec | None) -> tuple[Plan, FlightParams]:
        """The CPU-bound part of `plan` (runs in a worker thread)."""
        depot = (request.depot.lat, request.depot.lon) if request.depot else self.default_depot()
        validate_request(request, depot, self.settings.limits)
        ids = [b.id or f"B{i + 1}" for i, b in enumerate(request.buoys)]
        buoys = [(b.lat, b.lon) for b in request.buoys]
        fenced = {}
        if fence is not None and not fence.empty:
            validate_fence_points(depot, buoys, fence)
            fenced = fenced_legs(depot, np.asarray(buoys), fence)
        flight = FlightParams(request.altitude_m, request.speed_m_s, request.dwell_s, request.acceptance_radius_m)
        options = request.planner
        if request.battery is None:
            plan = make_plan(depot, buoys, ids, options.method, options.seed, options.time_limit_s, fenced)
            validate_route_length(plan.length_m, self.settings.limits)
        else:
            battery = battery_plan(request, pack, self.energy_model)
            plan = energy_plan(depot, buoys, ids, flight, battery, options.seed, options.time_limit_s, fenced,
                               options.method, self.energy_model)  # fmt: skip
        validate_fenced_route(plan, fenced)
        return plan, flight

    # ----- the lifecycle
    def active_mission(self) -> int | None:
        return self._flights.active_mission()

    async def create(self, request: MissionRequest) -> int:
        """Plan and store a mission; with start=true, also fly it in the background."""
        self._ownership.ensure_owner()
        if request.start:
            self._flights.ensure_vehicle_free()
        plan, flight = await self.plan(request)
        mission_id = self._storage.create_mission(asdict(flight), plan.to_dict())
        if request.start:
            try:
                self.launch(mission_id)
            except MissionConflictError as error:  # another mission started while this one was planned
                raise MissionConflictError(
                    f"{error}; mission {mission_id} is stored as planned: POST /missions/{mission_id}/start later"
                ) from None
        return mission_id

    def launch(self, mission_id: int) -> None:
        self._ownership.ensure_owner()
        self._flights.ensure_vehicle_free()
        self._flights.launch(self.get(mission_id))

    async def abort(self, mission_id: int) -> None:
        self._ownership.ensure_owner()
        await self._flights.abort(self.get(mission_id))

    # ----- views
    def live(self) -> dict[str, Any]:
        """What /ws pushes: the vehicle, and the active mission's status, progress and latest sample."""
        vehicle = self._link.status.as_dict() | self._ownership.as_dict()
        return {"type": "state", "vehicle": vehicle, "mission": self._flights.live_mission()}

    def vehicle(self) -> dict[str, Any]:
        """The link's view of the vehicle, with the depot a plan would use and the mission flying, if any, and
        who owns the link (`role` owner or standby, this `instance`, the `owner`'s name)."""
        data = self._link.status.as_dict() | self._ownership.as_dict()
        data["depot"] = dict(zip(("lat", "lon"), self.default_depot(), strict=True))
        data["active_mission"] = self.active_mission()
        return data

    def vehicles(self) -> list[dict[str, Any]]:
        """Every vehicle of the fleet as its link sees it: `sysid` (configured, else as heard), its `link`, and
        whether missions fly on it (`flies_missions`: the first)."""
        return [self._fleet_vehicle(link) for link in (self._link, *self._fleet)]

    def fleet_vehicle(self, sysid: int) -> dict[str, Any]:
        """One vehicle of the fleet by system id; raises VehicleNotFoundError."""
        for link in (self._link, *self._fleet):
            if (link.sysid or link.status.sysid) == sysid:
                return self._fleet_vehicle(link)
        raise VehicleNotFoundError(sysid)

    def _fleet_vehicle(self, link: LinkManager) -> dict[str, Any]:
        data = link.status.as_dict() | {"sysid": link.sysid or link.status.sysid, "link": str(link.connection)}
        return data | {"flies_missions": link is self._link, "role": self._ownership.as_dict()["role"]}

    # ----- queries over what is stored
    def get(self, mission_id: int) -> MissionRecord:
        record = self._storage.get_mission(mission_id)
        if record is None:
            raise MissionNotFoundError(mission_id)
        return record

    def list_missions(self, limit: int) -> list[MissionRecord]:
        """The latest missions, newest first."""
        return self._storage.list_missions(limit)

    def _version(self, mission_id: int) -> int:
        version = self._storage.mission_version(mission_id)
        if version is None:
            raise MissionNotFoundError(mission_id)
        return version

    # The documents the read routes serve, encoded: built once per version of the mission (or, for the list, of
    # the newest change to any mission) and served as bytes while the storage's version is unchanged.
    def mission_json(self, mission_id: int) -> bytes:
        """GET /missions/{id}: the MissionOut document."""
        version = self._version(mission_id)
        return self.documents.get(("mission", mission_id), version, lambda: views.mission_json(self.get(mission_id)))

    def missions_json(self, limit: int) -> bytes:
        """GET /missions: the latest `limit` MissionSummary documents, newest first."""
        version = self._storage.latest_version()
        return self.documents.get(("missions", limit), version, lambda: views.missions_json(self.list_missions(limit)))

    def track_json(self, mission_id: int, max_points: int) -> bytes:
        """GET /missions/{id}/track: the flown track cut to `max_points` for display (TrackOut). Samples are
        stored without moving the mission's version, so the track's version also counts them. Reads every
        sample when it builds: call it from a worker thread."""
        version = (self._version(mission_id), self._storage.telemetry_count(mission_id))
        return self.documents.get(
            ("track", mission_id, max_points),
            version,
            lambda: views.track_json(
                self.get(mission_id),
                self._storage.track_columns(mission_id),
                lambda times: self._storage.telemetry_at(mission_id, times),
                max_points,
            ),
        )

    def telemetry(self, mission_id: int, limit: int | None = None) -> list[dict[str, Any]]:
        """A mission's recorded samples (TelemetrySample documents), oldest first."""
        self._version(mission_id)  # 404 for no such mission: the one-row index lookup, not the whole record
        return self._storage.telemetry(mission_id, limit)

    def mission_file(self, mission_id: int) -> tuple[list[MissionItem], tuple[float, float, float], FlightParams]:
        """What a mission file needs: the mission's items, its home (the depot, on the ground) and flight."""
        record = self.get(mission_id)
        plan, flight = Plan.from_dict(record.plan), FlightParams(**record.flight)
        home = (plan.depot[0], plan.depot[1], 0.0)
        return mission_items(plan, flight), home, flight

    def report_index(self, mission_id: int) -> Path:
        """The mission's report (drawn, or the cached drawing when the mission has not changed): its index.html.
        Draws with matplotlib: call it from a worker thread."""
        self.get(mission_id)
        return report.cached_report(self._storage, mission_id, self.settings.reports_dir)
