"""POST /imports: buoys from a GeoJSON or CSV file sent as the request body."""

from __future__ import annotations

from fastapi import APIRouter, Depends, Query, Request
from pydantic import ValidationError

from gcs.api.routes.responses import WITH_BODY
from gcs.api.security import require_token
from gcs.domain.buoy_files import BuoyFileError, buoys_from_file
from gcs.domain.schemas import MAX_BUOYS, BuoyIn, ImportOut

router = APIRouter(tags=["imports"])


@router.post(
    "/imports",
    response_model=ImportOut,
    dependencies=[Depends(require_token)],
    responses=WITH_BODY,
    openapi_extra={
        "requestBody": {
            "content": {
                "text/csv": {"schema": {"type": "string"}},
                "application/geo+json": {"schema": {"type": "object"}},
            },
            "required": True,
        }
    },
)
async def import_buoys(request: Request, filename: str = Query(default="", max_length=255)) -> dict:
    """The body is the file itself (at most the service's max_body_bytes, 1 MiB by default: 413 beyond); the
    format follows `filename`'s extension or the Content-Type. At most 500 buoys, as a plan takes."""
    buoys = buoys_from_file(await request.body(), filename, request.headers.get("content-type", ""))
    if len(buoys) > MAX_BUOYS:
        raise BuoyFileError(f"the file has {len(buoys)} buoys; a mission takes at most {MAX_BUOYS}")
    return {"buoys": [_checked(i, b.as_dict()) for i, b in enumerate(buoys)]}


def _checked(index: int, buoy: dict) -> BuoyIn:
    """The buoy as a request takes it; a charted property it cannot take is the file's error (422)."""
    try:
        return BuoyIn.model_validate(buoy)
    except ValidationError as error:
        first = error.errors()[0]
        where = ".".join(str(part) for part in first["loc"])
        raise BuoyFileError(f"buoy {index + 1} ({buoy.get('id') or 'unnamed'}): {where}: {first['msg']}") from None
