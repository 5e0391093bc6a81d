"""GET /vehicle: the link's view of the vehicle (connected or not, state, home); GET /vehicles: the fleet's;
POST .../battery-swap: the operator's word that a fresh pack is in."""

from __future__ import annotations

from typing import Annotated, Any

from fastapi import APIRouter, Depends, Path

from gcs.api.routes.deps import ServiceDep
from gcs.api.routes.responses import CONFLICT, MUTATING, NO_VEHICLE, RouteOptions
from gcs.api.security import require_token
from gcs.domain.schemas import BatterySwapIn, BatterySwapOut, FleetVehicleOut, ServiceVehicleOut

router = APIRouter(tags=["vehicle"])
SystemId = Annotated[int, Path(ge=1, le=255)]


@router.get("/vehicle", response_model=ServiceVehicleOut)
def get_vehicle(service: ServiceDep) -> dict[str, Any]:
    """`connected` is false until the vehicle's heartbeat is heard; `home` falls back to the default depot.
    `role` is `owner` when this instance owns the vehicle link, `standby` when another one does (`owner` names
    it; a stand-by never connects to the vehicle and answers 503 to what would fly)."""
    return service.vehicle()


@router.get("/vehicles", response_model=list[FleetVehicleOut])
def list_vehicles(service: ServiceDep) -> list[dict[str, Any]]:
    """Every vehicle the service holds a link to (`serve --vehicle` repeated, `up --vehicles N`), in that order:
    its state as on GET /vehicle, `sysid`, its `link`, the `active_mission` flying on it, and what the link
    `received` from it. POST /missions names one by `vehicle` (default: the first)."""
    return service.vehicles()


@router.get("/vehicles/{sysid}", response_model=FleetVehicleOut, responses=NO_VEHICLE)
def get_fleet_vehicle(service: ServiceDep, sysid: SystemId) -> dict[str, Any]:
    """One vehicle of the fleet by its MAVLink system id."""
    return service.fleet_vehicle(sysid)


SWAP: RouteOptions = {"dependencies": [Depends(require_token)], "responses": MUTATING | CONFLICT}


@router.post("/vehicle/battery-swap", **SWAP)
async def swap_battery(service: ServiceDep, swap: BatterySwapIn | None = None) -> BatterySwapOut:
    """The operator swapped the vehicle's pack (on the ground, disarmed): the vehicle is told
    (MAV_CMD_BATTERY_RESET at `charge_pct`; the simulator puts the pack in) and a mission waiting for the swap
    (`waiting_for_battery`) goes on once the vehicle reports the charge its next sortie needs. The service never
    sends this by itself. 409 while the vehicle is armed or airborne."""
    return BatterySwapOut(**await service.battery_swapped(None, (swap or BatterySwapIn()).charge_pct))


@router.post("/vehicles/{sysid}/battery-swap", **SWAP | {"responses": MUTATING | CONFLICT | NO_VEHICLE})
async def swap_fleet_battery(service: ServiceDep, sysid: SystemId, swap: BatterySwapIn | None = None) -> BatterySwapOut:
    """As POST /vehicle/battery-swap, for one vehicle of the fleet by its system id."""
    return BatterySwapOut(**await service.battery_swapped(sysid, (swap or BatterySwapIn()).charge_pct))
