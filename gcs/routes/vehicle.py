"""GET /vehicle: the link's view of the vehicle (connected or not, state, home)."""

from __future__ import annotations

from typing import Annotated, Any

from fastapi import APIRouter, Depends

from gcs.missions import MissionService
from gcs.routes.deps import get_service

router = APIRouter(tags=["vehicle"])


@router.get("/vehicle")
def get_vehicle(service: Annotated[MissionService, Depends(get_service)]) -> dict[str, Any]:
    """`connected` is false until the vehicle's heartbeat is heard; `home` falls back to the default depot."""
    data = service.link.status.as_dict()
    data["depot"] = dict(zip(("lat", "lon"), service.default_depot(), strict=True))
    data["active_mission"] = service.active_mission()
    return data
