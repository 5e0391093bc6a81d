"""Records and plans -> the REST contract's documents (pure), and those documents encoded as the read routes
serve them (validated against the response model once, when the read cache builds them)."""

from __future__ import annotations

import json
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from datetime import UTC, datetime
from typing import Any

import numpy as np
from pydantic import TypeAdapter

from gcs.domain.inspection import InspectionRecord
from gcs.domain.listing import PageKey, encode_cursor
from gcs.domain.planning import Plan
from gcs.domain.records import MissionResults, PlannedShare, SortieFlown
from gcs.domain.schemas import (
    Buoy,
    BuoyResult,
    ChartedBuoyOut,
    EnergyOut,
    FleetOut,
    FleetPlanOut,
    FleetShareOut,
    InspectionOut,
    LatLon,
    MissionOut,
    MissionSummary,
    PlannedShareOut,
    PlanOut,
    SeparationOut,
    SortieOut,
    TrackOut,
)
from gcs.domain.status import MissionStatus
from gcs.reports import track_display
from gcs.storage import MissionRecord

MISSION_SUMMARIES = TypeAdapter(list[MissionSummary])
TELEMETRY_CHUNK = 1000  # samples encoded at a time when streaming a mission's telemetry
CHART_SAMPLES = 1000  # the most samples a track sends for the charts (a few hundred pixels wide each)


def _buoy_out(plan: Plan, index: int, ident: str, lat_lon: list[float], local: list[float]) -> Buoy:
    mark = plan.mark(index)
    charted = None if mark.charted_lat_lon is None else LatLon(lat=mark.charted_lat_lon[0], lon=mark.charted_lat_lon[1])
    return Buoy(index=index, id=ident, lat=lat_lon[0], lon=lat_lon[1], east_m=local[0], north_m=local[1],
                register_id=mark.register_id, charted=charted)  # fmt: skip


def plan_out(plan: Plan) -> PlanOut:
    return PlanOut(
        order=plan.order,
        length_m=plan.length_m,
        input_order_length_m=plan.input_order_length_m,
        improvement_pct=plan.improvement_pct,
        method=plan.method,
        elapsed_s=plan.elapsed_s,
        depot=LatLon(lat=plan.depot[0], lon=plan.depot[1]),
        buoys=[
            _buoy_out(plan, i, ident, ll, en)
            for i, (ident, ll, en) in enumerate(zip(plan.buoy_ids, plan.buoys_lat_lon, plan.buoys_local, strict=True))
        ],
        route=plan.route_lat_lon(),
        sorties=sorties_out(plan),
        energy=None if plan.energy is None else EnergyOut.model_validate(plan.energy.model_dump(exclude={"sorties"})),
        fleet=fleet_plan_out(plan),
    )


def sorties_out(plan: Plan, flown: list[SortieFlown] | None = None) -> list[SortieOut]:
    """Each sortie as planned (with its prediction when the plan has an energy section) and, for the sorties
    flown (`flown`, the recorder's per-sortie battery figures in the mission's progress), as measured."""
    predicted = plan.energy.sorties if plan.energy else []
    measured = {entry.sortie: entry for entry in flown or []}
    out = []
    for k in range(len(plan.sortie_orders())):
        sortie = plan.sortie_plan(k)
        prediction = predicted[k] if k < len(predicted) else None
        flight = measured.get(k)
        out.append(
            SortieOut(
                index=k,
                order=sortie.order,
                route=sortie.route_lat_lon(),
                length_m=sortie.length_m,
                predicted_energy_wh=prediction and prediction.energy_wh,
                predicted_time_s=prediction and prediction.time_s,
                margin_wh=prediction and prediction.margin_wh,
                margin_pct=prediction and prediction.margin_pct,
                predicted_landing_charge_pct=prediction and prediction.landing_charge_pct,
                used_energy_wh=flight and flight.used_energy_wh,
                landing_charge_pct=flight and flight.landing_charge_pct,
                battery_warning=flight and flight.battery_warning,
            )
        )
    return out


def _buoy_results(record: MissionRecord) -> list[BuoyResult]:
    """Each buoy's closest approach and arrival, with when the service heard it reached (wall clock)."""
    heard = record.progress.reached_wall_at

    def at(index: int) -> datetime | None:
        return datetime.fromtimestamp(heard[index], UTC) if index in heard else None

    return [b.model_copy(update={"arrival_at": at(b.index)}) for b in _buoy_figures(record)]


def _buoy_figures(record: MissionRecord) -> list[BuoyResult]:
    if record.results is not None and record.results.buoys is not None:
        return record.results.buoys
    ids = record.plan.buoy_ids
    if record.is_fleet:  # each part mission has the closest approaches and arrival times of its own buoys
        visited = set(record.progress.visited_buoys)
        return [
            BuoyResult(index=i, id=ident, closest_m=None, reached=i in visited, arrival_s=None)
            for i, ident in enumerate(ids)
        ]
    reached_at = record.progress.reached_at
    return [
        BuoyResult(index=i, id=ident, closest_m=None, reached=i in reached_at, arrival_s=reached_at.get(i))
        for i, ident in enumerate(ids)
    ]


def _heading(record: MissionRecord) -> dict[str, Any]:
    """What a mission's document and its summary in the list both begin with."""
    return {
        "id": record.id,
        "status": record.status,
        "reason": record.reason,
        "created_at": record.created_at,
        "updated_at": record.updated_at,
        "vehicle_sysid": record.vehicle_sysid,
        "kind": record.kind,
        "fleet_id": record.part_of,
    }


def mission_out(record: MissionRecord) -> MissionOut:
    plan = record.plan
    progress = record.progress.shown()
    if "buoys" not in record.progress.model_fields_set:  # stored before the recorder's first report
        progress.buoys = len(plan.order)
    if "sorties" not in record.progress.model_fields_set:
        progress.sorties = len(plan.sortie_orders())
    planned = dict(plan_out(plan))  # PlanOut's fields as they are (models, not dumped)
    # a fleet mission's shares as planned and as flown (FleetOut) in place of the plan's (FleetPlanOut)
    planned["fleet"] = fleet = fleet_out(record) if record.is_fleet else None
    if fleet:  # flown as its shares (FleetShareOut, each with its route): no tour or sortie of its own
        planned |= {"route": [], "sorties": []}
    else:
        planned["sorties"] = sorties_out(plan, record.progress.sorties_flown)
    return MissionOut(
        **_heading(record),
        **planned,
        altitude_m=record.flight.altitude_m,
        speed_m_s=record.flight.speed_m_s,
        dwell_s=record.flight.dwell_s,
        acceptance_radius_m=record.flight.acceptance_radius_m,
        progress=progress,
        buoy_results=_buoy_results(record),
        tracking=record.results.tracking if record.results else None,
        events=record.events,
    )


def planned_share_out(plan: Plan, share: PlannedShare) -> PlannedShareOut:
    """A vehicle's share as planned, with its route from its home through its buoys (`plan`: the fleet's)."""
    return PlannedShareOut(
        sysid=share.sysid,
        buoys=share.buoys,
        altitude_m=share.altitude_m,
        predicted_time_s=share.predicted_time_s,
        length_m=share.length_m,
        route=[share.home, *(plan.buoys_lat_lon[b] for b in share.buoys), share.home],
        start_s=share.start_s,
        depart_after=share.depart_after,
        final_hold_s=share.final_hold_s,
    )


def fleet_plan_out(plan: Plan) -> FleetPlanOut | None:
    """A fleet plan's section as POST /plans answers it (null: not a fleet plan)."""
    fleet = plan.fleet
    if fleet is None:
        return None
    return FleetPlanOut(
        makespan_s=fleet.makespan_s,
        total_time_s=fleet.total_time_s,
        layer_gap_m=fleet.layer_gap_m,
        separation_m=fleet.separation_m,
        shares=[planned_share_out(plan, share) for share in fleet.shares],
    )


def fleet_out(record: MissionRecord) -> FleetOut:
    """A fleet mission's shares as planned and as flown so far (its progress, kept by gcs.missions.fleet_missions), who
    inspected what and the separation (once it has ended)."""
    plan = record.plan
    fleet = plan.fleet
    assert fleet is not None  # asked only of a fleet mission, whose plan has its fleet section
    flown = {s.sysid: s for s in record.progress.shares}
    shares = []
    for share in fleet.shares:
        state = flown.get(share.sysid)
        shares.append(
            FleetShareOut(
                **planned_share_out(plan, share).model_dump(),
                mission_id=state.mission_id if state else 0,
                status=state.status if state else MissionStatus.PLANNED,
                visited_buoys=state.visited if state else [],
                lost=share.lost,
                handed_over=share.handed_over,
                started_t_s=share.started_t_s,
                ahead_t_s=share.ahead_t_s,
            )
        )
    results = record.results or MissionResults()
    return FleetOut(
        makespan_s=fleet.makespan_s,
        total_time_s=fleet.total_time_s,
        layer_gap_m=fleet.layer_gap_m,
        separation_m=fleet.separation_m,
        shares=shares,
        inspected_by=results.inspected_by,
        separation=results.separation or SeparationOut(min_horizontal_m=None, min_vertical_m=None, min_distance_m=None),
    )


def mission_summary(record: MissionRecord) -> MissionSummary:
    return MissionSummary(
        **_heading(record),
        buoys=len(record.plan.order),
        length_m=record.plan.length_m,
        tracking=record.results.tracking if record.results else None,
    )


def track_out(
    record: MissionRecord,
    columns: list[tuple[float, float | None, float | None, float | None]],
    samples_at: Callable[[list[float]], list[dict[str, Any]]],
    max_points: int,
) -> dict[str, Any]:
    """The flown track for display, from every sample's (t_s, lat, lon, cross_track_m): at most `max_points`
    positions (more only if the buoy arrivals alone exceed them) within `tolerance_m` of every recorded one, and
    at most as many whole samples (CHART_SAMPLES at most, read by `samples_at(times)`) for the charts."""
    table = np.array(columns, dtype=float).reshape(-1, 4)  # None -> NaN
    times, cross_track = table[:, 0], table[:, 3]
    located = ~np.isnan(table[:, 1]) & ~np.isnan(table[:, 2])
    lat_lon = table[located][:, 1:3]
    arrivals = record.progress.reached_at.values()
    local = record.plan.frame.project(lat_lon) if len(lat_lon) else lat_lon
    track = track_display.simplify_track(local, max_points, track_display.arrival_indices(times[located], arrivals))
    # the charts' series keeps the cross-track error's envelope (the figure the mission is judged by)
    charted = track_display.extremes_per_bucket(cross_track, min(max_points, CHART_SAMPLES))
    return {
        "mission": record.id,
        "samples": len(table),
        "tolerance_m": track.tolerance_m,
        "points": lat_lon[track.indices].tolist(),
        "series": samples_at([float(times[i]) for i in charted]),
    }


# ----- encoded as served: the response model validates the document once, when the read cache builds it
def mission_json(record: MissionRecord) -> bytes:
    return mission_out(record).model_dump_json().encode()


@dataclass(frozen=True)
class MissionsPage:
    """A page of GET /missions as served: the MissionSummary list encoded, and the cursor of the next page (None:
    this is the last)."""

    body: bytes
    next_cursor: str | None

    def __len__(self) -> int:
        return len(self.body)  # what the read cache counts against its byte budget


def missions_page(records: list[MissionRecord], limit: int) -> MissionsPage:
    """The page of the first `limit` of `records`; `records` holds one more when another page follows (its
    cursor: the page's last mission's key, gcs.domain.listing)."""
    shown = records[:limit]
    last = shown[-1] if len(records) > limit else None
    body = MISSION_SUMMARIES.dump_json([mission_summary(r) for r in shown])
    return MissionsPage(body, None if last is None else encode_cursor(PageKey(last.created_at, last.id)))


def track_json(
    record: MissionRecord,
    columns: list[tuple[float, float | None, float | None, float | None]],
    samples_at: Callable[[list[float]], list[dict[str, Any]]],
    max_points: int,
) -> bytes:
    return TrackOut.model_validate(track_out(record, columns, samples_at, max_points)).model_dump_json().encode()


def telemetry_chunks(samples: list[dict[str, Any]]) -> Iterator[bytes]:
    """GET /missions/{id}/telemetry as a JSON array, encoded TELEMETRY_CHUNK samples at a time. The samples are
    stored as TelemetrySample documents (the recorder builds them with the model), so they are sent as they are:
    validating and encoding 72 000 of them in one pydantic call held the GIL for about a second, during which
    the event loop, and every other request, stood still."""
    yield b"["
    for start in range(0, len(samples), TELEMETRY_CHUNK):
        chunk = json.dumps(samples[start : start + TELEMETRY_CHUNK], separators=(",", ":"), allow_nan=False)
        yield (b"," if start else b"") + chunk[1:-1].encode()
    yield b"]"


def frame_url(mission_id: int, frame_id: int) -> str:
    return f"/missions/{mission_id}/frames/{frame_id}"


def inspection_out(mission_id: int, record: InspectionRecord) -> InspectionOut:
    """A stored inspection record as the API shows it; `mission_id`: the mission holding its frames (a fleet
    mission's record, re-indexed to the fleet's buoys by gather_fleet_inspections: its part's)."""
    result = record.result
    return InspectionOut(
        buoy=record.buoy_id,
        index=record.buoy,
        verdict=result.verdict,
        findings=[finding.model_dump() for finding in result.findings],
        observed=None if result.observed is None else LatLon(lat=result.observed.lat, lon=result.observed.lon),
        offset_m=result.offset_m,
        light_seen=result.light_seen,
        charted=ChartedBuoyOut.model_validate(result.buoy.model_dump()),
        frames=[frame_url(mission_id, frame_id) for frame_id in record.frame_ids],
        best_frame=None if record.best_frame is None else frame_url(mission_id, record.best_frame),
        reason=result.reason,
        target=None if result.target is None else LatLon(lat=result.target.lat, lon=result.target.lon),
        offset_from_target_m=result.offset_from_target_m,
    )
