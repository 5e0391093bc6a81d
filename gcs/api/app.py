"""The FastAPI application factory: wires settings, storage, link manager and mission service to the routes."""

from __future__ import annotations

import asyncio
import gc
import logging
import time
from collections.abc import AsyncIterator
from contextlib import asynccontextmanager

import xstatic.pkg.leaflet as leaflet
from fastapi import FastAPI
from fastapi.middleware.cors import CORSMiddleware
from fastapi.responses import FileResponse
from fastapi.routing import APIRoute
from fastapi.staticfiles import StaticFiles

from gcs.api.body_limit import BodyLimitMiddleware
from gcs.api.docs_pages import DOCS_PATHS, install_docs
from gcs.api.errors import install_error_handlers
from gcs.api.http_headers import SecurityHeadersMiddleware
from gcs.api.routes import ais, buoy_files, buoys, inspections, live, missions, plans, vehicle
from gcs.missions.service import MissionService
from gcs.settings import Settings
from gcs.storage import open_storage
from gcs.storage.off_loop import AsyncStorage
from gcs.vehicle.connection import TransportHub
from gcs.vehicle.link import LinkManager
from planner.warmup import warm_up
from uavcore.mavlink import parse_signing_key

log = logging.getLogger(__name__)


async def warm_up_planner() -> float:
    """Compile (or load from numba's cache) the planner's kernels, off the event loop; returns the seconds it took.

    Awaited in the lifespan before it yields, so uvicorn takes no request until it ends: otherwise the first plan
    of each kind compiles inside its request, whose time limit the compile does not see (a 2 s fleet plan answered
    after 56 s on a cold cache). With the cache on disk it only loads the compiled code."""
    started = time.perf_counter()
    await asyncio.to_thread(warm_up)
    return time.perf_counter() - started


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
    app.add_middleware(SecurityHeadersMiddleware, docs_paths=DOCS_PATHS)


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
        docs_url=None,  # gcs.api.docs_pages serves both pages from the assets on this machine
        redoc_url=None,
    )
    app.state.settings = settings
    _install_middleware(app, settings)
    install_error_handlers(app)
    install_docs(app)
    for module in (plans, missions, inspections, buoy_files, buoys, vehicle, ais, live):
        app.include_router(module.router)

    index = settings.web_dir / "index.html"

    @app.get("/", include_in_schema=False)
    def page() -> FileResponse:
        return FileResponse(index)

    app.mount("/static/leaflet", StaticFiles(directory=leaflet.BASE_DIR), name="leaflet")
    app.mount("/web", StaticFiles(directory=settings.web_dir), name="web")
    return app
