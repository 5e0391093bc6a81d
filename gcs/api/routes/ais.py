"""GET /ais/atons: the AtoNs the AIS feed heard, each one's latest report; GET /ais/sources: the feed's sources.
Read-only. Async: the feed lives on the event loop, so it is read there, between its updates."""

from __future__ import annotations

from fastapi import APIRouter

from gcs.api.routes.deps import ServiceDep
from gcs.domain.ais import AisSourceOut, AtonsOut

router = APIRouter(prefix="/ais", tags=["ais"])


@router.get("/atons")
async def list_atons(service: ServiceDep) -> AtonsOut:
    """Each Aid to Navigation's latest AIS report (message 21): MMSI, name, type, position, the off-position and
    virtual flags, the source and shore station it came by, when it was received and its age. A report older than
    `stale_after_s` is `stale`: never a current position. An MMSI that several AtoNs report (other names or
    positions far apart) is not merged: each is a row with `conflict`, and `conflicts` lists them together."""
    return service.ais_atons()


@router.get("/sources")
async def list_ais_sources(service: ServiceDep) -> list[AisSourceOut]:
    """Each `--ais` source: connected (listening, for UDP), the last line's time and age (a silent feed's grows),
    and what became of its lines: decoded, bad checksum, unknown type, dropped by the rate bound, ..."""
    return service.ais_sources()
