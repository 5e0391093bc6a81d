"""POST /plans: plan only, nothing stored or flown."""

from __future__ import annotations

from fastapi import APIRouter, Depends

from gcs.api.routes.deps import ServiceDep
from gcs.api.routes.responses import WITH_BODY
from gcs.api.security import require_token
from gcs.domain.schemas import PlanOut, PlanRequest
from gcs.reports.views import plan_out

router = APIRouter(tags=["plans"])


@router.post("/plans", response_model=PlanOut, dependencies=[Depends(require_token)], responses=WITH_BODY)
async def create_plan(request: PlanRequest, service: ServiceDep) -> PlanOut:
    plan, _ = await service.plan(request)
    return plan_out(plan)
