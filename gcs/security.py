"""The optional API token: when the service has one, every mutating endpoint needs it (401 otherwise)."""

from __future__ import annotations

import secrets

from fastapi import HTTPException, Request, status

from gcs.routes.deps import SettingsDep


def require_token(request: Request, settings: SettingsDep) -> None:
    """FastAPI dependency: `Authorization: Bearer <token>` (or `X-API-Token: <token>`) must match."""
    expected = settings.token
    if not expected:
        return
    header = request.headers.get("authorization", "")
    given = header[7:] if header.lower().startswith("bearer ") else request.headers.get("x-api-token", "")
    if not secrets.compare_digest(given.encode(), expected.encode()):
        raise HTTPException(
            status.HTTP_401_UNAUTHORIZED, "missing or wrong API token", headers={"WWW-Authenticate": "Bearer"}
        )
