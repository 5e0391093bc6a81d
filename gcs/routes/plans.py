"""POST /plans: plan only, nothing stored or flown."""

from __future__ import annotations

import asyncio
from typing import Annotated

from fastapi import APIRouter, Depends

from gcs.missions import MissionService
from gcs.routes.deps import get_service
from gcs.schemas import PlanOut, PlanRequest
from gcs.security import require_token
from gcs.views import plan_out

router = APIRouter(tags=["plans"])


@router.post("/plans", response_model=PlanOut, dependencies=[Depends(require_token)])
async def create_plan(request: PlanRequest, service: Annotated[MissionService, Depends(get_service)]) -> dict:
    plan, _ = await asyncio.to_thread(service.plan, request)
    return plan_out(plan)
