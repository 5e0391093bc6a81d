"""A fleet mission within a battery and a geofence (gcs.missions.fleet_shares), without vehicles: every share in
sorties that fit its vehicle's pack, a buoy its vehicle cannot serve moved to one that can, a buoy nobody can serve
a 422 naming it, each share routed around the fence; and the fleet request's geofence, rally points and battery
checked at POST /plans, 422 naming the field."""

from __future__ import annotations

import dataclasses
import itertools

import numpy as np
import pytest
from fastapi.testclient import TestClient

from bench.processes import free_udp_port
from gcs.api.app import create_app
from gcs.domain.planning import FlightParams
from gcs.domain.schemas import MissionRequest, PlannerOptions
from gcs.missions.energy_planning import battery_plan, budget
from gcs.missions.fleet_planning import FleetMissionPlan, plan_fleet_mission
from gcs.missions.fleet_shares import constrained_fleet_plan
from gcs.missions.validation import RequestInvalidError, fence_from_request
from gcs.settings import Settings
from gcs.storage import open_storage
from planner.energy import EnergyModel
from uavcore.geodesy import DEFAULT_HOME, LocalFrame
from uavcore.geofence import CircleZone, Geofence, PolygonZone
from uavcore.mission import MavFrame, MissionType, rally_point_items

FRAME = LocalFrame(*DEFAULT_HOME)
MODEL = EnergyModel.load()
FLIGHT = FlightParams(altitude_m=5.0, speed_m_s=10.0, dwell_s=5.0, acceptance_radius_m=2.0, inspect=False)
OPTIONS = PlannerOptions(time_limit_s=1.0)


def lat_lon(north: float, east: float) -> tuple[float, float]:
    lat, lon, _ = FRAME.from_ned(north, east, 0.0)
    return float(lat), float(lon)


HOMES = {1: lat_lon(0.0, 0.0), 2: lat_lon(0.0, 160.0)}
BUOYS = [lat_lon(n, e) for n in (60.0, 140.0) for e in (0.0, 80.0, 160.0)]
IDS = [f"B{i + 1}" for i in range(len(BUOYS))]
NO_FENCES: dict = {1: None, 2: None}


def _batteries(capacity_mah: float) -> dict:
    request = MissionRequest(buoys=[{"lat": a, "lon": b} for a, b in BUOYS], battery={"capacity_mah": capacity_mah})
    return {sysid: battery_plan(request, None, MODEL) for sysid in HOMES}


def _planned() -> FleetMissionPlan:
    return plan_fleet_mission(HOMES, BUOYS, IDS, 5.0, 3.0, FLIGHT.speed_m_s, FLIGHT.dwell_s, time_limit_s=0.5)


def test_each_share_flies_in_sorties_that_fit_its_vehicles_battery():
    batteries = _batteries(350.0)  # 4.4 Wh a sortie: three of these buoys are more than one battery
    fleet = constrained_fleet_plan(_planned(), HOMES, BUOYS, IDS, FLIGHT, NO_FENCES, batteries, OPTIONS, MODEL)
    assert sorted(b for share in fleet.shares for b in share.buoys) == list(range(len(BUOYS)))
    allowed = budget(batteries[1], MODEL)["budget_wh"]
    for share in fleet.shares:
        plan = share.plan
        assert plan.energy is not None and plan.depot == pytest.approx(HOMES[share.sysid])
        assert plan.buoy_ids == [IDS[b] for b in share.buoys]  # the part's buoy i is the share's buoy i
        assert plan.order == list(range(len(share.buoys)))  # in flying order, sortie after sortie
        assert all(sortie.energy_wh <= allowed for sortie in plan.energy.sorties)
        assert share.predicted_time_s == pytest.approx(sum(s.time_s for s in plan.energy.sorties))
    assert max(len(share.plan.sortie_orders()) for share in fleet.shares) >= 2
    assert fleet.makespan_s == pytest.approx(max(share.predicted_time_s for share in fleet.shares))


def test_a_buoy_its_vehicle_cannot_serve_goes_to_one_that_can_and_one_nobody_can_is_named():
    far = lat_lon(0.0, 330.0)  # 170 m east of vehicle 2's home, 330 m from vehicle 1's
    buoys, ids = [*BUOYS, far], [*IDS, "far"]
    batteries = _batteries(350.0)
    planned = _planned()
    # as if the time-based sharing had given the far buoy to vehicle 1, which cannot fly there and back on a pack
    first = planned.shares[0]
    assert first.sysid == 1
    shares = [dataclasses.replace(first, buoys=[*first.buoys, 6]), *planned.shares[1:]]
    moved = constrained_fleet_plan(
        dataclasses.replace(planned, shares=shares), HOMES, buoys, ids, FLIGHT, NO_FENCES, batteries, OPTIONS, MODEL
    )
    by_vehicle = {share.sysid: share.buoys for share in moved.shares}
    assert 6 in by_vehicle[2] and 6 not in by_vehicle.get(1, [])
    with pytest.raises(RequestInvalidError) as refused:
        constrained_fleet_plan(
            dataclasses.replace(planned, shares=shares), HOMES, buoys, ids, FLIGHT, NO_FENCES, _batteries(120.0),
            OPTIONS, MODEL,
        )  # fmt: skip
    located = {loc: message for loc, message in refused.value.errors}
    assert ("body", "buoys", 6) in located and located[("body", "buoys", 6)].startswith("buoy far cannot be reached")


def test_each_share_is_routed_around_the_fence_from_its_home():
    # an exclusion square on the straight way between the two rows of buoys' middle column
    zones = [{"kind": "polygon", "inclusion": False, "vertices": [dict(zip(("lat", "lon"), lat_lon(n, e),
             strict=True)) for n, e in ((90.0, 60.0), (110.0, 60.0), (110.0, 100.0), (90.0, 100.0))]}]  # fmt: skip
    request = MissionRequest(buoys=[{"lat": a, "lon": b} for a, b in BUOYS], geofence=zones)
    assert request.geofence is not None
    fence = fence_from_request(request.geofence)
    fleet = constrained_fleet_plan(_planned(), HOMES, BUOYS, IDS, FLIGHT, {1: fence, 2: fence}, None, OPTIONS, MODEL)
    assert sorted(b for share in fleet.shares for b in share.buoys) == list(range(len(BUOYS)))
    for share in fleet.shares:
        route = [tuple(point) for point in share.plan.route_lat_lon()]
        assert all(fence.segment_violation(a, b) is None for a, b in itertools.pairwise(route)), share.sysid
        assert share.plan.buoy_ids == [IDS[b] for b in share.buoys]


def test_without_a_request_fence_each_vehicles_own_fence_keeps_its_share_and_one_outside_every_fence_is_named():
    """The fences the vehicles hold (a fleet request without `geofence`, as a single mission): vehicle 1 holds an
    inclusion circle around its home that leaves out the buoys on vehicle 2's side, vehicle 2 none."""
    own = {1: Geofence((CircleZone(HOMES[1], 120.0, True),)), 2: None}
    planned = _planned()
    # as if the sharing had given vehicle 1 every buoy: those outside its circle go to vehicle 2
    everything = [dataclasses.replace(planned.shares[0], sysid=1, buoys=list(range(len(BUOYS))))]
    fleet = constrained_fleet_plan(dataclasses.replace(planned, shares=everything), HOMES, BUOYS, IDS, FLIGHT, own,
                                   None, OPTIONS, MODEL)  # fmt: skip
    by_vehicle = {share.sysid: sorted(share.buoys) for share in fleet.shares}
    circle = own[1].zones[0]
    assert by_vehicle[1] == [j for j, (lat, lon) in enumerate(BUOYS) if own[1].contains(lat, lon)] != []
    assert sorted(by_vehicle[1] + by_vehicle[2]) == list(range(len(BUOYS)))
    first = next(share for share in fleet.shares if share.sysid == 1)
    route = [tuple(point) for point in first.plan.route_lat_lon()]
    assert all(own[1].segment_violation(a, b) is None for a, b in itertools.pairwise(route)), circle
    both = {1: own[1], 2: Geofence((CircleZone(HOMES[2], 120.0, True),))}
    with pytest.raises(RequestInvalidError) as refused:
        constrained_fleet_plan(dataclasses.replace(planned, shares=everything), HOMES, BUOYS, IDS, FLIGHT, both,
                               None, OPTIONS, MODEL)  # fmt: skip
    outside = [j for j, (lat, lon) in enumerate(BUOYS) if not any(f.contains(lat, lon) for f in both.values())]
    assert outside and [loc for loc, _ in refused.value.errors] == [("body", "buoys", j) for j in outside]
    assert all(message.endswith("is outside the geofence of every vehicle") for _, message in refused.value.errors)


def test_a_fence_and_rally_points_become_the_lists_the_vehicle_reads_back():
    fence = Geofence(
        (PolygonZone((lat_lon(-50, -50), lat_lon(-50, 250), lat_lon(250, 250), lat_lon(250, -50)), True),
         CircleZone(lat_lon(100, 80), 15.0, False)),
        return_point=lat_lon(0, 0),
    )  # fmt: skip
    items = fence.to_items()
    assert [item.seq for item in items] == list(range(6)) and {i.mission_type for i in items} == {MissionType.FENCE}
    assert [item.param1 for item in items[:4]] == [4.0] * 4 and items[4].param1 == 15.0
    again = Geofence.from_items(items)
    assert [z.inclusion for z in again.zones] == [True, False]
    assert np.allclose(again.zones[0].vertices, fence.zones[0].vertices, rtol=0, atol=1e-7)
    assert again.return_point == pytest.approx(fence.return_point, abs=1e-7)
    (rally,) = rally_point_items([(*lat_lon(10, 10), 20.0)])
    assert (rally.frame, rally.z, rally.mission_type) == (MavFrame.GLOBAL_RELATIVE_ALT_INT, 20.0, MissionType.RALLY)


# ----- the request, at POST /plans: a fleet of two vehicles the service knows by system id (not flying here)
@pytest.fixture
def client(tmp_path):
    links = [f"{sysid}=udpout:127.0.0.1:{free_udp_port()}" for sysid in (1, 2)]
    with TestClient(create_app(Settings(data_dir=tmp_path, vehicles=links))) as test_client:
        yield test_client


def _point(north: float, east: float) -> dict:
    return dict(zip(("lat", "lon"), lat_lon(north, east), strict=True))


FENCE = [{"kind": "polygon", "inclusion": True, "vertices": [_point(-50, -50), _point(-50, 250), _point(250, 250),
         _point(250, -50)]}]  # fmt: skip
BODY = {"vehicles": "fleet", "buoys": [_point(n, e) for n, e in ((60, 0), (60, 80), (140, 160))], "inspect": False}


def test_a_fleet_with_a_fence_and_a_rally_point_inside_it_is_planned_inside_the_fence(client):
    rally = [{**_point(200, 0), "alt_m": 15.0}]
    body = BODY | {"geofence": FENCE, "rally_points": rally, "planner": {"time_limit_s": 0.5}}
    answer = client.post("/plans", json=body)
    assert answer.status_code == 200, answer.text
    shares = answer.json()["fleet"]["shares"]
    assert sorted(b for share in shares for b in share["buoys"]) == [0, 1, 2]
    fence = fence_from_request(MissionRequest.model_validate(body).geofence or [])
    for share in shares:
        assert all(fence.segment_violation(tuple(a), tuple(b)) is None for a, b in itertools.pairwise(share["route"]))


def test_the_request_fence_and_rally_points_are_stored_with_every_plan_a_vehicle_flies(tmp_path, client):
    """What the lifecycle uploads before each sortie (Plan.fence, Plan.rally_points): a single mission's plan and each
    part's of a fleet mission carry the request's, stored and read back; a request without them carries none (the
    vehicle keeps its own lists)."""
    rally = [{**_point(200, 0), "alt_m": 15.0}]
    lists = {"geofence": FENCE, "rally_points": rally, "start": False, "planner": {"time_limit_s": 0.5}}
    single = client.post("/missions", json=BODY | lists | {"vehicles": None, "vehicle": 2})
    fleet = client.post("/missions", json=BODY | lists)
    bare = client.post("/missions", json=BODY | {"vehicles": None, "start": False})
    assert [a.status_code for a in (single, fleet, bare)] == [201, 201, 201], (single.text, fleet.text, bare.text)
    storage = open_storage(tmp_path / "gcs.sqlite")
    try:
        parts = storage.fleet_parts(fleet.json()["id"])
        assert len(parts) >= 1
        for record in (storage.get_mission(single.json()["id"]), *parts):
            assert record is not None
            assert [zone.model_dump(mode="json", exclude_none=True) for zone in record.plan.fence or []] == FENCE
            assert record.plan.rally_points == [[rally[0]["lat"], rally[0]["lon"], 15.0]]
        plain = storage.get_mission(bare.json()["id"])
        assert plain is not None and (plain.plan.fence, plain.plan.rally_points) == (None, None)
    finally:
        storage.close()


@pytest.mark.parametrize(
    ("changes", "location"),
    [
        ({"geofence": FENCE, "buoys": [_point(60, 0), _point(400, 0)]}, ["body", "buoys", 1]),
        ({"geofence": [{**FENCE[0], "vertices": FENCE[0]["vertices"][:2]}]}, ["body", "geofence", 0, "vertices"]),
        ({"geofence": FENCE, "rally_points": [{**_point(400, 0), "alt_m": 10.0}]}, ["body", "rally_points", 0]),
        ({"rally_points": [{**_point(10, 0), "alt_m": 900.0}]}, ["body", "rally_points", 0, "alt_m"]),
        ({"battery": {"capacity_mah": -5}}, ["body", "battery", "BatteryIn", "capacity_mah"]),
        ({"battery": {"capacity_mah": 60}}, ["body", "buoys", 2]),  # beyond one battery from either home
    ],
)
def test_a_bad_fleet_battery_or_geofence_is_422_naming_the_field(client, changes, location):
    answer = client.post("/plans", json=BODY | changes)
    assert answer.status_code == 422, answer.text
    assert location in [error["loc"] for error in answer.json()["detail"]], answer.json()
