"""Following a fleet mission (gcs.missions.fleet_missions), the pure parts: the separation's minima, the fleet mission's
progress from its parts', and how it ends."""

from __future__ import annotations

import dataclasses
import json
import math
import types
from pathlib import Path

import pytest
from pydantic import ValidationError
from stored_missions import FLIGHT, PLAN

from gcs.domain.planning import mission_items
from gcs.domain.records import MissionProgress, PlanFleet, PlannedShare
from gcs.domain.schemas import MissionRequest
from gcs.domain.status import MissionStatus
from gcs.missions.fleet_missions import Separation, fleet_ending, fleet_vehicles, may_depart, shares_progress
from gcs.missions.validation import RequestInvalidError
from gcs.settings import Limits
from gcs.storage import MissionRecord
from uavcore.geodesy import LocalFrame
from uavcore.mission import MavCmd

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


def _turns_plan(zone_centre: list[float]) -> object:
    shares = [
        _share(1, [2, 0]),
        PlannedShare(
            sysid=2, home=[55.0, 12.0], buoys=[3, 1], altitude_m=8.0, predicted_time_s=60.0, length_m=1.0,
            start_s=12.0, depart_after=1, zone_centre=zone_centre, zone_radius_m=8.0,
        ),
    ]  # fmt: skip
    fleet = PlanFleet(makespan_s=72.0, total_time_s=120.0, layer_gap_m=3.0, separation_m=5.0, shares=shares)
    return dataclasses.replace(PLAN, buoy_ids=["A", "B", "C", "D"], fleet=fleet)


def test_a_vehicle_takes_off_once_the_one_before_it_has_left_the_depot_zone():
    centre = (55.0, 12.0)
    frame = LocalFrame(*centre, 0.0)
    fleet = dataclasses.replace(_record(1, "flying", []), plan=_turns_plan(list(centre)))
    where: dict[int, tuple[float | None, float | None]] = {1: (None, None)}

    def link_of(sysid: int):
        lat, lon = where[sysid]
        return types.SimpleNamespace(status=types.SimpleNamespace(lat=lat, lon=lon))

    def parts(first: str) -> list[MissionRecord]:
        return [_record(2, first, [], sysid=1), _record(3, "planned", [], sysid=2)]

    assert may_depart(fleet, parts("planned")[0], parts("planned"), link_of)  # the first waits for nobody
    assert not may_depart(fleet, parts("planned")[1], parts("planned"), link_of)  # the one before not started
    assert not may_depart(fleet, parts("flying")[1], parts("flying"), link_of)  # flying, position not heard
    for north, leaves in ((0.0, False), (7.9, False), (8.1, True), (-30.0, True)):
        lat, lon, _ = frame.from_ned(north, 0.0, 0.0)
        where[1] = (float(lat), float(lon))
        assert may_depart(fleet, parts("flying")[1], parts("flying"), link_of) is leaves, north
    where[1] = tuple(map(float, frame.from_ned(0.0, 0.0, 0.0)[:2]))
    assert may_depart(fleet, parts("failed")[1], parts("failed"), link_of)  # the one before ended: nobody to wait for


def test_a_final_hold_lengthens_the_last_buoys_hold_only():
    items = mission_items(PLAN, dataclasses.replace(FLIGHT, final_hold_s=7.5))
    waypoints = [item for item in items if item.command == MavCmd.NAV_WAYPOINT]
    plain = [item for item in mission_items(PLAN, FLIGHT) if item.command == MavCmd.NAV_WAYPOINT]
    assert [w.param1 for w in waypoints[:-1]] == [w.param1 for w in plain[:-1]]
    assert waypoints[-1].param1 == pytest.approx(plain[-1].param1 + 7.5)


@pytest.mark.parametrize("value", [0.5, 150.0, "far"])
def test_the_separation_is_a_distance_within_bounds_named_when_refused(value):
    with pytest.raises(ValidationError) as refused:
        MissionRequest(buoys=[{"lat": 1.0, "lon": 1.0}], vehicles="fleet", separation_m=value)
    assert [error["loc"] for error in refused.value.errors()] == [("separation_m",)]
    assert MissionRequest(buoys=[{"lat": 1.0, "lon": 1.0}], vehicles="fleet").separation_m == 5.0
