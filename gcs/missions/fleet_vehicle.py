"""One vehicle of the service: its link, the lifecycle that flies missions on it, and what planning reads from it
(its home as the default depot, its geofence, its battery pack). A service without a fleet has one, whose
missions are stored without a vehicle (`sysid` None); a fleet's vehicles are known by their system ids."""

from __future__ import annotations

import asyncio
from typing import Any

from gcs.missions.inspector import FrameAnalysis
from gcs.missions.lifecycle import FlightLifecycle, vehicle_pack
from gcs.settings import Settings
from gcs.storage.off_loop import AsyncStorage
from gcs.vehicle.link import LinkError, LinkManager
from gcs.vehicle.mission_protocol import MissionTransferError
from planner.energy import EnergyModel
from uavcore.battery_pack import PackSpec
from uavcore.geofence import FenceError, Geofence

FENCE_READ_TIMEOUT_S = 1.5  # wall clock for the vehicle's geofence before a plan


class FleetVehicle:
    def __init__(
        self,
        sysid: int | None,
        link: LinkManager,
        settings: Settings,
        storage: AsyncStorage,
        energy_model: EnergyModel,
        analysis: FrameAnalysis | None = None,
    ) -> None:
        self.sysid = sysid  # what its missions store as vehicle_sysid (None: the service's one vehicle)
        self.link = link
        self.flights = FlightLifecycle(settings, storage, link, energy_model, analysis)
        self._default_home = settings.home
        self._fence_unanswered: int | None = None  # the vehicle incarnation that did not answer a fence request

    @property
    def system_id(self) -> int | None:
        """Its MAVLink system id: as configured, else as heard (None: not heard yet)."""
        return self.link.sysid or self.link.status.sysid

    def depot(self) -> tuple[float, float]:
        """Where its missions start when a request names no depot: its home, else the settings' home."""
        home = self.link.status.home or self._default_home
        return home[0], home[1]

    async def pack(self) -> PackSpec | None:
        """Its pack and warning thresholds from its parameters (None: it has none such, or does not answer)."""
        return await vehicle_pack(self.link)

    async def fence(self) -> Geofence | None:
        """Its current geofence; what was read at connection if it does not answer in time (an autopilot without
        fences may never answer: it is not asked again until it reconnects or reboots)."""
        link = self.link
        if not link.status.connected or self._fence_unanswered == link.status.incarnation:
            return link.fence
        try:
            async with asyncio.timeout(FENCE_READ_TIMEOUT_S):
                return await link.download_fence()
        except (TimeoutError, LinkError, MissionTransferError, FenceError):
            self._fence_unanswered = link.status.incarnation
            return link.fence

    def describe(self) -> dict[str, Any]:
        """Its entry in GET /vehicles: the link's state, `sysid`, `link`, the mission flying on it, and what the
        link has `received` from it (messages, and GLOBAL_POSITION_INT alone: the position stream a fleet's
        service must keep up with)."""
        link = self.link
        received = {"messages": link.messages_received, "positions": link.positions_received}
        return link.status.as_dict() | {
            "sysid": self.system_id,
            "link": str(link.connection),
            "active_mission": self.flights.active_mission(),
            "received": received,
        }
