"""The buoy register through the app, without flying: NOAA's US4MD81M imported into it, a mission stored with
four of its buoys named by register id and their inspection records (tests/inspected_missions.py: ok, off station,
not inspected, light out), then each buoy's history and open defects, an operator closing a defect, the filters,
the alarms from the inspection and from AIS, the exports, and bad input."""

from __future__ import annotations

import csv
import io
import time
from pathlib import Path

import pytest
import shapely
import shapely.geometry
from inspected_missions import NOT_INSPECTED_REASON, OFF_STATION, inspection_result
from test_gcs_api import errors_of, make_client

from gcs.domain.aton_table import HeardReport
from gcs.domain.inspection import InspectionRecord
from gcs.domain.register import RegisterBuoy
from gcs.storage import open_storage
from uavcore.ais import AtonReport

CELL = Path(__file__).parent / "data" / "enc" / "US4MD81M" / "US4MD81M.000"
TOKEN = {"Authorization": "Bearer s3cret"}
ANNAPOLIS = "-76.47,38.95,-76.44,38.98"  # five of the cell's marks: a data buoy and four lit beacons
MMSI = 993_672_001


@pytest.fixture
def register(tmp_path):
    """The service with the cell imported into its register."""
    with make_client(tmp_path, token="s3cret") as client:
        imported = client.post("/buoys/imports?filename=US4MD81M.000", content=CELL.read_bytes(), headers=TOKEN)
        assert imported.status_code == 200, imported.text
        yield client, imported.json()


@pytest.fixture
def inspected(register, tmp_path):
    """A mission of four register buoys, stored as planned, with their inspection records as the inspector stores
    them (without frames: the register keeps none); the client, the mission's id and the four register ids in the
    mission's input order."""
    client, _ = register
    marks = client.get("/buoys", params={"bbox": ANNAPOLIS}).json()
    assert len(marks) == 5
    chosen = marks[:4]
    buoys = [{"id": m["name"][:64], "lat": m["lat"], "lon": m["lon"], "kind": m["kind"], "light": m["light"],
              "swing_radius_m": m["swing_radius_m"], "register_id": m["id"]} for m in chosen]  # fmt: skip
    created = client.post("/missions", json={"buoys": buoys, "depot": {"lat": 38.96, "lon": -76.455}, "start": False},
                          headers=TOKEN)  # fmt: skip
    assert created.status_code == 201, created.text
    mission = created.json()["id"]
    storage = open_storage(tmp_path / "gcs.sqlite")
    plan = storage.get_mission(mission).plan
    for index in range(4):
        result = inspection_result(plan, index, 0, NOT_INSPECTED_REASON)
        storage.set_inspection(mission, InspectionRecord(buoy=index, buoy_id=plan.buoy_ids[index], result=result))
    storage.close()
    return client, mission, [m["id"] for m in chosen]


def test_a_chart_cell_fills_the_register_and_a_second_import_changes_nothing(register):
    client, imported = register
    assert imported["source"] == "US4MD81M edition 31 update 0"
    assert len(imported["created"]) == 316 and imported["updated"] == [] and imported["unchanged"] == 0
    buoys = client.get("/buoys").json()
    assert len(buoys) >= 20 and len({b["kind"] for b in buoys}) >= 4
    assert all(b["last_inspected_at"] is None and b["open_defects"] == 0 for b in buoys)
    lit = next(b for b in buoys if b["id"] == "0226000268610001")
    assert (lit["name"], lit["kind"], lit["light"], lit["swing_radius_m"]) == (
        "Annapolis Harbor Entrance Light 4", "starboard", "Fl R 6s", 0.0
    )  # fmt: skip
    assert lit["charted"]["object_class"] == "BCNLAT" and lit["charted"]["region"] == "B"
    again = client.post("/buoys/imports?filename=US4MD81M.000", content=CELL.read_bytes(), headers=TOKEN).json()
    assert (again["created"], again["updated"], again["unchanged"]) == ([], [], 316)
    history = client.get("/buoys/0226000268610001").json()["history"]
    assert [e["kind"] for e in history] == ["registered"]


def test_the_cells_land_piers_and_depth_contours_are_the_offline_base_map(register, tmp_path):
    client, _ = register
    answer = client.get("/basemap.geojson", headers={"Accept-Encoding": "gzip"})
    assert answer.headers["content-encoding"] == "gzip" and answer.headers["content-type"] == "application/geo+json"
    features = answer.json()["features"]  # (httpx decompresses it)
    layers = {f["properties"]["layer"] for f in features}
    assert layers == {"land", "shoreline_construction", "depth_contour"}
    land = shapely.union_all(
        [shapely.geometry.shape(f["geometry"]) for f in features if f["properties"]["layer"] == "land"]
    )
    assert land.contains(shapely.Point(-76.49, 38.978))  # Annapolis
    assert not land.contains(shapely.Point(-76.45, 38.96))  # the harbour's entrance, where its beacons stand
    depths = {f["properties"]["depth_m"] for f in features if f["properties"]["layer"] == "depth_contour"}
    assert {1.8, 3.6, 5.4, 9.1} <= depths
    # imported again: the cell's base map replaced, not doubled; a service with no cell imported has none
    client.post("/buoys/imports?filename=US4MD81M.000", content=CELL.read_bytes(), headers=TOKEN)
    assert len(client.get("/basemap.geojson").json()["features"]) == len(features)
    with make_client(tmp_path / "other") as empty:
        assert empty.get("/basemap.geojson").json() == {"type": "FeatureCollection", "features": []}


def test_the_round_trip_chart_register_mission_inspection_history_defects_and_alarms(inspected):
    client, mission, (ok, off_station, not_seen, light_out) = inspected
    buoy = client.get(f"/buoys/{off_station}").json()
    assert buoy["latest_inspection"]["mission_id"] == mission and buoy["latest_inspection"]["verdict"] == "defect"
    assert [e["kind"] for e in buoy["history"]] == ["registered", "inspection", "defect_opened"]
    (defect,) = buoy["defects"]
    assert (defect["code"], defect["state"], defect["mission_id"]) == ("off_station", "open", mission)
    assert defect["finding"] == {"code": "off_station", **OFF_STATION}
    assert client.get(f"/buoys/{ok}").json()["defects"] == []

    assert {b["id"] for b in client.get("/buoys", params={"open_defects": "true"}).json()} == {off_station, light_out}
    overdue = {b["id"] for b in client.get("/buoys", params={"overdue_days": 30}).json()}
    assert not_seen in overdue and not {ok, off_station, light_out} & overdue and len(overdue) == 313

    (alarm,) = client.get("/alarms").json()
    assert (alarm["buoy"], alarm["source"], alarm["mission_id"], alarm["distance_m"]) == (
        off_station, "inspection", mission, OFF_STATION["offset_m"]
    )  # fmt: skip

    path = f"/buoys/{off_station}/defects/{defect['id']}"
    change = {"state": "closed", "note": "re-moored on its charted position by the tender"}
    assert client.patch(path, json=change).status_code == 401
    closed = client.patch(path, json=change, headers=TOKEN)
    assert closed.status_code == 200 and (closed.json()["state"], closed.json()["note"]) == ("closed", change["note"])
    last = client.get(f"/buoys/{off_station}").json()["history"][-1]
    assert (last["kind"], last["note"], last["detail"]["to"]) == ("defect_state", change["note"], "closed")
    assert client.get("/alarms").json() == []
    assert {b["id"] for b in client.get("/buoys", params={"open_defects": "true"}).json()} == {light_out}


def test_an_ais_report_off_position_or_outside_the_swing_circle_is_an_alarm(inspected):
    client, _, (ok, *_) = inspected
    assert client.patch(f"/buoys/{ok}", json={"mmsi": MMSI}, headers=TOKEN).json()["mmsi"] == MMSI
    charted = client.get(f"/buoys/{ok}").json()
    feed = client.app.state.service.ais
    moved = AtonReport(mmsi=MMSI, name="ANNAPOLIS 4", aid_type=24, lat=charted["lat"] + 0.0005, lon=charted["lon"],
                       position_accuracy=True, off_position=True, virtual=False, second=30)  # fmt: skip
    feed.table.add(HeardReport(moved, "udp://0.0.0.0:10110", time.time(), time.monotonic()))
    alarms = [a for a in client.get("/alarms").json() if a["source"] == "ais"]
    (alarm,) = alarms
    assert alarm["buoy"] == ok and 55.0 < alarm["distance_m"] < 56.0 and alarm["ais"]["mmsi"] == MMSI
    assert "off position" in alarm["why"] and "from the charted one" in alarm["why"]
    assert client.get(f"/buoys/{ok}").json()["ais"]["name"] == "ANNAPOLIS 4"


def hear(client, mmsi: int, name: str, lat: float, lon: float, virtual: bool = False, ago_s: float = 0.0) -> None:
    """An AtoN report as the service's AIS feed would have received it `ago_s` ago."""
    report = AtonReport(mmsi=mmsi, name=name, aid_type=24, lat=lat, lon=lon, position_accuracy=True,
                        off_position=False, virtual=virtual, second=30)  # fmt: skip
    heard = HeardReport(report, "udp://0.0.0.0:10110", time.time() - ago_s, time.monotonic() - ago_s)
    client.app.state.service.ais.table.add(heard)


def test_a_mission_takes_its_buoys_from_the_register_where_ais_last_saw_them_and_judges_them_by_the_chart(register):
    client, _ = register
    depot = {"lat": 38.96, "lon": -76.455}
    annapolis = [float(x) for x in ANNAPOLIS.split(",")]
    marks = {m["id"]: m for m in client.get("/buoys", params={"bbox": ANNAPOLIS}).json()}
    seen_by_mmsi, seen_by_name, virtual = sorted(marks)[:3]
    client.patch(f"/buoys/{seen_by_mmsi}", json={"mmsi": MMSI}, headers=TOKEN)
    client.patch(f"/buoys/{virtual}", json={"mmsi": MMSI + 1}, headers=TOKEN)
    moved = (marks[seen_by_mmsi]["lat"] + 0.0002, marks[seen_by_mmsi]["lon"])  # 22 m north: drifting, or dragged
    chosen = {"ids": [seen_by_mmsi, seen_by_name]}
    hear(client, MMSI, "WHATEVER", *moved, ago_s=client.app.state.service.ais.stale_after_s + 60.0)
    stale = client.post("/plans", json={"depot": depot, "from_register": chosen}, headers=TOKEN).json()["buoys"]
    assert all(b["charted"] is None for b in stale)  # a stale report is no current position: the chart's is taken
    hear(client, MMSI, "WHATEVER", *moved)
    by_name = marks[seen_by_name]
    hear(client, MMSI + 2, by_name["name"].upper(), by_name["lat"] - 0.0001, by_name["lon"])
    hear(client, MMSI + 1, "V", marks[virtual]["lat"], marks[virtual]["lon"], virtual=True)

    planned = client.post("/plans", json={"depot": depot, "from_register": {"bbox": annapolis}}, headers=TOKEN)
    assert planned.status_code == 200, planned.text
    buoys = {b["register_id"]: b for b in planned.json()["buoys"]}
    assert set(buoys) == set(marks) - {virtual}  # nothing physical is at a virtual AtoN
    assert (buoys[seen_by_mmsi]["lat"], buoys[seen_by_mmsi]["lon"]) == pytest.approx(moved)
    assert buoys[seen_by_mmsi]["charted"] == {"lat": marks[seen_by_mmsi]["lat"], "lon": marks[seen_by_mmsi]["lon"]}
    assert buoys[seen_by_name]["lat"] == pytest.approx(by_name["lat"] - 0.0001) and buoys[seen_by_name]["charted"]
    for register_id in set(buoys) - {seen_by_mmsi, seen_by_name}:  # no AIS: where the chart has them
        assert (buoys[register_id]["lat"], buoys[register_id]["charted"]) == (marks[register_id]["lat"], None)
    assert buoys[seen_by_mmsi]["id"] == marks[seen_by_mmsi]["name"]
    assert client.get(f"/buoys/{seen_by_name}").json()["ais_match"] == "name"

    # the mission stores what the inspection judges against: the chart, with the AIS position it looked at
    created = client.post("/missions", json={"depot": depot, "from_register": chosen, "start": False}, headers=TOKEN)
    assert created.status_code == 201, created.text
    plan = client.app.state.service.register._storage.blocking.get_mission(created.json()["id"]).plan
    (index,) = [i for i in range(2) if plan.mark(i).register_id == seen_by_mmsi]
    assert plan.mark(index).charted_lat_lon == (marks[seen_by_mmsi]["lat"], marks[seen_by_mmsi]["lon"])
    assert plan.buoys_lat_lon[index] == pytest.approx(list(moved))
    # the match is the register's, whatever the selection: once a buoy left out of it takes that AtoN's MMSI, the
    # buoy of its name is no longer its (GET /buoys/{id} and a mission of that buoy alone agree)
    claimer = next(i for i in sorted(marks) if i not in (seen_by_mmsi, seen_by_name, virtual))
    client.patch(f"/buoys/{claimer}", json={"mmsi": MMSI + 2}, headers=TOKEN)
    assert client.get(f"/buoys/{seen_by_name}").json()["ais_match"] is None
    alone = {"depot": depot, "from_register": {"ids": [seen_by_name]}}
    (flown,) = client.post("/plans", json=alone, headers=TOKEN).json()["buoys"]
    assert (flown["lat"], flown["charted"]) == (by_name["lat"], None)


def test_a_register_selection_that_names_nothing_flyable_is_a_422_naming_it(register):
    client, _ = register
    depot = {"lat": 38.96, "lon": -76.455}
    some = client.get("/buoys", params={"bbox": ANNAPOLIS}).json()[0]

    def plan(**body) -> list:
        return errors_of(client.post("/plans", json={"depot": depot} | body, headers=TOKEN))

    assert plan() == [(["body", "buoys"], "at least 1 buoy is needed: give buoys, or select some with `from_register`")]
    assert plan(from_register={"ids": [some["id"], "NOPE"]}) == [
        (["body", "from_register", "ids", 1], "no buoy 'NOPE' in the register")
    ]
    assert plan(from_register={"bbox": [10.0, 50.0, 11.0, 51.0]}) == [
        (["body", "from_register"], "no buoy of the register matches the selection")
    ]
    assert plan(from_register={"ids": [some["id"]], "open_defects": True})[0][0] == ["body", "from_register"]
    named = {"lat": some["lat"], "lon": some["lon"], "register_id": some["id"]}
    assert plan(buoys=[named], from_register={"ids": [some["id"]]}) == [
        (["body", "from_register"], f"buoy {some['id']!r} is in `buoys` already")
    ]
    assert plan(from_register={"bbox": [11.0, 50.0, 10.0, 51.0]})[0][0] == ["body", "from_register", "bbox"]
    assert plan(from_register={"overdue_days": 0})[0][0] == ["body", "from_register", "overdue_days"]
    assert plan(from_register={"ids": []})[0][0] == ["body", "from_register", "ids"]


def test_text_from_the_chart_is_data_in_json_and_csv(register, tmp_path):
    client, _ = register
    storage = open_storage(tmp_path / "gcs.sqlite")
    storage.upsert_buoys([RegisterBuoy("X1", 38.97, -76.45, "<script>alert(1)</script>", "special", None),
                          RegisterBuoy("X2", 38.97, -76.46, "=HYPERLINK(\"http://x\")", "special", None)])  # fmt: skip
    storage.close()
    answer = client.get("/buoys/X1")
    assert answer.headers["content-type"] == "application/json"
    assert answer.json()["name"] == "<script>alert(1)</script>"
    rows = list(csv.DictReader(io.StringIO(client.get("/buoys.csv", params={"kind": "special"}).text)))
    names = {row["id"]: row["name"] for row in rows}
    assert names["X2"] == '\'=HYPERLINK("http://x")' and names["X1"] == "<script>alert(1)</script>"
    geojson = client.get("/buoys.geojson", params={"bbox": ANNAPOLIS}).json()
    assert len(geojson["features"]) == 7 and geojson["features"][0]["geometry"]["type"] == "Point"


def field_of(response) -> list:
    """Where the first problem of a 422 is."""
    return errors_of(response)[0][0]


def test_bad_input_is_a_422_naming_the_field_and_an_unknown_id_a_404(register):
    client, _ = register
    assert field_of(client.get("/buoys", params={"bbox": "1,2,3"})) == ["query", "bbox"]
    assert field_of(client.get("/buoys", params={"kind": "purple"})) == ["query", "kind"]
    assert field_of(client.get("/buoys", params={"overdue_days": -1})) == ["query", "overdue_days"]
    assert field_of(client.get("/buoys.csv", params={"open_defects": "maybe"})) == ["query", "open_defects"]
    unknown = {"buoys": [{"lat": 38.96, "lon": -76.45, "register_id": "NOPE"}], "start": False}
    assert errors_of(client.post("/missions", json=unknown, headers=TOKEN)) == [
        (["body", "buoys", 0, "register_id"], "no buoy 'NOPE' in the register")
    ]
    buoy = client.get("/buoys").json()[0]["id"]
    defect = f"/buoys/{buoy}/defects/1"
    assert field_of(client.patch(defect, json={"state": "open", "note": "x"}, headers=TOKEN)) == ["body", "state"]
    assert field_of(client.patch(defect, json={"state": "closed"}, headers=TOKEN)) == ["body", "note"]
    assert field_of(client.patch(f"/buoys/{buoy}", json={"mmsi": 12}, headers=TOKEN)) == ["body", "mmsi"]
    not_a_cell = client.post("/buoys/imports", content=b'{"type": "FeatureCollection"}', headers=TOKEN)
    assert field_of(not_a_cell) == ["body"]
    outside = client.post("/buoys/imports?filename=c.000&area=10,50,11,51", content=CELL.read_bytes(), headers=TOKEN)
    assert field_of(outside) == ["query", "area"]
    closing = {"state": "closed", "note": "x"}
    assert client.get("/buoys/NOPE").status_code == 404
    missing = client.patch(f"/buoys/{buoy}/defects/999", json=closing, headers=TOKEN)
    problem = {"type": "not_found", "loc": ["path", "defect_id"], "msg": f"buoy '{buoy}' has no defect 999"}
    assert (missing.status_code, missing.json()) == (404, {"detail": [problem]})
    assert client.patch("/buoys/NOPE/defects/1", json=closing, headers=TOKEN).status_code == 404
