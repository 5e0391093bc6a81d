"""A mission's inspections: each buoy's verdict and findings, their CSV and GeoJSON exports, the camera frames
behind them, the vehicle's flight log, and the deletion of a mission with everything it stored."""

from __future__ import annotations

import asyncio
import json

from fastapi import APIRouter, Depends, Response

from gcs.api.routes.deps import ServiceDep
from gcs.api.routes.missions import MissionId, download_response, file_responses
from gcs.api.routes.responses import CONFLICT, MUTATING, NOT_FOUND
from gcs.api.security import require_token
from gcs.domain.schemas import InspectionOut
from gcs.reports import exports

router = APIRouter(tags=["inspections"])

# what a stored frame's first bytes say it is: only these are served as images, anything else as bytes
IMAGE_SIGNATURES = {b"\xff\xd8\xff": "image/jpeg", b"\x89PNG\r\n\x1a\n": "image/png"}


@router.get("/missions/{mission_id}/inspections", response_model=list[InspectionOut], responses=NOT_FOUND)
async def get_inspections(mission_id: MissionId, service: ServiceDep) -> list[InspectionOut]:
    """One record per buoy inspected or not so far (a buoy appears once its burst is judged, or when the sortie
    ends): verdict `ok`, `defect` (with findings) or `not_inspected` (with the reason), what was observed and
    the frames' URLs. Empty for a mission that has not flown."""
    return await service.inspections(mission_id)


@router.get("/missions/{mission_id}/inspections.csv", response_class=Response, responses=file_responses("text/csv"))
async def get_inspections_csv(mission_id: MissionId, service: ServiceDep) -> Response:
    content = exports.inspections_csv(await service.inspections(mission_id))
    return download_response(content, "text/csv", f"mission-{mission_id}-inspections.csv")


@router.get(
    "/missions/{mission_id}/inspections.geojson",
    response_class=Response,
    responses=file_responses("application/geo+json"),
)
async def get_inspections_geojson(mission_id: MissionId, service: ServiceDep) -> Response:
    inspections = await service.inspections(mission_id)
    document = exports.inspections_geojson(inspections, {"mission": mission_id})
    content = await asyncio.to_thread(json.dumps, document)
    return download_response(content, "application/geo+json", f"mission-{mission_id}-inspections.geojson")


@router.get(
    "/missions/{mission_id}/frames/{frame_id}",
    response_class=Response,
    responses=file_responses("image/jpeg", "image/png", "application/octet-stream"),
)
async def get_frame(mission_id: MissionId, frame_id: MissionId, service: ServiceDep) -> Response:
    """A camera frame as the camera sent it. Served as an image only when it is one (JPEG or PNG by its first
    bytes); the service decoded it before storing it, but what a camera sends is never trusted further."""
    data = await service.frame(mission_id, frame_id)
    kind = next((media for magic, media in IMAGE_SIGNATURES.items() if data.startswith(magic)), None)
    headers = {"Cache-Control": "private, max-age=86400, immutable"}  # a stored frame never changes
    return Response(data, media_type=kind or "application/octet-stream", headers=headers)


@router.get(
    "/missions/{mission_id}/log",
    response_class=Response,
    responses=file_responses("application/octet-stream"),
)
async def get_flight_log(mission_id: MissionId, service: ServiceDep) -> Response:
    """The flight log the vehicle kept of the mission (PX4's ULog, downloaded over the MAVLink log protocol after
    the landing), for pyulog, PlotJuggler or Flight Review. 404 while there is none, saying why when its download
    failed."""
    data = await service.flight_log(mission_id)
    headers = {"Content-Disposition": f'attachment; filename="mission-{mission_id}.ulg"'}
    return Response(data, media_type="application/octet-stream", headers=headers)


@router.delete(
    "/missions/{mission_id}",
    status_code=204,
    response_class=Response,
    dependencies=[Depends(require_token)],
    responses=MUTATING | NOT_FOUND | CONFLICT,
)
async def delete_mission(mission_id: MissionId, service: ServiceDep) -> Response:
    """Remove a mission and everything stored with it: telemetry, camera frames, inspections, its report (a fleet
    mission: its parts too). 409 while it is being flown: abort it first."""
    await service.delete(mission_id)
    return Response(status_code=204)
