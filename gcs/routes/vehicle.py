"""GET /vehicle: the link's view of the vehicle (connected or not, state, home); GET /vehicles: the fleet's."""

from __future__ import annotations

from typing import Annotated, Any

from fastapi import APIRouter, Path

from gcs.routes.deps import ServiceDep
from gcs.routes.responses import NO_VEHICLE

router = APIRouter(tags=["vehicle"])


@router.get("/vehicle")
def get_vehicle(service: ServiceDep) -> dict[str, Any]:
    """`connected` is false until the vehicle's heartbeat is heard; `home` falls back to the default depot.
    `role` is `owner` when this instance owns the vehicle link, `standby` when another one does (`owner` names
    it; a stand-by never connects to the vehicle and answers 503 to what would fly)."""
    return service.vehicle()


@router.get("/vehicles")
def list_vehicles(service: ServiceDep) -> list[dict[str, Any]]:
    """Every vehicle the service holds a link to (`serve --vehicle` repeated, `up --vehicles N`), in that order:
    its state as on GET /vehicle, `sysid`, its `link`, the `active_mission` flying on it, and what the link
    `received` from it. POST /missions names one by `vehicle` (default: the first)."""
    return service.vehicles()


@router.get("/vehicles/{sysid}", responses=NO_VEHICLE)
def get_fleet_vehicle(service: ServiceDep, sysid: Annotated[int, Path(ge=1, le=255)]) -> dict[str, Any]:
    """One vehicle of the fleet by its MAVLink system id."""
    return service.fleet_vehicle(sysid)
