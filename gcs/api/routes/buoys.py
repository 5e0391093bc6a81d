"""The buoy register: S-57 cells imported into it, its buoys (filtered, exported), each buoy's history and
defects, an operator's change of a defect's state, and the off-station alarms. Thin: MissionService.register does
the work."""

from __future__ import annotations

import asyncio
import gzip
import json
from typing import Annotated

from fastapi import APIRouter, Depends, Path, Query, Request, Response

from gcs.api.routes.buoy_files import CELL_BODY, AreaQuery, RegionQuery, file_body, read_chart
from gcs.api.routes.deps import ServiceDep, SettingsDep
from gcs.api.routes.missions import download_response
from gcs.api.routes.responses import MUTATING, NO_BUOY, WITH_BODY, Responses
from gcs.api.security import require_token
from gcs.charts import is_cell
from gcs.domain.areas import AreaError, parse_bbox
from gcs.domain.buoy_files import BuoyFileError
from gcs.domain.register import (
    AlarmOut,
    BuoyDetailOut,
    BuoyFilter,
    BuoyOut,
    BuoyPatchIn,
    DefectOut,
    DefectPatchIn,
    RegisterImportOut,
)
from gcs.domain.schemas import BuoyKind
from gcs.missions.validation import RequestInvalidError
from gcs.reports import exports

router = APIRouter(tags=["buoys"])
BuoyId = Annotated[str, Path(min_length=1, max_length=64, description="the register id (the chart's LNAM)")]
DefectId = Annotated[int, Path(ge=1, le=2**63 - 1)]
BboxQuery = Annotated[
    str | None, Query(max_length=200, description="only buoys charted in west,south,east,north (degrees)")
]
KindQuery = Annotated[BuoyKind | None, Query(description="only buoys of this IALA kind")]
OverdueQuery = Annotated[
    float | None, Query(gt=0.0, le=36_500.0, description="only buoys not inspected for this many days, or never")
]
DefectsQuery = Annotated[
    bool | None, Query(description="true: only buoys with open or confirmed defects; false: only those without")
]


@router.post(
    "/buoys/imports",
    response_model=RegisterImportOut,
    dependencies=[Depends(require_token)],
    responses=WITH_BODY,
    openapi_extra=file_body(CELL_BODY),
)
async def import_register(
    request: Request,
    service: ServiceDep,
    settings: SettingsDep,
    filename: str = Query(default="", max_length=255),
    area: AreaQuery = None,
    region: RegionQuery = None,
) -> RegisterImportOut:
    """An S-57 cell's buoys and beacons into the register, as POST /imports reads them (same body, area and
    region): a buoy new by its LNAM is registered, a known one updated where the chart changed it (its history
    kept). An id or a name the import gives twice is reported in `duplicates`, never merged."""
    body = await request.body()
    if not is_cell(body, filename):
        raise BuoyFileError("the register imports S-57 cells (.000): the body is not one")
    chart = await read_chart(body, filename, area, region or settings.iala_region, basemap=True)
    return await service.register.import_chart(chart)


async def _buoys(
    service: ServiceDep,
    bbox: BboxQuery = None,
    kind: KindQuery = None,
    overdue_days: OverdueQuery = None,
    open_defects: DefectsQuery = None,
) -> list[BuoyOut]:
    """The dependency GET /buoys and its exports share: the filtered buoys."""
    try:
        box = None if bbox is None else parse_bbox(bbox)
    except AreaError as error:
        raise RequestInvalidError([(("query", "bbox"), str(error))]) from None
    return await service.register.buoys(BuoyFilter(bbox=box, kind=kind, open_defects=open_defects), overdue_days)


FilteredBuoys = Annotated[list[BuoyOut], Depends(_buoys)]


@router.get("/buoys", response_model=list[BuoyOut])
async def list_buoys(buoys: FilteredBuoys) -> list[BuoyOut]:
    """The register's buoys by id, with their last inspection and count of open defects; filters combine."""
    return buoys


def export(media_type: str) -> Responses:
    """An export's answer: the file (never a 404: no buoy passing the filters is an empty file)."""
    return {200: {"description": "the file", "content": {media_type: {}}}}


@router.get("/buoys.geojson", response_class=Response, responses=export("application/geo+json"))
async def get_buoys_geojson(buoys: FilteredBuoys) -> Response:
    content = await asyncio.to_thread(json.dumps, exports.buoys_geojson(buoys))
    return download_response(content, "application/geo+json", "buoys.geojson")


@router.get("/buoys.csv", response_class=Response, responses=export("text/csv"))
async def get_buoys_csv(buoys: FilteredBuoys) -> Response:
    return download_response(exports.buoys_csv(buoys), "text/csv", "buoys.csv")


@router.get("/basemap.geojson", response_class=Response, responses=export("application/geo+json"))
async def get_basemap(request: Request, service: ServiceDep) -> Response:
    """The offline base map: the land, piers and breakwaters and depth contours of every chart cell the register
    imported (features with `layer`: land, shoreline_construction, depth_contour; a contour's `depth_m`). Empty
    before any import. Megabytes for a harbour cell: sent gzip-compressed to a client that takes it."""
    content = await service.register.basemap()
    headers = {"Vary": "Accept-Encoding", "Cache-Control": "no-cache"}
    if "gzip" in request.headers.get("accept-encoding", ""):
        content = await asyncio.to_thread(gzip.compress, content, 6)
        headers["Content-Encoding"] = "gzip"
    return Response(content, media_type="application/geo+json", headers=headers)


@router.get("/buoys/{buoy_id}", response_model=BuoyDetailOut, responses=NO_BUOY)
async def get_buoy(buoy_id: BuoyId, service: ServiceDep) -> BuoyDetailOut:
    """A buoy as charted, its latest inspection, its open and confirmed defects, its whole history, and the
    latest AIS report of its MMSI when the feed heard one."""
    return await service.register.buoy(buoy_id)


@router.patch(
    "/buoys/{buoy_id}", response_model=BuoyOut, dependencies=[Depends(require_token)], responses=MUTATING | NO_BUOY
)
async def patch_buoy(buoy_id: BuoyId, change: BuoyPatchIn, service: ServiceDep) -> BuoyOut:
    """Give the buoy the MMSI of its AIS transmitter (the chart does not carry it), or null."""
    return await service.register.set_mmsi(buoy_id, change.mmsi)


@router.patch(
    "/buoys/{buoy_id}/defects/{defect_id}",
    response_model=DefectOut,
    dependencies=[Depends(require_token)],
    responses=MUTATING | NO_BUOY,
)
async def patch_defect(buoy_id: BuoyId, defect_id: DefectId, change: DefectPatchIn, service: ServiceDep) -> DefectOut:
    """An operator confirms or closes a defect, with a note; the change joins the buoy's history."""
    return await service.register.set_defect(buoy_id, defect_id, change.state, change.note)


@router.get("/alarms", response_model=list[AlarmOut])
async def list_alarms(service: ServiceDep) -> list[AlarmOut]:
    """Off-station alarms, each with its evidence: an inspection's off_station finding on a register buoy (until
    its defect is closed), and a register buoy whose MMSI's current AIS report carries the off-position flag or a
    position outside its swing circle."""
    return await service.register.alarms()
