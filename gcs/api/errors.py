"""Every error answer in one shape: FastAPI's own for validation errors, `{"detail": [{type, loc, msg}]}`.

A 404, 409 or 503 says what went wrong the way a 422 does, so a client reads every 4xx and 5xx one way: each
problem's `msg` in plain words, its `loc` naming the part of the request it concerns (["path", "mission_id"],
["header", "Authorization"], ["body", "buoys", 3]; [] for the request as a whole) and its `type` a stable code
(`not_found`, `conflict`, `unavailable`, or pydantic's for a field that did not validate). FastAPI's shape rather
than RFC 9457's problem details: it was already every 422's, which clients and the map page read.
"""

from __future__ import annotations

import json
import math
from collections.abc import Mapping, Sequence

from fastapi import FastAPI, Request
from fastapi.exceptions import RequestValidationError
from fastapi.responses import JSONResponse
from starlette.exceptions import HTTPException as StarletteHTTPException

from gcs.domain.buoy_files import BuoyFileError
from gcs.missions.lifecycle import MissionConflictError, VehicleCommandError
from gcs.missions.ownership import NotOwnerError
from gcs.missions.register import BuoyNotFoundError
from gcs.missions.service import (
    FlightLogNotFoundError,
    FrameNotFoundError,
    MissionNotFoundError,
    VehicleNotFoundError,
)
from gcs.missions.validation import Location, RequestInvalidError
from planner.errors import PlannerError

# the `type` of an error answer's problems by its status (a 422's come from the validation)
ERROR_TYPES = {
    400: "bad_request",
    401: "unauthorized",
    404: "not_found",
    405: "method_not_allowed",
    409: "conflict",
    413: "too_large",
    500: "internal_error",
    502: "bad_gateway",
    503: "unavailable",
}


class ApiError(Exception):
    """An error answer a route gives: its status, and the part of the request it concerns."""

    def __init__(self, status: int, loc: Location, msg: str, headers: Mapping[str, str] | None = None) -> None:
        super().__init__(msg)
        self.status, self.loc, self.msg, self.headers = status, loc, msg, dict(headers or {})


def error_body(status: int, problems: Sequence[tuple[Location, str]], types: Sequence[str] | None = None) -> dict:
    """The document of an error answer: one entry per problem."""
    kinds = types or [ERROR_TYPES.get(status, "error")] * len(problems)
    pairs = zip(problems, kinds, strict=True)
    return {"detail": [{"type": kind, "loc": list(loc), "msg": msg} for (loc, msg), kind in pairs]}


def error_bytes(status: int, loc: Location, msg: str) -> bytes:
    """error_body encoded, for an answer sent below FastAPI (the body-limit middleware's 413)."""
    return json.dumps(error_body(status, [(loc, msg)])).encode()


def error_response(
    status: int,
    problems: Sequence[tuple[Location, str]],
    types: Sequence[str] | None = None,
    headers: Mapping[str, str] | None = None,
) -> JSONResponse:
    return JSONResponse(error_body(status, problems, types), status_code=status, headers=headers)


def install_error_handlers(app: FastAPI) -> None:
    """Each error the routes and services raise, answered in the one shape."""

    @app.exception_handler(RequestValidationError)
    async def invalid_request(_: Request, error: RequestValidationError) -> JSONResponse:
        # FastAPI's default echoes the input, which cannot be encoded when it is NaN or Infinity: a 500.
        problems = [(tuple(e["loc"]), e["msg"]) for e in error.errors()]
        return error_response(422, problems, [e["type"] for e in error.errors()])

    @app.exception_handler(StarletteHTTPException)
    async def http_error(_: Request, error: StarletteHTTPException) -> JSONResponse:
        # FastAPI's answer to a body it cannot decode (not UTF-8): bad input, a 422 as any other
        if error.status_code == 400:
            return error_response(422, [(("body",), "the body is not JSON in UTF-8")], ["json_invalid"])
        # a path no route has (404), a method the route has not (405), from Starlette's router and StaticFiles
        return error_response(error.status_code, [((), str(error.detail))], headers=error.headers)

    @app.exception_handler(ApiError)
    async def api_error(_: Request, error: ApiError) -> JSONResponse:
        return error_response(error.status, [(error.loc, error.msg)], headers=error.headers)

    @app.exception_handler(RequestInvalidError)
    async def request_invalid(_: Request, error: RequestInvalidError) -> JSONResponse:
        return error_response(422, error.errors, ["value_error"] * len(error.errors))

    @app.exception_handler(PlannerError)
    async def planner_error(_: Request, error: PlannerError) -> JSONResponse:
        return error_response(422, [(("body", "buoys"), str(error))], ["value_error"])

    @app.exception_handler(BuoyFileError)
    async def buoy_file_error(_: Request, error: BuoyFileError) -> JSONResponse:
        return error_response(422, [(("body",), str(error))], ["value_error"])

    @app.exception_handler(MissionNotFoundError)
    async def no_mission(_: Request, error: MissionNotFoundError) -> JSONResponse:
        return error_response(404, [(("path", "mission_id"), f"no mission {error.args[0]}")])

    @app.exception_handler(FrameNotFoundError)
    async def no_frame(_: Request, error: FrameNotFoundError) -> JSONResponse:
        return error_response(404, [(("path", "frame_id"), error.args[0])])

    @app.exception_handler(FlightLogNotFoundError)
    async def no_flight_log(_: Request, error: FlightLogNotFoundError) -> JSONResponse:
        return error_response(404, [(("path", "mission_id"), error.args[0])])

    @app.exception_handler(BuoyNotFoundError)
    async def no_buoy(_: Request, error: BuoyNotFoundError) -> JSONResponse:
        return error_response(404, [(("path", error.field), error.args[0])])

    @app.exception_handler(VehicleNotFoundError)
    async def no_vehicle(_: Request, error: VehicleNotFoundError) -> JSONResponse:
        return error_response(404, [(("path", "sysid"), f"no vehicle with system id {error.args[0]}")])

    @app.exception_handler(MissionConflictError)
    async def conflict(_: Request, error: MissionConflictError) -> JSONResponse:
        return error_response(409, [((), str(error))])

    @app.exception_handler(VehicleCommandError)
    async def vehicle_silent(_: Request, error: VehicleCommandError) -> JSONResponse:
        # the service is the vehicle's gateway: a vehicle that did not answer is a 502 (one that refused is a
        # 409, MissionConflictError: its answer says the present state does not allow it)
        return error_response(502, [((), str(error))])

    @app.exception_handler(NotOwnerError)
    async def standby(request: Request, error: NotOwnerError) -> JSONResponse:
        # a client may retry here (this instance takes over when the owner dies) or go to the owner
        retry_s = max(1, math.ceil(request.app.state.settings.lease_poll_s))
        return error_response(503, [((), str(error))], headers={"Retry-After": str(retry_s)})

    @app.exception_handler(Exception)
    async def internal_error(_: Request, __: Exception) -> JSONResponse:
        # Starlette's last resort (it re-raises the error to the server, which logs its traceback, after this
        # answer): the client gets the one shape, never a traceback
        return error_response(500, [((), "the service failed to answer this request; its log says why")])
