"""POST /imports: buoys from a GeoJSON or CSV file sent as the request body."""

from __future__ import annotations

from fastapi import APIRouter, Depends, Query, Request

from gcs.buoy_files import BuoyFileError, buoys_from_file
from gcs.schemas import ImportOut
from gcs.security import require_token

router = APIRouter(tags=["imports"])
MAX_FILE_BYTES = 2_000_000


@router.post(
    "/imports",
    response_model=ImportOut,
    dependencies=[Depends(require_token)],
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
    """The body is the file itself; the format follows `filename`'s extension or the Content-Type."""
    data = await request.body()
    if len(data) > MAX_FILE_BYTES:
        raise BuoyFileError(f"the file is larger than {MAX_FILE_BYTES} bytes")
    buoys = buoys_from_file(data, filename, request.headers.get("content-type", ""))
    return {"buoys": [b.as_dict() for b in buoys]}
