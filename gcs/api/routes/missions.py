"""Missions: create (plan + fly), list, read, telemetry, exports, start, abort, and the operator's hold, resume,
return and land in flight."""

from __future__ import annotations

import asyncio
import json
from typing import Annotated

from fastapi import APIRouter, Depends, Path, Query, Request, Response
from fastapi.responses import FileResponse, RedirectResponse, StreamingResponse

from gcs.api.errors import ApiError
from gcs.api.routes.deps import ServiceDep
from gcs.api.routes.responses import (
    CONFLICT,
    MUTATING,
    NOT_FOUND,
    VEHICLE_SILENT,
    WITH_BODY,
    Responses,
    RouteOptions,
)
from gcs.api.security import require_token
from gcs.domain.listing import CURSOR_PATTERN, MAX_CURSOR, MissionFilter, TimeBound
from gcs.domain.schemas import MissionOut, MissionRequest, MissionSummary, TelemetrySample, TrackOut
from gcs.domain.status import MissionStatus
from gcs.reports import exports, report
from gcs.reports.views import MissionsPage, mission_out, telemetry_chunks

router = APIRouter(tags=["missions"])
# POST /missions answers with links to what can be asked of the new mission (OpenAPI links: clients and
# schemathesis's stateful tests follow them with the id from the answer).
_MISSION_LINKS = {
    name: {"operationId": name, "parameters": {"mission_id": "$response.body#/id"}}
    for name in (
        *("get_mission", "get_telemetry", "get_qgc_plan", "get_waypoints", "get_track", "get_report"),
        *("get_display_track", "start_mission", "abort_mission"),
        *("hold_mission", "resume_mission", "return_mission", "land_mission"),
    )
}
CREATED: Responses = {201: {"links": _MISSION_LINKS}}
# start and abort: what they answer and need
ACTION: RouteOptions = {
    "response_model": MissionOut,
    "dependencies": [Depends(require_token)],
    "responses": MUTATING | NOT_FOUND | CONFLICT,
}
# the operator's commands in flight: the same, and the vehicle may not answer (a refusal is a 409 naming it)
COMMAND: RouteOptions = ACTION | {"responses": MUTATING | NOT_FOUND | CONFLICT | VEHICLE_SILENT}


def file_responses(*media_types: str) -> Responses:
    """A download's answer: a file of these media types, or 404."""
    return {200: {"description": "the file", "content": {kind: {} for kind in media_types}}} | NOT_FOUND


REDIRECT: Responses = {307: {"headers": {"Location": {"required": True, "schema": {"type": "string"}}}}}
MissionId = Annotated[int, Path(ge=1, le=2**63 - 1, description="the mission's id (SQLite integer)")]


@router.post(
    "/missions",
    status_code=201,
    response_model=MissionOut,
    dependencies=[Depends(require_token)],
    responses=CREATED | WITH_BODY | CONFLICT,
)
async def create_mission(request: MissionRequest, service: ServiceDep) -> MissionOut:
    """Plan, store, and (start=true) upload, arm and fly.

    Answers 201 as soon as the mission is planned and stored (status `planned`); the upload, arming and flight
    run in the background: poll GET /missions/{id} or watch /ws. With no vehicle heard within the service's
    vehicle wait (default 5 s) the mission ends `failed` with reason "no vehicle". 409 while another mission
    uses the vehicle."""
    mission_id = await service.create(request)
    return mission_out(await service.get(mission_id))


def _encoded(body: bytes) -> Response:
    """A document the service encoded once (gcs.missions.read_cache), served as it is: the route's response_model still
    tells OpenAPI its shape, and the cache built it as that model (gcs.reports.views)."""
    return Response(body, media_type="application/json")


LimitQuery = Annotated[int, Query(ge=1, le=1000, description="the most missions in the page")]
CursorQuery = Annotated[
    str | None,
    Query(
        max_length=MAX_CURSOR,
        pattern=CURSOR_PATTERN,
        description='where the previous page ended: its X-Next-Cursor (the Link rel="next" URL carries it)',
    ),
]
StatusQuery = Annotated[
    list[MissionStatus] | None, Query(description="only missions in one of these statuses (repeat the parameter)")
]
VehicleQuery = Annotated[
    int | None,
    Query(ge=1, le=255, description="only missions of the vehicle with this system id (a fleet mission: of a part)"),
]
SinceQuery = Annotated[
    TimeBound | None,
    Query(description="only missions created at or after this date-time (with its offset), or from this date (UTC)"),
]
UntilQuery = Annotated[
    TimeBound | None,
    Query(description="only missions created before this date-time (with its offset), or through this date (UTC)"),
]
_NEXT_PAGE_HEADERS = {
    "Link": {
        "description": 'the next page: `<URL>; rel="next"` (RFC 8288), this request\'s URL with the next cursor; '
        "absent on the last page",
        "schema": {"type": "string"},
    },
    "X-Next-Cursor": {
        "description": "the next page's `cursor`; absent on the last page",
        "schema": {"type": "string"},
    },
}
PAGED: Responses = {200: {"description": "a page of missions, newest first", "headers": _NEXT_PAGE_HEADERS}}


def _page(request: Request, page: MissionsPage) -> Response:
    """A page as served, with the next page's URL and cursor when there is one. The Link is relative (RFC 8288
    resolves it against the request's URL), so it stays right behind a proxy that serves the API elsewhere; it
    keeps every other query parameter, repeated ones too, and replaces the cursor."""
    response = _encoded(page.body)
    if page.next_cursor is not None:
        query = request.url.include_query_params(cursor=page.next_cursor).query
        response.headers["Link"] = f'<{request.url.path}?{query}>; rel="next"'
        response.headers["X-Next-Cursor"] = page.next_cursor
    return response


# The read routes answer from the service's cache of encoded documents: one version query per request (in a
# storage thread, gcs.storage.off_loop), then the bytes.
@router.get("/missions", response_model=list[MissionSummary], responses=PAGED)
async def list_missions(
    request: Request,
    service: ServiceDep,
    limit: LimitQuery = 100,
    cursor: CursorQuery = None,
    status: StatusQuery = None,
    vehicle: VehicleQuery = None,
    since: SinceQuery = None,
    until: UntilQuery = None,
) -> Response:
    """The missions, newest first by creation time (`created_at`, then id), a page at a time: the body is the
    page's list; when more follow, the `Link` header (rel="next") and `X-Next-Cursor` give the next page (the
    same query with `cursor`). A fleet mission is listed, its part missions are in its `fleet`
    (GET /missions/{id}).

    Filters combine: `status` (repeatable: any of them; a fleet mission's own status), `vehicle` (the system id
    a mission was stored for; a fleet mission matches when any of its parts flies that vehicle; missions of a
    service without a fleet are stored with no vehicle and match no `vehicle`), `since` / `until` on the
    mission's creation time (`created_at`, to the millisecond): `since` inclusive, `until` exclusive; a date
    alone is a whole day in UTC (`since` from its 00:00, `until` through its end). 422 naming the field for
    a status that does not exist, a time that is not ISO 8601 (a date-time needs its offset), an `until` not
    after `since`, or a cursor this service did not give (a cursor holds only where its page ended: the filters
    come from the query, so keep them from page to page, as the Link does)."""
    where = MissionFilter.of(status, vehicle, since, until)
    return _page(request, await service.missions_page(limit, where, cursor))


@router.get("/missions/{mission_id}", response_model=MissionOut, responses=NOT_FOUND)
async def get_mission(mission_id: MissionId, service: ServiceDep) -> Response:
    return _encoded(await service.mission_json(mission_id))


@router.post("/missions/{mission_id}/start", **ACTION)
async def start_mission(mission_id: MissionId, service: ServiceDep) -> MissionOut:
    """Fly a mission created with start=false."""
    await service.launch(mission_id)
    return mission_out(await service.get(mission_id))


@router.post("/missions/{mission_id}/abort", **ACTION)
async def abort_mission(mission_id: MissionId, service: ServiceDep) -> MissionOut:
    """Return to the depot (NAV_RETURN_TO_LAUNCH); a mission not yet flying simply ends."""
    await service.abort(mission_id)
    return mission_out(await service.get(mission_id))


@router.post("/missions/{mission_id}/hold", **COMMAND)
async def hold_mission(mission_id: MissionId, service: ServiceDep) -> MissionOut:
    """Hold where it is (PX4 AUTO.LOITER, ArduPilot LOITER); the mission stays flying, its flight-time budget
    stopped, until resumed, returned or landed. 409 unless it is in the air (a fleet mission: command its parts)."""
    await service.command(mission_id, "hold")
    return mission_out(await service.get(mission_id))


@router.post("/missions/{mission_id}/resume", **COMMAND)
async def resume_mission(mission_id: MissionId, service: ServiceDep) -> MissionOut:
    """After a hold or a return: fly on in the mission mode from the first buoy not yet visited. 409 otherwise."""
    await service.resume(mission_id)
    return mission_out(await service.get(mission_id))


@router.post("/missions/{mission_id}/return", **COMMAND)
async def return_mission(mission_id: MissionId, service: ServiceDep) -> MissionOut:
    """Return to the depot (PX4 AUTO.RTL, ArduPilot RTL), resumable until landed; landed, the mission ends
    aborted naming the buoys not inspected (abort, by contrast, ends it at once)."""
    await service.command(mission_id, "return")
    return mission_out(await service.get(mission_id))


@router.post("/missions/{mission_id}/land", **COMMAND)
async def land_mission(mission_id: MissionId, service: ServiceDep) -> MissionOut:
    """Land where it is (PX4 AUTO.LAND, ArduPilot LAND); on the ground and disarmed the mission ends aborted."""
    await service.command(mission_id, "land")
    return mission_out(await service.get(mission_id))


@router.get("/missions/{mission_id}/telemetry", response_model=list[TelemetrySample], responses=NOT_FOUND)
async def get_telemetry(
    mission_id: MissionId, service: ServiceDep, limit: Annotated[int | None, Query(ge=1, le=1_000_000)] = None
) -> StreamingResponse:
    """Every recorded sample, oldest first (the first `limit`): streamed in chunks (encoded in a worker thread),
    so a long flight's megabytes never hold up the other requests."""
    samples = await service.telemetry(mission_id, limit)
    return StreamingResponse(telemetry_chunks(samples), media_type="application/json")


@router.get("/missions/{mission_id}/track", response_model=TrackOut, responses=NOT_FOUND)
async def get_display_track(
    mission_id: MissionId,
    service: ServiceDep,
    max_points: Annotated[int, Query(ge=2, le=100_000, description="the most positions (and chart samples)")] = 2000,
) -> Response:
    """The flown track for the map page: at most `max_points` positions (the first, the last and every buoy
    arrival always among them) within `tolerance_m` of every recorded one, and samples spread over the flight for
    the charts. Every sample is in /telemetry and track.geojson."""
    return _encoded(await service.track_json(mission_id, max_points))


def download_response(content: str, media_type: str, filename: str) -> Response:
    return Response(
        content, media_type=media_type, headers={"Content-Disposition": f'attachment; filename="{filename}"'}
    )


@router.get(
    "/missions/{mission_id}/track.geojson", response_class=Response, responses=file_responses("application/geo+json")
)
async def get_track(mission_id: MissionId, service: ServiceDep) -> Response:
    properties = {"mission": mission_id, "status": (await service.get(mission_id)).status}
    samples = await service.telemetry(mission_id)
    content = await asyncio.to_thread(lambda: json.dumps(exports.track_geojson(samples, properties)))
    return download_response(content, "application/geo+json", f"mission-{mission_id}-track.geojson")


@router.get("/missions/{mission_id}/plan", response_class=Response, responses=file_responses("application/json"))
async def get_qgc_plan(mission_id: MissionId, service: ServiceDep) -> Response:
    file = await service.mission_file(mission_id)
    speed = file.flight.speed_m_s
    document = exports.qgc_plan(file.items, file.home, speed, speed, file.fence, file.rally_points)
    return download_response(json.dumps(document, indent=2), "application/json", f"mission-{mission_id}.plan")


@router.get("/missions/{mission_id}/waypoints", response_class=Response, responses=file_responses("text/plain"))
async def get_waypoints(mission_id: MissionId, service: ServiceDep) -> Response:
    file = await service.mission_file(mission_id)  # WPL 110 holds the mission alone: no fence, no rally points
    text = exports.waypoints_text(file.items, file.home)
    return download_response(text, "text/plain", f"mission-{mission_id}.waypoints")


@router.get(
    "/missions/{mission_id}/report",
    response_class=RedirectResponse,
    status_code=307,
    responses=REDIRECT | NOT_FOUND,
)
async def get_report(mission_id: MissionId, service: ServiceDep) -> RedirectResponse:
    """The mission report (figures table and PNGs, the paper's Section VI from this flight): redirects to
    its index.html, which names its figures relative to itself."""
    await service.get(mission_id)
    return RedirectResponse(f"/missions/{mission_id}/report/index.html", status_code=307)


@router.get(
    "/missions/{mission_id}/report/{name}",
    response_class=FileResponse,
    responses=file_responses("text/html", "image/png", "image/jpeg"),
)
async def get_report_file(mission_id: MissionId, name: str, service: ServiceDep) -> FileResponse:
    """index.html, one of its figures or a defective buoy's best frame, drawn (copied) on first request and again
    only after the mission changed."""
    await service.get(mission_id)
    if not report.is_report_file(name):
        raise ApiError(404, ("path", "name"), f"no report file {name!r}")
    index = await service.report_index(mission_id)
    if not (index.parent / name).is_file():  # energy.png: only for a mission planned with energy figures
        raise ApiError(404, ("path", "name"), f"mission {mission_id}'s report has no {name}")
    return FileResponse(index.parent / name, headers={"Cache-Control": "no-cache"})
