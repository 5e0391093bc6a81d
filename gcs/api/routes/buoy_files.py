"""POST /imports: buoys from a file sent as the request body: GeoJSON, CSV, or an S-57 chart cell (.000)."""

from __future__ import annotations

import asyncio
from typing import Annotated, Any

from fastapi import APIRouter, Depends, Query, Request
from pydantic import ValidationError

from gcs.api.body_limit import too_large_detail
from gcs.api.errors import ApiError
from gcs.api.routes.deps import SettingsDep
from gcs.api.routes.responses import WITH_BODY
from gcs.api.security import require_token
from gcs.charts import is_cell, read_upload
from gcs.domain.areas import AreaError, parse_area
from gcs.domain.buoy_files import BuoyFileError, buoys_from_file
from gcs.domain.charted_marks import ChartImport, NothingInAreaError
from gcs.domain.schemas import MAX_BUOYS, BuoyIn, IalaRegion, ImportOut
from gcs.missions.validation import Location, RequestInvalidError

router = APIRouter(tags=["imports"])
MAX_AREA_CHARS = 8000  # a polygon of a few hundred vertices, inside what HTTP servers take as a request line
CHART_ONLY = "filters and reads an S-57 cell's marks; a GeoJSON or CSV file is taken whole, as charted in it"
AreaQuery = Annotated[
    str | None,
    Query(
        max_length=MAX_AREA_CHARS,
        description="an S-57 cell's buoys and beacons inside this area only: west,south,east,north in degrees, or "
        "a GeoJSON Polygon",
    ),
]
RegionQuery = Annotated[
    IalaRegion | None,
    Query(
        description="the IALA region of an S-57 cell's marks where the cell names none (default: the service's "
        "iala_region); the cell's own MARSYS wins",
    ),
]


CELL_BODY = {"application/octet-stream": {"schema": {"type": "string", "format": "binary"}}}


def file_body(content: dict[str, Any]) -> dict[str, Any]:
    """A route's openapi_extra for a body that is the file itself."""
    return {"requestBody": {"content": content, "required": True}}


@router.post(
    "/imports",
    response_model=ImportOut,
    dependencies=[Depends(require_token)],
    responses=WITH_BODY,
    openapi_extra=file_body(
        {"text/csv": {"schema": {"type": "string"}}, "application/geo+json": {"schema": {"type": "object"}}} | CELL_BODY
    ),
)
async def import_buoys(
    request: Request,
    settings: SettingsDep,
    filename: str = Query(default="", max_length=255),
    area: AreaQuery = None,
    region: RegionQuery = None,
) -> dict[str, Any]:
    """The body is the file itself. An S-57 cell (named .000, or starting with an ISO 8211 leader) may be up to
    max_chart_bytes (5 MiB); another file up to max_body_bytes (1 MiB): 413 beyond. GeoJSON or CSV follows
    `filename`'s extension or the Content-Type; a point whose role is depot is the answer's `depot`, not a buoy. At
    most 500 buoys, as a plan takes."""
    body = await request.body()
    if is_cell(body, filename):
        return await _chart_import(body, filename, area, region or settings.iala_region)
    if len(body) > settings.max_body_bytes:
        raise ApiError(413, ("body",), too_large_detail(settings.max_body_bytes))
    _refuse_chart_options(area=area, region=region)
    file = buoys_from_file(body, filename, request.headers.get("content-type", ""))
    _check_count(len(file.buoys), f"the file has {len(file.buoys)} buoys")
    return {"buoys": [_checked(i, b.as_dict()) for i, b in enumerate(file.buoys)], "depot": file.depot_as_dict()}


async def read_chart(
    body: bytes, filename: str, area: str | None, region: IalaRegion, basemap: bool = False
) -> ChartImport:
    """An uploaded cell's marks (in `area`, a query parameter), a bad area the query's 422; `basemap`: also its land,
    piers and depth contours (gcs.charts.read_upload). GDAL reads in a worker thread (about half a second for a 3.5 MB
    cell): the event loop keeps serving the vehicle link meanwhile."""
    try:
        shape = None if area is None else parse_area(area)
    except AreaError as error:
        raise RequestInvalidError([(("query", "area"), str(error))]) from None
    try:
        return await asyncio.to_thread(read_upload, body, filename, region, shape, basemap)
    except NothingInAreaError as error:
        raise RequestInvalidError([(("query", "area"), str(error))]) from None


async def _chart_import(body: bytes, filename: str, area: str | None, region: IalaRegion) -> dict[str, Any]:
    """The cell's marks as buoys, with the chart's description of each and the warnings."""
    chart = await read_chart(body, filename, area, region)
    _check_count(len(chart.marks), f"{chart.cell.name} has {len(chart.marks)} buoys and beacons (an area takes fewer)")
    buoys = [_checked(i, mark.as_buoy()) for i, mark in enumerate(chart.marks)]
    return {"buoys": buoys, "chart": _chart_document(chart), "warnings": list(chart.warnings)}


def _chart_document(chart: ChartImport) -> dict[str, Any]:
    cell = chart.cell
    return {
        "cell": cell.name,
        "edition": cell.edition,
        "update": cell.update,
        "issued": cell.issued,
        "region": chart.region,
        "region_source": chart.region_source,
        "marks": [mark.as_dict() for mark in chart.marks],
    }


def _refuse_chart_options(**given: str | None) -> None:
    errors: list[tuple[Location, str]] = [
        (("query", name), f"{name} {CHART_ONLY}") for name, value in given.items() if value is not None
    ]
    if errors:
        raise RequestInvalidError(errors)


def _check_count(count: int, what: str) -> None:
    if count > MAX_BUOYS:
        raise BuoyFileError(f"{what}; a mission takes at most {MAX_BUOYS}")


def _checked(index: int, buoy: dict) -> BuoyIn:
    """The buoy as a request takes it; a charted property it cannot take is the file's error (422)."""
    try:
        return BuoyIn.model_validate(buoy)
    except ValidationError as error:
        first = error.errors()[0]
        where = ".".join(str(part) for part in first["loc"])
        raise BuoyFileError(f"buoy {index + 1} ({buoy.get('id') or 'unnamed'}): {where}: {first['msg']}") from None
