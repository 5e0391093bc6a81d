"""Security headers on every HTTP response: a Content-Security-Policy, nosniff, no referrer, no framing.

The policy allows only the service's own scripts: the page (gcs/web) and the report have no inline script and
no on* attributes, so a buoy name or a STATUSTEXT that slipped into markup still could not run. Styles are the
service's files plus the report's one inline <style>, allowed by its hash. Images: the service's, `data:` (Leaflet
blanks a tile it drops with a data: GIF) and the OpenStreetMap tile server the map page uses when it is online.
/docs and /redoc (gcs.api.docs_pages) load Swagger UI and ReDoc from the service itself (/static/docs), nothing from
another origin, so their policy names none; they (and Swagger UI's OAuth2 redirect page) still need inline script,
FastAPI's HTML starting Swagger UI with one built per request, and inline style (ReDoc's injected <style>s).
"""

from __future__ import annotations

import base64
import hashlib

from starlette.datastructures import MutableHeaders
from starlette.types import ASGIApp, Message, Receive, Scope, Send

from gcs.reports.drawing import REPORT_STYLE

TILE_SERVER = "https://tile.openstreetmap.org"  # the origin of map.js's OSM_URL


def _sha256_source(text: str) -> str:
    return "'sha256-" + base64.b64encode(hashlib.sha256(text.encode()).digest()).decode() + "'"


def _policy(directives: dict[str, str]) -> str:
    return "; ".join(f"{name} {value}" for name, value in directives.items())


_LOCKED = {"object-src": "'none'", "base-uri": "'none'", "frame-ancestors": "'none'", "form-action": "'self'"}
PAGE_POLICY = _policy(
    {
        "default-src": "'self'",
        "script-src": "'self'",
        "style-src": f"'self' {_sha256_source(REPORT_STYLE)}",
        "img-src": f"'self' data: {TILE_SERVER}",
        "connect-src": "'self'",  # fetch and the /ws WebSocket ('self' covers ws: and wss: of the same host)
        **_LOCKED,
    }
)
DOCS_POLICY = _policy(
    {
        "default-src": "'self'",
        "script-src": "'self' 'unsafe-inline'",  # their HTML holds no data (Swagger UI shows answers as text)
        "style-src": "'self' 'unsafe-inline'",
        "font-src": "'self'",
        "img-src": "'self' data:",  # swagger-ui.css draws its icons as data: images
        "worker-src": "'self' blob:",  # ReDoc's search index runs in a worker made from a blob
        "connect-src": "'self'",  # /openapi.json and Swagger UI's "Try it out"
        **_LOCKED,
    }
)
COMMON_HEADERS = {
    "X-Content-Type-Options": "nosniff",  # a JSON answer quoting markup is never taken for HTML
    "Referrer-Policy": "no-referrer",
    "X-Frame-Options": "DENY",  # frame-ancestors for browsers older than CSP 2
    "Cross-Origin-Opener-Policy": "same-origin",
}


class SecurityHeadersMiddleware:
    """Pure ASGI (so streamed and file responses pass through untouched): adds the headers to every HTTP
    response that does not set them itself. `docs_paths` are the paths that get DOCS_POLICY."""

    def __init__(self, app: ASGIApp, docs_paths: frozenset[str] = frozenset()) -> None:
        self.app, self.docs_paths = app, docs_paths

    async def __call__(self, scope: Scope, receive: Receive, send: Send) -> None:
        if scope["type"] != "http":
            await self.app(scope, receive, send)
            return
        policy = DOCS_POLICY if scope["path"] in self.docs_paths else PAGE_POLICY

        async def send_with_headers(message: Message) -> None:
            if message["type"] == "http.response.start":
                headers = MutableHeaders(scope=message)
                for name, value in {"Content-Security-Policy": policy, **COMMON_HEADERS}.items():
                    headers.setdefault(name, value)
            await send(message)

        await self.app(scope, receive, send_with_headers)
