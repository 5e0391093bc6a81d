"""The FastAPI application factory: wires settings, storage, link manager and mission service to the routes."""

from __future__ import annotations

import asyncio
import gc
import logging
import math
import time
from collections.abc import AsyncIterator
from contextlib import asynccontextmanager
from importlib.resources import files

import xstatic.pkg.leaflet as leaflet
from fastapi import FastAPI, Request
from fastapi.exception_handlers import http_exception_handler
from fastapi.exceptions import RequestValidationError
from fastapi.middleware.cors import CORSMiddleware
from fastapi.openapi.docs import get_redoc_html, get_swagger_ui_html, get_swagger_ui_oauth2_redirect_html
from fastapi.responses import FileResponse, HTMLResponse, JSONResponse
from fastapi.routing import APIRoute
from fastapi.staticfiles import StaticFiles
from starlette.exceptions import HTTPException as StarletteHTTPException
from starlette.responses import Response

from gcs.api.body_limit import BodyLimitMiddleware
from gcs.api.http_headers import SecurityHeadersMiddleware
from gcs.api.routes import ais, buoy_files, buoys, inspections, live, missions, plans, vehicle
from gcs.domain.buoy_files import BuoyFileError
from gcs.missions.lifecycle import MissionConflictError
from gcs.missions.ownership import NotOwnerError
from gcs.missions.register import BuoyNotFoundError
from gcs.missions.service import FrameNotFoundError, MissionNotFoundError, MissionService, VehicleNotFoundError
from gcs.missions.validation import RequestInvalidError
from gcs.settings import Settings
from gcs.storage import open_storage
from gcs.storage.off_loop import AsyncStorage
from gcs.vehicle.connection import TransportHub
from gcs.vehicle.link import LinkManager
from planner.errors import PlannerError
from planner.warmup import warm_up
from uavcore.mavlink import parse_signing_key

log = logging.getLogger(__name__)

# The API's documentation pages, served by _install_docs rather than by FastAPI, whose pages load Swagger UI and
# ReDoc from a CDN and stay blank without a network. The assets come from the fastapi-offline wheel (its static/
# folder: swagger-ui-bundle.js, swagger-ui.css, redoc.standalone.js, favicon.png), as Leaflet comes from xstatic.
DOCS_URL = "/docs"
OAUTH2_REDIRECT_URL = "/docs/oauth2-redirect"  # FastAPI's default page for Swagger UI's OAuth2 flows
REDOC_URL = "/redoc"
DOCS_ASSETS_URL = "/static/docs"
DOCS_ASSETS_DIR = files("fastapi_offline") / "static"


async def warm_up_planner() -> float:
    """Compile (or load from numba's cache) the planner's kernels, off the event loop; returns the seconds it took.

    Awaited in the lifespan before it yields, so uvicorn takes no request until it ends: otherwise the first plan
    of each kind compiles inside its request, whose time limit the compile does not see (a 2 s fleet plan answered
    after 56 s on a cold cache). With the cache on disk it only loads the compiled code."""
    started = time.perf_counter()
    await asyncio.to_thread(warm_up)
    return time.perf_counter() - started


def _unprocessable(errors: list[tuple[tuple, str]], types: list[str] | None = None) -> JSONResponse:
    """422 in the shape FastAPI gives its own validation errors: {"detail": [{type, loc, msg}]}."""
    types = types or ["value_error"] * len(errors)
    detail = [{"type": kind, "loc": list(loc), "msg": msg} for (loc, msg), kind in zip(errors, types, strict=True)]
    return JSONResponse({"detail": detail}, status_code=422)


def _install_error_handlers(app: FastAPI) -> None:
    @app.exception_handler(RequestValidationError)
    async def invalid_body(_: Request, error: RequestValidationError) -> JSONResponse:
        # FastAPI's default echoes the input, which cannot be encoded when it is NaN or Infinity: a 500.
        return _unprocessable(
            [(tuple(e["loc"]), e["msg"]) for e in error.errors()], [e["type"] for e in error.errors()]
        )

    @app.exception_handler(StarletteHTTPException)
    async def http_error(request: Request, error: StarletteHTTPException) -> Response:
        if error.status_code == 400:  # FastAPI's answer to a body it cannot decode (not UTF-8): bad input too
            return _unprocessable([(("body",), "the body is not JSON in UTF-8")], ["json_invalid"])
        return await http_exception_handler(request, error)

    @app.exception_handler(RequestInvalidError)
    async def request_invalid(_: Request, error: RequestInvalidError) -> JSONResponse:
        return _unprocessable(error.errors)

    @app.exception_handler(PlannerError)
    async def planner_error(_: Request, error: PlannerError) -> JSONResponse:
        return _unprocessable([(("body", "buoys"), str(error))])

    @app.exception_handler(BuoyFileError)
    async def buoy_file_error(_: Request, error: BuoyFileError) -> JSONResponse:
        return _unprocessable([(("body",), str(error))])

    @app.exception_handler(MissionNotFoundError)
    async def not_found(_: Request, error: MissionNotFoundError) -> JSONResponse:
        return JSONResponse({"detail": f"no mission {error.args[0]}"}, status_code=404)

    @app.exception_handler(FrameNotFoundError)
    async def no_frame(_: Request, error: FrameNotFoundError) -> JSONResponse:
        return JSONResponse({"detail": error.args[0]}, status_code=404)

    @app.exception_handler(BuoyNotFoundError)
    async def no_buoy(_: Request, error: BuoyNotFoundError) -> JSONResponse:
        return JSONResponse({"detail": error.args[0]}, status_code=404)

    @app.exception_handler(VehicleNotFoundError)
    async def no_vehicle(_: Request, error: VehicleNotFoundError) -> JSONResponse:
        return JSONResponse({"detail": f"no vehicle with system id {error.args[0]}"}, status_code=404)

    @app.exception_handler(MissionConflictError)
    async def conflict(_: Request, error: MissionConflictError) -> JSONResponse:
        return JSONResponse({"detail": str(error)}, status_code=409)

    @app.exception_handler(NotOwnerError)
    async def standby(request: Request, error: NotOwnerError) -> JSONResponse:
        # a client may retry here (this instance takes over when the owner dies) or go to the owner
        retry_s = max(1, math.ceil(request.app.state.settings.lease_poll_s))
        return JSONResponse({"detail": str(error)}, status_code=503, headers={"Retry-After": str(retry_s)})


def _operation_id(route: APIRoute) -> str:
    """The OpenAPI operationId of a route: its function's name (get_mission), which the links between
    operations name (POST /missions answers with links to get_mission, start_mission, ...)."""
    return route.name


def _install_middleware(app: FastAPI, settings: Settings) -> None:
    """Each middleware added wraps those before it: the security headers, added last, go on every answer
    (a 413 and a CORS preflight too); the body limit acts before CORS and the routes read anything."""
    if settings.cors_origins:  # off by default: only the service's own page calls it
        app.add_middleware(
            CORSMiddleware,
            allow_origins=list(settings.cors_origins),
            allow_methods=["GET", "POST", "PATCH"],
            allow_headers=["Authorization", "Content-Type", "X-API-Token"],
        )
    # POST /imports takes an S-57 cell too, as POST /buoys/imports (the register's) does: the routes hold other
    # files to max_body_bytes
    imports = max(settings.max_body_bytes, settings.max_chart_bytes)
    cells = {"/imports": imports, "/buoys/imports": imports}
    app.add_middleware(BodyLimitMiddleware, max_bytes=settings.max_body_bytes, path_limits=cells)
    # the pages of _install_docs (FastAPI's own are off: app.docs_url and app.redoc_url are None)
    docs = frozenset({DOCS_URL, OAUTH2_REDIRECT_URL, REDOC_URL})
    app.add_middleware(SecurityHeadersMiddleware, docs_paths=docs)


def _install_docs(app: FastAPI) -> None:
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


def create_app(settings: Settings | None = None, *, freeze_startup_heap: bool = False) -> FastAPI:
    """The service. Storage opens and the link starts with the app's lifespan, and close with it.

    `freeze_startup_heap` (the serving process: `gcs serve`): once started, what is alive (the modules, the
    planner's compiled kernels, the service) is moved out of the garbage collector's sight until the service
    stops. A full collection walked all of it, 70-90 ms holding the GIL, and under bench.gcs_bench's 50 reading
    clients one came every 0.3 s once the storage's calls hopped to threads (none before): every request and
    vehicle message in flight waited, and the read p99 went from 20-35 to 100-150 ms. Off in tests, which start
    many apps in one process."""
    settings = settings or Settings()

    @asynccontextmanager
    async def lifespan(app: FastAPI) -> AsyncIterator[None]:
        # first, before the links start: a cold compile holds the GIL for much of its time, and a link started
        # beside it could miss heartbeats
        log.info("planner kernels compiled or loaded in %.1f s", await warm_up_planner())
        storage = AsyncStorage(open_storage(settings.database))  # every query off the event loop
        key = None if settings.signing_key is None else parse_signing_key(settings.signing_key)
        hub = TransportHub()  # a fleet's vehicles on one connection (a router's) share its socket
        links = [
            LinkManager(url, settings.heartbeat_timeout_s, signing_key=key, sysid=sysid, transports=hub.open_transport)
            for sysid, url in settings.fleet
        ]
        # owner or stand-by: gcs.missions.ownership, by the settings
        service = MissionService(settings, storage, links[0], fleet=links[1:])
        app.state.service = service
        await service.start()
        if freeze_startup_heap:
            gc.collect()  # the start-up's garbage goes first: frozen, it would never be collected
            gc.freeze()
        try:
            yield
        finally:
            if freeze_startup_heap:
                gc.unfreeze()
            await service.stop()
            await storage.close()

    app = FastAPI(
        title="buoy-gcs",
        description="Mission service for UAV buoy inspection: plan (CHNN-GA), upload, fly, record, report.",
        version="0.1.0",
        lifespan=lifespan,
        generate_unique_id_function=_operation_id,
        docs_url=None,  # _install_docs serves both pages from the assets on this machine
        redoc_url=None,
    )
    app.state.settings = settings
    _install_middleware(app, settings)
    _install_error_handlers(app)
    _install_docs(app)
    for module in (plans, missions, inspections, buoy_files, buoys, vehicle, ais, live):
        app.include_router(module.router)

    index = settings.web_dir / "index.html"

    @app.get("/", include_in_schema=False)
    def page() -> FileResponse:
        return FileResponse(index)

    app.mount("/static/leaflet", StaticFiles(directory=leaflet.BASE_DIR), name="leaflet")
    app.mount("/web", StaticFiles(directory=settings.web_dir), name="web")
    return app
