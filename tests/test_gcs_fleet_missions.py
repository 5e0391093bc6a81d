"""Following a fleet mission (gcs.missions.fleet_missions), the pure parts: the separation's minima, the fleet mission's
progress from its parts', and how it ends."""

from __future__ import annotations

import dataclasses
import json
import math
from pathlib import Path

import pytest
from stored_missions import FLIGHT, PLAN

from gcs.domain.records import MissionProgress, PlanFleet, PlannedShare
from gcs.domain.schemas import MissionRequest
from gcs.domain.status import MissionStatus
from gcs.missions.fleet_missions import Separation, fleet_ending, fleet_vehicles, shares_progress
from gcs.missions.validation import RequestInvalidError
from gcs.settings import Limits
from gcs.storage import MissionRecord

REPO = Path(__file__).resolve().parents[1]


def test_each_minimum_is_taken_on_its_own_over_every_pair_and_instant():
    separation = Separation()
    assert separation.min_distance_m is None
    separation.fold({1: (0.0, 0.0, 5.0), 2: (30.0, 40.0, 8.0), 3: (0.0, 100.0, 11.0)})
    assert separation.min_horizontal_m == pytest.approx(50.0)  # 1-2
    assert separation.min_vertical_m == pytest.approx(3.0)  # 1-2 and 2-3
    assert separation.min_distance_m == pytest.approx(math.hypot(50.0, 3.0))
    separation.fold({1: (0.0, 0.0, 5.0), 2: (3.0, 0.0, 5.0)})  # later: side by side at one height
    assert (separation.min_horizontal_m, separation.min_vertical_m) == (pytest.approx(3.0), 0.0)


def _record(mission_id: int, status: str, visited: list[int], reason: str | None = None, sysid=None):
    plan = FLEET_PLAN if sysid is None else PLAN
    progress = MissionProgress(visited_buoys=visited)
    return MissionRecord(
        mission_id, "t", "t", MissionStatus(status), reason, FLIGHT, plan, progress, None, vehicle_sysid=sysid,
        fleet_id=1,
    )  # fmt: skip


def _share(sysid: int, buoys: list[int]) -> PlannedShare:
    return PlannedShare(
        sysid=sysid, home=[55.0, 12.0], buoys=buoys, altitude_m=5.0, predicted_time_s=60.0, length_m=1.0
    )


FLEET_PLAN = dataclasses.replace(
    PLAN,
    buoy_ids=["A", "B", "C", "D"],
    fleet=PlanFleet(
        makespan_s=60.0, total_time_s=120.0, layer_gap_m=3.0, shares=[_share(1, [2, 0]), _share(2, [3, 1])]
    ),
)


def test_the_fleet_progress_maps_each_parts_visits_to_the_fleets_buoys_and_its_end_names_what_was_missed():
    fleet = _record(1, "flying", [])
    parts = [
        _record(2, "completed", [0, 1], sysid=1),
        _record(3, "failed", [0], "link lost: no heartbeat from the vehicle", sysid=2),
    ]
    progress = shares_progress(fleet, parts)
    assert [s.visited for s in progress.shares] == [[2, 0], [3]]
    assert progress.visited_buoys == [0, 2, 3] and progress.visited == 3 and progress.buoys == 4
    status, reason = fleet_ending(fleet, parts)
    assert status == MissionStatus.FAILED
    assert reason == "vehicle 2 failed (link lost: no heartbeat from the vehicle); not inspected: B"
    parts[1] = _record(3, "failed", [0, 1], "link lost", sysid=2)
    assert fleet_ending(fleet, parts) == (MissionStatus.COMPLETED, None)  # lost, but every buoy inspected
    parts[1] = _record(3, "aborted", [0, 1], "aborted by the operator", sysid=2)
    assert fleet_ending(fleet, parts)[0] == MissionStatus.ABORTED
    parts[1] = _record(3, "completed", [0, 1], sysid=2)
    assert fleet_ending(fleet, parts) == (MissionStatus.COMPLETED, None)
    # its battery failsafe brought vehicle 2 down: lost as by a link loss, not aborted by the operator
    parts[1] = _record(3, "aborted", [0], "battery failsafe (Critical battery level!): ...", sysid=2)
    assert fleet_ending(fleet, parts) == (
        MissionStatus.FAILED,
        "vehicle 2 aborted (battery failsafe (Critical battery level!): ...); not inspected: B",
    )
    parts[1] = _record(3, "aborted", [0, 1], "battery failsafe (Critical battery level!): ...", sysid=2)
    assert fleet_ending(fleet, parts) == (MissionStatus.COMPLETED, None)  # its buoys inspected by the others


def test_a_fleet_request_names_known_vehicles_once_and_keeps_its_layers_within_the_airframe():
    buoys = [{"lat": 1.0, "lon": 1.0}]
    assert fleet_vehicles(MissionRequest(buoys=buoys, vehicles="fleet"), [1, 2, 3], Limits()) == [1, 2, 3]
    assert fleet_vehicles(MissionRequest(buoys=buoys, vehicles=[3, 1]), [1, 2, 3], Limits()) == [3, 1]
    request = MissionRequest(buoys=buoys, vehicles=[1, 1, 9], vehicle=2, altitude_m=110.0, layer_gap_m=10.0)
    with pytest.raises(RequestInvalidError) as refused:
        fleet_vehicles(request, [1, 2], Limits())
    assert [loc for loc, _ in refused.value.errors] == [
        ("body", "vehicle"),
        ("body", "vehicles", 1),
        ("body", "vehicles", 2),
        ("body", "layer_gap_m"),
    ]


@pytest.mark.parametrize("example", ["reference_fleet_mission.json", "reference_buoys.geojson"])
def test_the_example_files_make_a_fleet_request_the_fleet_takes(example):
    """The fleet example (the reference buoys, `vehicles: fleet`, no depot) and the example GeoJSON as a fleet's
    buoys (its depot feature is not the fleet's: the vehicles fly from their homes) are fleet requests it flies."""
    document = json.loads((REPO / "examples" / example).read_text())
    body = document if "vehicles" in document else {"buoys": document, "vehicles": "fleet"}
    request = MissionRequest.model_validate(body)
    assert (len(request.buoys), request.depot) == (13, None)
    assert fleet_vehicles(request, [1, 2, 3], Limits()) == [1, 2, 3]
