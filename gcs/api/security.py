"""The optional API token and the live stream's admission.

When the service has a token, every mutating endpoint needs it (401 with `WWW-Authenticate: Bearer` otherwise),
and so does the WebSocket /ws. Reads (GET) stay open: the page must be able to show the map without a token.

A browser cannot set an `Authorization` header on a WebSocket, so the page offers the token as a subprotocol,
as Kubernetes' API server accepts it: `new WebSocket(url, ["buoy-gcs.live", "bearer.<base64url(token)>"])`; the
service answers with the plain `buoy-gcs.live`, so the token is never echoed, and it never appears in a URL (an
access log would keep a `?token=` query). Other clients may send `Authorization: Bearer` instead.
"""

from __future__ import annotations

import base64
import binascii
import secrets
from urllib.parse import urlsplit

from fastapi import Request
from starlette.datastructures import Headers
from starlette.websockets import WebSocket

from gcs.api.errors import ApiError
from gcs.api.routes.deps import SettingsDep
from gcs.settings import Settings

LIVE_SUBPROTOCOL = "buoy-gcs.live"  # what the service answers a page that offered its token
TOKEN_SUBPROTOCOL_PREFIX = "bearer."  # + the token in base64url without padding


def _header_token(headers: Headers) -> str:
    """`Authorization: Bearer <token>`, else `X-API-Token: <token>`, else ""."""
    header = headers.get("authorization", "")
    return header[7:] if header.lower().startswith("bearer ") else headers.get("x-api-token", "")


def _subprotocol_token(offered: list[str]) -> str:
    for protocol in offered:
        if protocol.startswith(TOKEN_SUBPROTOCOL_PREFIX):
            encoded = protocol[len(TOKEN_SUBPROTOCOL_PREFIX) :]
            try:
                return base64.urlsafe_b64decode(encoded + "=" * (-len(encoded) % 4)).decode()
            except (binascii.Error, UnicodeDecodeError):
                return ""
    return ""


def _matches(given: str, expected: str) -> bool:
    # constant time: how much of a guess is right must not show in the answer's timing
    return secrets.compare_digest(given.encode(), expected.encode())


def require_token(request: Request, settings: SettingsDep) -> None:
    """FastAPI dependency: `Authorization: Bearer <token>` (or `X-API-Token: <token>`) must match."""
    expected = settings.token
    if expected and not _matches(_header_token(request.headers), expected):
        loc = ("header", "Authorization")
        raise ApiError(401, loc, "missing or wrong API token", headers={"WWW-Authenticate": "Bearer"})


def _same_origin(origin: str, headers: Headers) -> bool:
    """The Origin names the host the browser asked (the Host header): the service's own page."""
    return urlsplit(origin).netloc.lower() == headers.get("host", "").lower()


def websocket_refusal(websocket: WebSocket, settings: Settings) -> str | None:
    """Why this WebSocket handshake is refused, or None to accept it.

    A browser sends Origin with every WebSocket handshake and no same-origin rule protects a WebSocket, so a
    page of another site could read the live stream in its visitor's browser (cross-site WebSocket hijacking):
    only the service's own page and the CORS origins may connect. Clients that are no browser send no Origin."""
    origin = websocket.headers.get("origin")
    if origin is not None and not _same_origin(origin, websocket.headers) and origin not in settings.cors_origins:
        return f"origin {origin} is not allowed"
    if settings.token:
        given = _header_token(websocket.headers) or _subprotocol_token(websocket.scope.get("subprotocols", []))
        if not _matches(given, settings.token):
            return "missing or wrong API token"
    return None


def accepted_subprotocol(websocket: WebSocket) -> str | None:
    """The subprotocol to answer: the page's, when it offered one (a browser fails a handshake that offered
    subprotocols and got none back)."""
    return LIVE_SUBPROTOCOL if LIVE_SUBPROTOCOL in websocket.scope.get("subprotocols", []) else None
