"""The REST API without a vehicle: every endpoint, every validation error, the token, the page.

Flying is covered by the integration test against the real vehicle (test_gcs_integration.py).
"""

import asyncio
import gc
import json
import time
from pathlib import Path

import pytest
from fastapi.testclient import TestClient

from bench.processes import free_udp_port
from gcs.api.app import create_app
from gcs.domain.schemas import HomeOut, VehicleOut
from gcs.domain.status import MissionStatus
from gcs.reports.exports import read_qgc_plan, read_waypoints
from gcs.settings import Limits, Settings
from gcs.storage import MissionRecord
from gcs.storage.off_loop import AsyncStorage
from gcs.vehicle.link import VehicleStatus
from planner import plan_tour
from planner.scenario import reference_scenario
from uavcore.geodesy import DEFAULT_HOME

REPO = Path(__file__).resolve().parents[1]
SCENARIO = reference_scenario(1)
BUOYS = [{"lat": lat, "lon": lon} for lat, lon in SCENARIO.buoys_lat_lon]


def make_client(tmp_path, **overrides) -> TestClient:
    options = {"vehicle_wait_s": 0.3, **overrides}
    settings = Settings(db_path=tmp_path / "gcs.sqlite", vehicle_url=f"udpout:127.0.0.1:{free_udp_port()}", **options)
    return TestClient(create_app(settings))


@pytest.fixture
def client(tmp_path):
    with make_client(tmp_path) as c:
        yield c


def wait_status(client, mission_id, statuses, timeout_s=60.0):  # a backstop on a loaded machine
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        body = client.get(f"/missions/{mission_id}").json()
        if body["status"] in statuses:
            return body
        time.sleep(0.05)
    raise AssertionError(f"mission {mission_id} still {body['status']}")


def errors_of(response) -> list[tuple[list, str]]:
    assert response.status_code == 422, response.text
    return [(e["loc"], e["msg"]) for e in response.json()["detail"]]


# ----- the app
def test_the_serving_app_keeps_its_start_up_objects_out_of_full_collections_while_it_runs(tmp_path):
    # gcs serve's app: a full collection walking the start-up's objects held the GIL ~90 ms (gcs.api.app)
    settings = Settings(db_path=tmp_path / "gcs.sqlite", vehicle_url=f"udpout:127.0.0.1:{free_udp_port()}")
    frozen_before = gc.get_freeze_count()
    with TestClient(create_app(settings, freeze_startup_heap=True)) as client:
        service = client.app.state.service
        assert gc.get_freeze_count() > frozen_before
        assert not any(o is service for o in gc.get_objects())  # no collection walks it
        assert client.get("/missions").status_code == 200
    assert gc.get_freeze_count() == frozen_before  # given back to the collector when the service stops
    with TestClient(create_app(settings)) as client:  # tests' apps (many in one process) freeze nothing
        assert gc.get_freeze_count() == frozen_before
        assert any(o is client.app.state.service for o in gc.get_objects())


def test_the_vehicle_document_names_every_field_of_the_links_vehicle_status():
    # GET /vehicle(s)' response models list the link's VehicleStatus fields by name: a field added to one only
    # would be dropped from the answer, or make every answer a 500
    document = VehicleStatus(connected=True, home=(55.0, 12.0, 3.0)).as_dict() | {"role": "owner"}
    assert set(document) == set(VehicleOut.model_fields)
    assert VehicleOut.model_validate(document).home == HomeOut(lat=55.0, lon=12.0, alt=3.0)


# ----- planning
def test_plan_reference_scenario_is_the_exact_optimum(client):
    response = client.post("/plans", json={"buoys": BUOYS, "planner": {"method": "exact"}})
    assert response.status_code == 200
    body = response.json()
    assert sorted(body["order"]) == list(range(13))
    points = [[0.0, 0.0], *SCENARIO.buoys_local.tolist()]
    assert body["length_m"] == pytest.approx(plan_tour(points, method="exact").length, rel=1e-6)
    assert body["input_order_length_m"] > body["length_m"]
    expected_pct = 100 * (body["input_order_length_m"] - body["length_m"]) / body["input_order_length_m"]
    assert body["improvement_pct"] == pytest.approx(expected_pct)
    assert body["depot"] == {"lat": DEFAULT_HOME[0], "lon": DEFAULT_HOME[1]}
    assert body["route"][0] == body["route"][-1] == [DEFAULT_HOME[0], DEFAULT_HOME[1]]
    assert len(body["route"]) == 15
    assert body["buoys"][3]["id"] == "B4"


def test_plan_accepts_a_geojson_feature_collection(client):
    features = [
        {
            "type": "Feature",
            "geometry": {"type": "Point", "coordinates": [b["lon"], b["lat"]]},
            "properties": {"id": f"n{i}"},
        }
        for i, b in enumerate(BUOYS)
    ]
    collection = {"type": "FeatureCollection", "features": features}
    from_geojson = client.post("/plans", json={"buoys": collection, "planner": {"method": "exact"}}).json()
    from_list = client.post("/plans", json={"buoys": BUOYS, "planner": {"method": "exact"}}).json()
    assert from_geojson["order"] == from_list["order"]
    assert from_geojson["buoys"][0]["id"] == "n0"


def test_plan_with_an_explicit_depot(client):
    depot = {"lat": 38.9205, "lon": 121.6625}
    body = client.post("/plans", json={"buoys": BUOYS[:4], "depot": depot}).json()
    assert body["depot"] == depot and body["route"][0] == [depot["lat"], depot["lon"]]


# ----- validation: one case per rule, each naming the field
@pytest.mark.parametrize(
    ("change", "loc", "reason"),
    [
        ({"buoys": [{"lat": 91.0, "lon": 0.0}]}, ["body", "buoys", 0, "lat"], "less than or equal to 90"),
        ({"buoys": [{"lat": 0.0, "lon": -181.0}]}, ["body", "buoys", 0, "lon"], "greater than or equal to -180"),
        ({"buoys": []}, ["body", "buoys"], "at least 1"),
        ({"buoys": [BUOYS[0]] * 501}, ["body", "buoys"], "at most 500"),
        (
            {"buoys": [BUOYS[0], {"lat": BUOYS[0]["lat"] + 1e-6, "lon": BUOYS[0]["lon"]}]},
            ["body", "buoys", 1],
            "at least 2 m apart",
        ),
        ({"buoys": [{"lat": DEFAULT_HOME[0], "lon": DEFAULT_HOME[1]}]}, ["body", "buoys", 0], "from the depot"),
        ({"buoys": [{"lat": 40.0, "lon": 121.663}]}, ["body", "buoys", 0], "maximum range"),
        ({"altitude_m": 500.0}, ["body", "altitude_m"], "airframe's limits"),
        ({"altitude_m": 0.5}, ["body", "altitude_m"], "airframe's limits"),
        ({"speed_m_s": 40.0}, ["body", "speed_m_s"], "airframe's limits"),
        ({"dwell_s": -1.0}, ["body", "dwell_s"], "airframe's limits"),
        ({"acceptance_radius_m": 0.0}, ["body", "acceptance_radius_m"], "airframe's limits"),
        ({"planner": {"time_limit_s": 999.0}}, ["body", "planner", "time_limit_s"], "exceeds"),
        ({"planner": {"method": "magic"}}, ["body", "planner", "method"], "Input should be"),
        ({"depot": {"lat": -95.0, "lon": 0.0}}, ["body", "depot", "lat"], "greater than or equal to -90"),
        ({"colour": "red"}, ["body", "colour"], "Extra inputs"),
        (
            {
                "buoys": {
                    "type": "FeatureCollection",
                    "features": [{"type": "Feature", "geometry": {"type": "Polygon"}}],
                }
            },
            ["body", "buoys"],
            "features[0].geometry: must be a Point",
        ),
    ],
)
def test_validation_errors_name_field_and_reason(client, change, loc, reason):
    body = {"buoys": BUOYS, **change}
    for path in ("/plans", "/missions"):
        errors = errors_of(client.post(path, json=body))
        assert any(e_loc == loc and reason in msg for e_loc, msg in errors), errors


@pytest.mark.parametrize("bad", ["NaN", "Infinity", "-Infinity"])
def test_non_finite_numbers_are_refused(client, bad):
    text = json.dumps({"buoys": BUOYS}).replace(str(BUOYS[0]["lat"]), bad, 1)
    errors = errors_of(client.post("/plans", content=text, headers={"content-type": "application/json"}))
    assert errors[0][0] == ["body", "buoys", 0, "lat"] and "finite" in errors[0][1]


def test_route_longer_than_the_battery_range_is_refused(tmp_path):
    with make_client(tmp_path, limits=Limits(max_route_length_m=1000.0)) as c:
        errors = errors_of(c.post("/plans", json={"buoys": BUOYS}))
    assert errors[0][0] == ["body", "buoys"] and "maximum range is 1000 m" in errors[0][1]


def test_planner_size_limit_is_a_422(client):
    # 70 buoys on a grid: more than the pure CHNN takes (planner.TooLargeError -> 422 on the buoys)
    grid = [{"lat": 38.92 + 0.0002 * (i // 7), "lon": 121.67 + 0.0003 * (i % 7)} for i in range(70)]
    errors = errors_of(client.post("/plans", json={"buoys": grid, "planner": {"method": "chnn"}}))
    assert errors[0][0] == ["body", "buoys"] and "at most" in errors[0][1]


# ----- missions without a vehicle
def test_mission_without_start_is_stored_planned_and_listed(client):
    response = client.post("/missions", json={"buoys": BUOYS, "start": False})
    assert response.status_code == 201
    mission = response.json()
    assert mission["status"] == "planned" and mission["reason"] is None
    assert sorted(mission["order"]) == list(range(13))
    assert mission["altitude_m"] == 5.0 and mission["progress"]["buoys"] == 13
    assert [e["status"] for e in mission["events"]] == ["planned"]
    listed = client.get("/missions").json()
    assert [m["id"] for m in listed] == [mission["id"]] and listed[0]["buoys"] == 13
    assert [(m["kind"], m["fleet_id"]) for m in (mission, listed[0])] == [("single", None)] * 2
    assert client.get(f"/missions/{mission['id']}").json()["order"] == mission["order"]


def test_start_with_no_vehicle_fails_clearly(client):
    mission = client.post("/missions", json={"buoys": BUOYS}).json()
    assert mission["status"] == "planned"
    final = wait_status(client, mission["id"], {"failed"})
    assert final["reason"] == "no vehicle"
    assert [e["status"] for e in final["events"]] == ["planned", "failed"]
    vehicle = client.get("/vehicle").json()
    assert vehicle["connected"] is False and vehicle["active_mission"] is None
    assert vehicle["depot"] == {"lat": DEFAULT_HOME[0], "lon": DEFAULT_HOME[1]}


def test_start_endpoint_and_conflicts(client):
    mission_id = client.post("/missions", json={"buoys": BUOYS, "start": False}).json()["id"]
    assert client.post(f"/missions/{mission_id}/start").status_code == 200
    other = client.post("/missions", json={"buoys": BUOYS}).status_code  # the vehicle is busy (waiting)
    assert other == 409
    wait_status(client, mission_id, {"failed"})
    assert client.post(f"/missions/{mission_id}/start").status_code == 409  # only planned missions start


def test_abort_a_planned_mission_and_abort_twice(client):
    mission_id = client.post("/missions", json={"buoys": BUOYS, "start": False}).json()["id"]
    response = client.post(f"/missions/{mission_id}/abort")
    assert response.status_code == 200 and response.json()["status"] == "aborted"
    assert client.post(f"/missions/{mission_id}/abort").status_code == 409


def test_abort_while_waiting_for_the_vehicle(tmp_path):
    with make_client(tmp_path, vehicle_wait_s=30.0) as c:
        mission_id = c.post("/missions", json={"buoys": BUOYS}).json()["id"]
        body = c.post(f"/missions/{mission_id}/abort").json()
    assert body["status"] == "aborted" and "before takeoff" in body["reason"]


def test_abort_while_the_missions_task_still_reads_its_mission(tmp_path, monkeypatch):
    # the task is cancelled at its first await (reading its mission, in a storage thread), before it could record
    # an end: the abort must still end the mission
    reads: list[int] = []
    read = AsyncStorage.existing_mission

    async def first_read_never_answers(self: AsyncStorage, mission_id: int) -> MissionRecord:
        reads.append(mission_id)
        if len(reads) == 1:
            await asyncio.get_running_loop().create_future()  # until cancelled
        return await read(self, mission_id)

    monkeypatch.setattr(AsyncStorage, "existing_mission", first_read_never_answers)
    with make_client(tmp_path, vehicle_wait_s=30.0) as c:
        mission_id = c.post("/missions", json={"buoys": BUOYS}).json()["id"]
        deadline = time.monotonic() + 30.0
        while not reads and time.monotonic() < deadline:
            time.sleep(0.01)
        assert reads == [mission_id]
        body = c.post(f"/missions/{mission_id}/abort").json()
    assert body["status"] == "aborted" and "before takeoff" in body["reason"]


def test_unknown_mission_is_404_everywhere(client):
    for path in ("", "/telemetry", "/track.geojson", "/plan", "/waypoints"):
        assert client.get(f"/missions/9999{path}").status_code == 404
    for path in ("/abort", "/start"):
        assert client.post(f"/missions/9999{path}").status_code == 404


def test_exports_of_a_planned_mission(client):
    mission = client.post("/missions", json={"buoys": BUOYS, "start": False, "dwell_s": 3.0}).json()
    plan_response = client.get(f"/missions/{mission['id']}/plan")
    assert "attachment" in plan_response.headers["content-disposition"]
    home, items = read_qgc_plan(plan_response.text)
    assert home[:2] == pytest.approx((DEFAULT_HOME[0], DEFAULT_HOME[1]))
    waypoint_items = [i for i in items if i.command == 16]
    assert len(waypoint_items) == 13 and all(i.param1 == 3.0 for i in waypoint_items)
    visited = [mission["buoys"][k] for k in mission["order"]]
    flown = [c for i in waypoint_items for c in (i.lat, i.lon)]
    assert flown == pytest.approx([c for b in visited for c in (b["lat"], b["lon"])], abs=1e-7)
    _, wpl_items = read_waypoints(client.get(f"/missions/{mission['id']}/waypoints").text)
    assert [i.command for i in wpl_items] == [i.command for i in items]
    track = client.get(f"/missions/{mission['id']}/track.geojson").json()
    assert track["geometry"] == {"type": "LineString", "coordinates": []}
    assert client.get(f"/missions/{mission['id']}/telemetry").json() == []


# ----- imports
def test_import_csv_and_geojson(client):
    csv_body = client.post("/imports?filename=b.csv", content=b"id,lat,lon\nA,38.92,121.66\n").json()
    # register_id: a buoy of the register (POST /buoys/imports); a plain file's buoys are not
    uncharted = {
        "kind": None,
        "light": None,
        "swing_radius_m": None,
        "register_id": None,
        "charted": None,
        "region": None,
    }
    # chart and warnings: an S-57 cell's (tests/test_gcs_chart_import.py)
    assert csv_body == {
        "buoys": [{"id": "A", "lat": 38.92, "lon": 121.66} | uncharted],
        "depot": None,
        "chart": None,
        "warnings": [],
    }
    charted = {"kind": "port", "light": "Fl(2) R 6s", "swing_radius_m": 8.0}
    faults = {"shows": "dark", "offset_m": [20.0, 0.0]}  # a world file's: not what the chart says, left out
    collection = {
        "type": "FeatureCollection",
        "features": [
            {"type": "Feature", "geometry": {"type": "Point", "coordinates": [121.66, 38.92]}, "properties": {}},
            {
                "type": "Feature",
                "geometry": {"type": "Point", "coordinates": [121.67, 38.93]},
                "properties": {"id": "P1"} | charted | faults,
            },
        ],
    }
    geo = client.post("/imports", content=json.dumps(collection), headers={"content-type": "application/geo+json"})
    assert geo.json()["buoys"] == [
        {"id": None, "lat": 38.92, "lon": 121.66} | uncharted,
        {"id": "P1", "lat": 38.93, "lon": 121.67, "register_id": None, "charted": None, "region": None} | charted,
    ]


def test_an_imported_buoy_whose_charted_light_is_not_a_character_is_422_naming_it(client):
    feature = {
        "type": "Feature",
        "geometry": {"type": "Point", "coordinates": [121.66, 38.92]},
        "properties": {"id": "P1", "kind": "port", "light": "Fl(2) X 6s"},
    }
    response = client.post("/imports?filename=b.geojson", content=json.dumps(feature))
    assert response.status_code == 422
    assert "buoy 1 (P1): light: " in errors_of(response)[0][1]


def test_the_example_geojson_imports_and_plans_as_13_buoys_from_its_depot(client):
    """examples/reference_buoys.geojson marks its depot with role "depot": imported, it is the answer's depot, not
    a 14th buoy; posted as a mission's buoys, it is the plan's depot (the request names none)."""
    text = (REPO / "examples" / "reference_buoys.geojson").read_text()
    depot = {"lat": 38.921, "lon": 121.663}
    imported = client.post("/imports?filename=reference_buoys.geojson", content=text).json()
    assert len(imported["buoys"]) == 13 and imported["depot"] == depot
    plan = client.post("/plans", json={"buoys": json.loads(text)})
    assert plan.status_code == 200, plan.text
    assert len(plan.json()["buoys"]) == 13 and plan.json()["depot"] == depot
    # that depot is the vehicle's home too: a file's depot elsewhere is where that plan starts
    moved = json.loads(text)
    moved["features"][0]["geometry"]["coordinates"] = [121.665, 38.922]
    assert client.post("/plans", json={"buoys": moved}).json()["depot"] == {"lat": 38.922, "lon": 121.665}
    assert client.post("/plans", json={"buoys": moved, "depot": depot}).json()["depot"] == depot  # the request's
    example = client.post("/plans", json=json.loads((REPO / "examples" / "reference_mission.json").read_text()))
    assert example.json()["depot"] == depot  # the two example files: one mission

    def places(answer):  # the GeoJSON has 8 decimals (1 mm), the mission file all of them
        return [c for b in sorted(answer.json()["buoys"], key=lambda b: b["id"]) for c in (b["lat"], b["lon"])]

    assert places(example) == pytest.approx(places(plan), abs=1e-7)


def test_import_errors_are_422_with_the_reason(client):
    errors = errors_of(client.post("/imports?filename=b.csv", content=b"lat,lon\n95,1\n"))
    assert "line 2: latitude 95" in errors[0][1]
    assert "no rows" in errors_of(client.post("/imports?filename=b.csv", content=b""))[0][1]


# ----- token
def test_token_guards_every_mutating_endpoint(tmp_path):
    with make_client(tmp_path, token="s3cret") as c:
        planned = {"buoys": BUOYS, "start": False}
        for path, body in (
            ("/plans", {"buoys": BUOYS}),
            ("/missions", planned),
            ("/missions/1/abort", None),
            ("/missions/1/start", None),
            ("/imports", None),
        ):
            response = c.post(path, json=body)
            assert response.status_code == 401, path
            assert response.headers["www-authenticate"] == "Bearer"
        assert c.post("/missions", json=planned, headers={"Authorization": "Bearer wrong"}).status_code == 401
        assert c.post("/missions", json=planned, headers={"Authorization": "Bearer s3cret"}).status_code == 201
        assert c.post("/plans", json={"buoys": BUOYS}, headers={"X-API-Token": "s3cret"}).status_code == 200
        assert c.get("/missions").status_code == 200  # reading needs no token
        assert c.get("/vehicle").status_code == 200


def test_token_from_the_environment(monkeypatch):
    monkeypatch.setenv("BUOY_GCS_TOKEN", "from-env")
    assert Settings().token == "from-env"
    assert Settings(token="cli").token == "cli"  # the command line's value wins
    monkeypatch.setenv("BUOY_GCS_TOKEN", "")
    assert Settings().token is None  # an empty variable is no token


def test_mission_status_is_one_named_enum_in_the_openapi_document(client):
    schemas = client.get("/openapi.json").json()["components"]["schemas"]
    assert schemas["MissionStatus"]["enum"] == [status.value for status in MissionStatus]
    for model in ("MissionOut", "MissionSummary"):
        assert schemas[model]["properties"]["status"] == {"$ref": "#/components/schemas/MissionStatus"}


# ----- live and page
def test_websocket_streams_vehicle_state(client):
    with client.websocket_connect("/ws") as ws:
        messages = [ws.receive_json() for _ in range(3)]
    assert all(m["type"] == "state" and m["vehicle"]["connected"] is False for m in messages)
    assert messages[0]["mission"] is None


def test_page_and_vendored_libraries_are_served(client):
    page = client.get("/")
    assert page.status_code == 200 and "<html" in page.text.lower()
    assert "/static/leaflet/leaflet.js" in page.text
    assert client.get("/static/leaflet/leaflet.js").status_code == 200
    assert client.get("/web/vendor/uplot/uPlot.iife.min.js").status_code == 200
    assert client.get("/web/app.js").status_code == 200
    assert client.get("/docs").status_code == 200
    assert "/missions/{mission_id}/track.geojson" in client.get("/openapi.json").json()["paths"]
