"""The error answers each route can give, declared once for the OpenAPI document (`responses=` on the routes).

Every error body lists its problems as FastAPI's 422 does, `{"detail": [{type, loc, msg}]}` (gcs.api.errors);
FastAPI declares 422 by itself on every route that takes a parameter or a body.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any, TypedDict

from fastapi import params
from pydantic import BaseModel, Field

# What a route's `responses=` takes (FastAPI's type): status code -> what OpenAPI says of that answer.
Responses = dict[int | str, dict[str, Any]]


class RouteOptions(TypedDict, total=False):
    """Decorator arguments several routes share (`@router.post(path, **OPTIONS)`): typed, so each is checked."""

    response_model: Any
    dependencies: Sequence[params.Depends]
    responses: Responses


class ProblemOut(BaseModel):
    type: str = Field(description="a stable code: not_found, conflict, unauthorized, too_large, unavailable, ...")
    loc: list[str | int] = Field(description="the part of the request it concerns ([]: the request as a whole)")
    msg: str = Field(description="what went wrong, in plain words")


class ErrorOut(BaseModel):
    detail: list[ProblemOut]


def _error(description: str, **extra: Any) -> dict[str, Any]:
    return {"model": ErrorOut, "description": description, **extra}


UNAUTHORIZED: Responses = {
    401: _error(
        "the service has an API token and the request did not carry it (Authorization: Bearer <token>)",
        headers={"WWW-Authenticate": {"required": True, "schema": {"type": "string", "const": "Bearer"}}},
    )
}
NOT_FOUND: Responses = {404: _error("no mission with this id")}
NO_BUOY: Responses = {404: _error("no buoy with this register id (or it has no such defect)")}
NO_VEHICLE: Responses = {404: _error("no vehicle with this system id")}
CONFLICT: Responses = {
    409: _error("another mission uses the vehicle, or this mission is not in a state that allows it")
}
VEHICLE_SILENT: Responses = {
    502: _error("the vehicle did not answer the command (it may or may not have acted on it: its mode says)")
}
TOO_LARGE: Responses = {413: _error("the request body is larger than the service's max_body_bytes")}
UNAVAILABLE: Responses = {
    503: _error(
        "this service is on stand-by: another instance owns the vehicle link (the detail names it)",
        headers={"Retry-After": {"required": True, "schema": {"type": "integer", "minimum": 1}}},
    )
}

MUTATING = UNAUTHORIZED | UNAVAILABLE  # every POST: the token, and the stand-by service that may not act
WITH_BODY = MUTATING | TOO_LARGE  # a POST that takes a body
