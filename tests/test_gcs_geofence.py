"""Geofences and the route: the service plans around a fence's forbidden legs, refuses with 422 naming the buoy pair
when no route avoids them, reads the vehicle's own fence when the request names none; and MAVSDK flying such a
leg anyway meets the vehicle's GF_ACTION."""

from __future__ import annotations

import itertools
import math
import time

import pytest
from fastapi.testclient import TestClient
from mavsdk.plugins.action import Action
from mavsdk.plugins.geofence import FenceType, GeofenceData, Point, Polygon
from mavsdk.plugins.geofence import Geofence as MavsdkGeofence
from mavsdk.plugins.mission_raw import MissionItem as MavsdkItem
from mavsdk.plugins.mission_raw import MissionRaw
from mavsdk.plugins.param import Param
from mavsdk.plugins.telemetry import FlightMode, Telemetry
from sitl_process import WAIT_S
from test_sitl_mavsdk import FIELDS, mavsdk_system, wait_until

from bench.processes import free_udp_port
from gcs.api.app import create_app
from gcs.reports.exports import read_qgc_fence_and_rally
from gcs.settings import Settings
from uavcore.geodesy import DEFAULT_HOME, LocalFrame
from uavcore.geofence import CircleZone, Geofence, PolygonZone
from uavcore.mission import MavCmd, MavFrame, MissionItem

FRAME = LocalFrame(*DEFAULT_HOME)


def lat_lon(north: float, east: float) -> dict:
    lat, lon, _ = FRAME.from_ned(north, east, 0.0)
    return {"lat": float(lat), "lon": float(lon)}


def square(north: float, east: float, half: float) -> list[dict]:
    return [lat_lon(north + dn, east + de) for dn, de in ((-half, -half), (-half, half), (half, half), (half, -half))]


# Four buoys at the corners of a 200 m square north of the depot; an exclusion square between the two northern ones.
BUOYS = [lat_lon(100, -100), lat_lon(300, -100), lat_lon(300, 100), lat_lon(100, 100)]
WALL = {"kind": "polygon", "inclusion": False, "vertices": square(300, 0, 20)}


@pytest.fixture
def client(tmp_path):
    settings = Settings(db_path=tmp_path / "gcs.sqlite", vehicle_url=f"udpout://127.0.0.1:{free_udp_port()}")
    with TestClient(create_app(settings)) as test_client:
        yield test_client


def _legs(plan: dict) -> list[tuple[tuple[float, float], tuple[float, float]]]:
    depot = (DEFAULT_HOME[0], DEFAULT_HOME[1])
    stops = [depot, *((BUOYS[i]["lat"], BUOYS[i]["lon"]) for i in plan["order"]), depot]
    return list(itertools.pairwise(stops))


def test_the_route_goes_around_a_forbidden_leg_when_another_order_avoids_it(client):
    body = {"buoys": BUOYS, "planner": {"method": "exact"}}
    free = client.post("/plans", json=body)
    assert free.status_code == 200
    fence = Geofence((PolygonZone(tuple((v["lat"], v["lon"]) for v in WALL["vertices"]), False),))
    assert any(fence.segment_violation(a, b) for a, b in _legs(free.json())), "the fence must matter here"
    fenced = client.post("/plans", json={**body, "geofence": [WALL]})
    assert fenced.status_code == 200, fenced.text
    assert not any(fence.segment_violation(a, b) for a, b in _legs(fenced.json()))
    assert fenced.json()["length_m"] > free.json()["length_m"]


def test_a_leg_no_route_avoids_is_422_naming_the_buoy_pair(client):
    # a long wall across the whole field, between the depot's side (two buoys) and the far side (one buoy)
    wall = {
        "kind": "polygon",
        "inclusion": False,
        "vertices": [lat_lon(200, -500), lat_lon(200, 500), lat_lon(210, 500), lat_lon(210, -500)],
    }
    buoys = [{"id": "near", **lat_lon(100, 0)}, {"id": "far", **lat_lon(300, 0)}]
    answer = client.post("/plans", json={"buoys": buoys, "geofence": [wall]})
    assert answer.status_code == 422
    errors = answer.json()["detail"]
    # the tour crosses the wall twice: to the far buoy and back; each crossing names its pair
    assert {tuple(e["loc"]) for e in errors} == {("body", "geofence")} and len(errors) == 2
    assert all("far" in e["msg"] and "exclusion polygon" in e["msg"] for e in errors), errors


def test_a_buoy_inside_an_exclusion_zone_is_422_naming_it(client):
    circle = {"kind": "circle", "inclusion": False, "center": BUOYS[2], "radius_m": 30.0}
    answer = client.post("/plans", json={"buoys": BUOYS, "geofence": [circle]})
    assert answer.status_code == 422
    (error,) = answer.json()["detail"]
    assert error["loc"] == ["body", "buoys", 2] and "exclusion circle" in error["msg"]


def test_outside_every_inclusion_zone_is_refused_too(client):
    keep_in = {"kind": "circle", "inclusion": True, "center": lat_lon(0, 0), "radius_m": 250.0}
    answer = client.post("/plans", json={"buoys": BUOYS, "geofence": [keep_in]})
    assert answer.status_code == 422
    assert {tuple(e["loc"]) for e in answer.json()["detail"]} == {("body", "buoys", 1), ("body", "buoys", 2)}


@pytest.mark.parametrize(
    ("zone", "field"),
    [
        ({"kind": "polygon", "inclusion": False, "vertices": square(0, 0, 5)[:2]}, "vertices"),
        ({"kind": "circle", "inclusion": False, "center": lat_lon(0, 0)}, "geofence"),
        ({"kind": "circle", "inclusion": False, "center": lat_lon(0, 0), "radius_m": -1.0}, "radius_m"),
        ({"kind": "triangle", "inclusion": False}, "kind"),
    ],
)
def test_a_malformed_zone_is_422_naming_the_field(client, zone, field):
    answer = client.post("/plans", json={"buoys": BUOYS, "geofence": [zone]})
    assert answer.status_code == 422
    assert any(field in map(str, error["loc"]) for error in answer.json()["detail"]), answer.json()


# ----- with the real vehicle: its fence is the default, and flying through it anyway meets GF_ACTION


def _fence_data() -> GeofenceData:
    points = [Point(v["lat"], v["lon"]) for v in WALL["vertices"]]
    return GeofenceData(polygons=[Polygon(points, FenceType.EXCLUSION)], circles=[])


@pytest.mark.integration
@pytest.mark.slow
def test_the_vehicles_own_fence_refuses_a_mission_through_it(start_sitl, tmp_path):
    vehicle = start_sitl(speed=5)
    with mavsdk_system(vehicle.port) as system:
        MavsdkGeofence(system).upload_geofence(_fence_data())
    buoys = [{"id": "west", **lat_lon(300, -100)}, {"id": "east", **lat_lon(300, 100)}]
    settings = Settings(db_path=tmp_path / "gcs.sqlite", vehicle_url=f"udpout://127.0.0.1:{vehicle.port}")
    with TestClient(create_app(settings)) as client:
        deadline = time.monotonic() + WAIT_S
        while not client.get("/vehicle").json().get("connected"):
            assert time.monotonic() < deadline, "the service never heard the vehicle"
            time.sleep(0.1)
        # two buoys either side of the wall, north of the depot: the leg between them crosses it whichever way
        answer = client.post("/missions", json={"buoys": buoys, "start": False})
        assert answer.status_code == 422, answer.text
        (error,) = answer.json()["detail"]
        assert error["loc"] == ["body", "geofence"] and (
            "west -> east" in error["msg"] or "east -> west" in error["msg"]
        )
        assert client.get("/missions").json() == [] or all(
            m["status"] != "planned" for m in client.get("/missions").json()
        )


def _crossing_mission() -> list[MavsdkItem]:
    def item(seq: int, command: int, north: float, east: float, alt: float, frame=MavFrame.GLOBAL_RELATIVE_ALT_INT):
        point = lat_lon(north, east)
        mission_item = MissionItem(
            seq,
            frame,
            command,
            current=int(seq == 0),
            param1=0.0,
            param2=2.0,
            param3=0.0,
            param4=math.nan,
            x=round(point["lat"] * 1e7),
            y=round(point["lon"] * 1e7),
            z=alt,
        )
        return MavsdkItem(**{name: getattr(mission_item, name) for name in FIELDS})

    return [
        item(0, MavCmd.NAV_TAKEOFF, 0, 0, 5.0),
        item(1, MavCmd.NAV_WAYPOINT, 300, -100, 5.0),
        item(2, MavCmd.NAV_WAYPOINT, 300, 100, 5.0),  # the leg 1 -> 2 runs through the wall
        item(3, MavCmd.NAV_RETURN_TO_LAUNCH, 0, 0, 0.0, frame=MavFrame.MISSION),
    ]


@pytest.mark.integration
@pytest.mark.slow
def test_mavsdk_flying_through_the_fence_anyway_meets_gf_action_return(start_sitl):
    vehicle = start_sitl(speed=20)
    with mavsdk_system(vehicle.port) as system:
        Param(system).set_param_int("GF_ACTION", 3)  # return
        MavsdkGeofence(system).upload_geofence(_fence_data())
        MissionRaw(system).upload_mission(_crossing_mission())
        telemetry = Telemetry(system)
        texts: list[str] = []
        subscription = telemetry.subscribe_status_text(lambda status, _: texts.append(status.text))
        Action(system).arm()
        MissionRaw(system).start_mission()
        wait_until(lambda: telemetry.flight_mode() == FlightMode.MISSION, WAIT_S, "the mission to start")
        wait_until(lambda: telemetry.flight_mode() == FlightMode.RETURN_TO_LAUNCH, 3 * WAIT_S, "GF_ACTION's return")
        # the text comes with the mode change, but MAVSDK may hand it over a little after the new mode
        wait_until(lambda: any(t.startswith("Geofence breached") for t in texts), WAIT_S, "the breach's STATUSTEXT")
        telemetry.unsubscribe_status_text(subscription)
        north, east, _ = FRAME.to_ned(telemetry.position().latitude_deg, telemetry.position().longitude_deg, 0.0)
        # turned back at the wall (x = 280..320 m north, |east| <= 20 m), not after the eastern buoy
        assert north > 250 and east < 0, (north, east)
        assert any(text.startswith("Geofence breached") for text in texts), texts


def test_zone_kinds_from_the_request_match_uavcore():
    from gcs.domain.schemas import FenceZoneIn
    from gcs.missions.validation import fence_from_request

    fence = fence_from_request(
        [
            FenceZoneIn(**WALL),
            FenceZoneIn(kind="circle", inclusion=True, center=lat_lon(0, 0), radius_m=500.0),
        ]
    )
    assert isinstance(fence.zones[0], PolygonZone) and not fence.zones[0].inclusion
    assert isinstance(fence.zones[1], CircleZone) and fence.zones[1].radius_m == 500.0


def test_a_missions_qgc_plan_carries_the_fence_and_rally_points_it_was_given(client):
    keep_in = {"kind": "circle", "inclusion": True, "center": lat_lon(150, 0), "radius_m": 600.0}
    rally = {**lat_lon(-20, 30), "alt_m": 15.0}
    body = {"buoys": BUOYS, "start": False, "geofence": [keep_in, WALL], "rally_points": [rally]}
    mission = client.post("/missions", json=body)
    assert mission.status_code == 201, mission.text
    zones, points = read_qgc_fence_and_rally(client.get(f"/missions/{mission.json()['id']}/plan").text)
    assert [zone.model_dump(mode="json", exclude_none=True) for zone in zones] == [keep_in, WALL]
    assert points == [[rally["lat"], rally["lon"], rally["alt_m"]]]
