"""The route dependencies, defined once: every route takes the service (and, when it needs one, the settings)
as `service: ServiceDep` / `settings: SettingsDep`, HTTP and WebSocket routes alike."""

from __future__ import annotations

from typing import Annotated

from fastapi import Depends
from starlette.requests import HTTPConnection

from gcs.missions.service import MissionService
from gcs.settings import Settings


# async: FastAPI runs a plain-def dependency in its thread pool, a hop per request for reading an attribute
async def get_service(connection: HTTPConnection) -> MissionService:
    """The app's mission service (HTTPConnection: a Request or a WebSocket, so both kinds of route can use it)."""
    return connection.app.state.service


async def get_settings(connection: HTTPConnection) -> Settings:
    return connection.app.state.settings


ServiceDep = Annotated[MissionService, Depends(get_service)]
SettingsDep = Annotated[Settings, Depends(get_settings)]
