"""Shared route dependencies."""

from __future__ import annotations

from fastapi import Request

from gcs.missions import MissionService


def get_service(request: Request) -> MissionService:
    return request.app.state.service
