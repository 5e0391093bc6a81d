"""Records and plans -> the REST contract's documents (pure)."""

from __future__ import annotations

from typing import Any

from gcs.planning import Plan
from gcs.storage import MissionRecord


def plan_out(plan: Plan) -> dict[str, Any]:
    return {
        "order": plan.order,
        "length_m": plan.length_m,
        "input_order_length_m": plan.input_order_length_m,
        "improvement_pct": plan.improvement_pct,
        "method": plan.method,
        "elapsed_s": plan.elapsed_s,
        "depot": {"lat": plan.depot[0], "lon": plan.depot[1]},
        "buoys": [
            {"index": i, "id": ident, "lat": ll[0], "lon": ll[1], "east_m": en[0], "north_m": en[1]}
            for i, (ident, ll, en) in enumerate(zip(plan.buoy_ids, plan.buoys_lat_lon, plan.buoys_local, strict=True))
        ],
        "route": plan.route_lat_lon(),
    }


def _buoy_results(record: MissionRecord, plan: Plan) -> list[dict[str, Any]]:
    if record.results is not None:
        return record.results["buoys"]
    reached_at = {int(k): v for k, v in (record.progress.get("reached_at") or {}).items()}
    return [
        {"index": i, "id": ident, "closest_m": None, "reached": i in reached_at, "arrival_s": reached_at.get(i)}
        for i, ident in enumerate(plan.buoy_ids)
    ]


def mission_out(record: MissionRecord) -> dict[str, Any]:
    plan = Plan.from_dict(record.plan)
    progress = {k: v for k, v in record.progress.items() if k != "reached_at"}
    progress.setdefault("buoys", len(plan.order))
    return {
        "id": record.id,
        "status": record.status,
        "reason": record.reason,
        "created_at": record.created_at,
        "updated_at": record.updated_at,
        **plan_out(plan),
        **record.flight,
        "progress": progress,
        "buoy_results": _buoy_results(record, plan),
        "tracking": record.results["tracking"] if record.results else None,
        "events": record.events,
    }


def mission_summary(record: MissionRecord) -> dict[str, Any]:
    return {
        "id": record.id,
        "status": record.status,
        "reason": record.reason,
        "created_at": record.created_at,
        "updated_at": record.updated_at,
        "buoys": len(record.plan["order"]),
        "length_m": record.plan["length_m"],
        "tracking": record.results["tracking"] if record.results else None,
    }
