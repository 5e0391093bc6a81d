"""The API's documentation pages, /docs (Swagger UI) and /redoc, served here rather than by FastAPI, whose pages load
Swagger UI and ReDoc from a CDN and stay blank without a network. The assets come from the fastapi-offline wheel
(its static/ folder: swagger-ui-bundle.js, swagger-ui.css, redoc.standalone.js, favicon.png), as Leaflet comes from
xstatic."""

from __future__ import annotations

from importlib.resources import files

from fastapi import FastAPI, Request
from fastapi.openapi.docs import get_redoc_html, get_swagger_ui_html, get_swagger_ui_oauth2_redirect_html
from fastapi.responses import HTMLResponse
from fastapi.staticfiles import StaticFiles

DOCS_URL = "/docs"
OAUTH2_REDIRECT_URL = "/docs/oauth2-redirect"  # FastAPI's default page for Swagger UI's OAuth2 flows
REDOC_URL = "/redoc"
DOCS_ASSETS_URL = "/static/docs"
DOCS_ASSETS_DIR = files("fastapi_offline") / "static"
# the pages (FastAPI's own are off: app.docs_url and app.redoc_url are None), whose security policy differs
DOCS_PATHS = frozenset({DOCS_URL, OAUTH2_REDIRECT_URL, REDOC_URL})


def install_docs(app: FastAPI) -> None:
    """/docs (Swagger UI) and /redoc as FastAPI's own pages, with their scripts and styles from DOCS_ASSETS_URL:
    they work with no network. Out of the OpenAPI document, as FastAPI's are."""
    openapi_url = app.openapi_url
    assert openapi_url is not None  # the pages show /openapi.json

    def under_root(request: Request, path: str) -> str:
        # behind a proxy that strips a prefix (uvicorn --root-path), as FastAPI's pages do
        return request.scope.get("root_path", "").rstrip("/") + path

    @app.get(DOCS_URL, include_in_schema=False)
    async def swagger_ui(request: Request) -> HTMLResponse:
        assets = under_root(request, DOCS_ASSETS_URL)
        return get_swagger_ui_html(
            openapi_url=under_root(request, openapi_url),
            title=f"{app.title} - Swagger UI",
            swagger_js_url=f"{assets}/swagger-ui-bundle.js",
            swagger_css_url=f"{assets}/swagger-ui.css",
            swagger_favicon_url=f"{assets}/favicon.png",
            oauth2_redirect_url=under_root(request, OAUTH2_REDIRECT_URL),
            init_oauth=app.swagger_ui_init_oauth,
            swagger_ui_parameters=app.swagger_ui_parameters,
        )

    @app.get(OAUTH2_REDIRECT_URL, include_in_schema=False)
    async def swagger_ui_oauth2_redirect() -> HTMLResponse:
        return get_swagger_ui_oauth2_redirect_html()

    @app.get(REDOC_URL, include_in_schema=False)
    async def redoc(request: Request) -> HTMLResponse:
        assets = under_root(request, DOCS_ASSETS_URL)
        return get_redoc_html(
            openapi_url=under_root(request, openapi_url),
            title=f"{app.title} - ReDoc",
            redoc_js_url=f"{assets}/redoc.standalone.js",
            redoc_favicon_url=f"{assets}/favicon.png",
            with_google_fonts=False,  # ReDoc falls back to the system's fonts
        )

    app.mount(DOCS_ASSETS_URL, StaticFiles(directory=str(DOCS_ASSETS_DIR)), name="docs-assets")
