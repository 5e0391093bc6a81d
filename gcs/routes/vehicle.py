"""GET /vehicle: the link's view of the vehicle (connected or not, state, home)."""

from __future__ import annotations

from typing import Any

from fastapi import APIRouter

from gcs.routes.deps import ServiceDep

router = APIRouter(tags=["vehicle"])


@router.get("/vehicle")
def get_vehicle(service: ServiceDep) -> dict[str, Any]:
    """`connected` is false until the vehicle's heartbeat is heard; `home` falls back to the default depot.
    `role` is `owner` when this instance owns the vehicle link, `standby` when another one does (`owner` names
    it; a stand-by never connects to the vehicle and answers 503 to what would fly)."""
    return service.vehicle()
