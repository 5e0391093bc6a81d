"""The inspections' HTTP face over stored records: the per-buoy list (a fleet mission's gathered from its parts),
the CSV and GeoJSON exports, the frames served as what they are, deletion, and the request's charted buoys
refused with the field named."""

from __future__ import annotations

import csv
import io
from dataclasses import replace

import pytest
from PIL import Image
from stored_missions import FLIGHT, PLAN
from test_gcs_api import errors_of, make_client

from gcs.domain.inspection import BuoyInspection, Finding, InspectionRecord, LatLon, StoredFrame
from gcs.domain.planning import BuoyMark
from gcs.missions.inspector import charted_record, not_inspected
from gcs.storage import open_storage

CHARTED = replace(PLAN, buoy_ids=["=HYPERLINK(1)", "B2"], marks=[BuoyMark("port", "Fl R 4s", 5.0), BuoyMark()])


def jpeg() -> bytes:
    out = io.BytesIO()
    Image.new("RGB", (64, 36), (40, 90, 120)).save(out, "JPEG")
    return out.getvalue()


def frame(buoy: int, index: int) -> StoredFrame:
    return StoredFrame(buoy=buoy, image_index=index, t_s=float(index), lat=55.0, lon=12.0, height_m=5.0,
                       q=(1.0, 0.0, 0.0, 0.0), file_url=f"mftp://[;comp=100]/IMG_{index:06d}.jpg")  # fmt: skip


def defect(plan, index: int, frame_ids: list[int]) -> InspectionRecord:
    """An off-station record of buoy `index`, seen 12.5 m from its charted position."""
    finding = Finding(code="off_station", offset_m=12.5, swing_radius_m=5.0, bearing_deg=90)
    result = BuoyInspection(buoy=charted_record(plan, index), verdict="defect", findings=[finding],
                            observed=LatLon(lat=55.0005, lon=12.0002), offset_m=12.5, light_seen="flashing . R 4.0s",
                            frames=[0, 1])  # fmt: skip
    return InspectionRecord(buoy=index, buoy_id=plan.buoy_ids[index], result=result, frame_ids=frame_ids,
                            best_frame=frame_ids[-1])  # fmt: skip


@pytest.fixture
def stored(tmp_path):
    """A mission with a defect (two frames: a JPEG, and bytes that are no image) and a buoy not inspected; a fleet
    mission whose parts each inspected one buoy; the service over that database."""
    storage = open_storage(tmp_path / "gcs.sqlite")
    mission = storage.create_mission(FLIGHT, CHARTED)
    ids = [storage.add_frame(mission, frame(0, 0), b"<html>not an image</html>", 10**6),
           storage.add_frame(mission, frame(0, 1), jpeg(), 10**6)]  # fmt: skip
    storage.set_inspection(mission, defect(CHARTED, 0, ids))
    storage.set_inspection(mission, not_inspected(CHARTED, 1, "the vehicle has no camera"))
    storage.set_status(mission, "completed")
    first_part = replace(CHARTED, buoy_ids=["B2"], buoys_lat_lon=[CHARTED.buoys_lat_lon[1]], order=[0], marks=None)
    second_part = replace(CHARTED, buoy_ids=[CHARTED.buoy_ids[0], "B2"], order=[0, 1])  # B2 re-shared to it
    fleet, (first, second) = storage.create_fleet_mission(FLIGHT, CHARTED, [(FLIGHT, first_part, 1),
                                                                             (FLIGHT, second_part, 2)])  # fmt: skip
    storage.set_inspection(first, not_inspected(first_part, 0, "not reached (the vehicle was lost)"))
    storage.set_inspection(second, defect(second_part, 1, [storage.add_frame(second, frame(1, 5), jpeg(), 10**6)]))
    storage.set_inspection(second, not_inspected(second_part, 0, "no frame of its burst came from the camera"))
    storage.close()
    with make_client(tmp_path) as client:
        yield client, mission, fleet, second


def test_the_inspections_list_each_buoy_with_its_verdict_findings_and_frame_urls(stored):
    client, mission, _, _ = stored
    first, second = client.get(f"/missions/{mission}/inspections").json()
    assert (first["buoy"], first["index"], first["verdict"], first["offset_m"]) == ("=HYPERLINK(1)", 0, "defect", 12.5)
    assert first["findings"] == [{"code": "off_station", "offset_m": 12.5, "swing_radius_m": 5.0, "bearing_deg": 90}]
    charted = {"lat": 55.0005, "lon": 12.0, "kind": "port", "light": "Fl R 4s", "swing_radius_m": 5.0, "region": "A"}
    assert first["charted"] == charted
    assert first["frames"][1] == first["best_frame"] and first["frames"][0].startswith(f"/missions/{mission}/frames/")
    assert (second["verdict"], second["reason"], second["charted"]["kind"]) == (
        "not_inspected",
        "the vehicle has no camera",
        "unknown",
    )
    assert client.get("/missions/999/inspections").status_code == 404


def test_a_frame_is_served_as_an_image_only_when_it_is_one(stored):
    client, mission, _, _ = stored
    not_an_image, image = client.get(f"/missions/{mission}/inspections").json()[0]["frames"]
    served = client.get(image)
    assert served.headers["content-type"] == "image/jpeg" and Image.open(io.BytesIO(served.content)).size == (64, 36)
    assert client.get(not_an_image).headers["content-type"] == "application/octet-stream"
    assert "nosniff" in client.get(not_an_image).headers.get("x-content-type-options", "")
    assert client.get(f"/missions/{mission}/frames/99999").status_code == 404


def test_the_exports_hold_every_buoy_and_a_cell_a_spreadsheet_would_run_is_kept_as_text(stored):
    client, mission, _, _ = stored
    response = client.get(f"/missions/{mission}/inspections.csv")
    assert response.headers["content-type"].startswith("text/csv")
    assert f'filename="mission-{mission}-inspections.csv"' in response.headers["content-disposition"]
    rows = list(csv.DictReader(io.StringIO(response.text)))
    assert [(r["buoy"], r["verdict"], r["findings"], r["offset_m"]) for r in rows] == [
        ("'=HYPERLINK(1)", "defect", "off_station", "12.5"),
        ("B2", "not_inspected", "", ""),
    ]
    assert rows[1]["reason"] == "the vehicle has no camera" and '"offset_m": 12.5' in rows[0]["details"]
    document = client.get(f"/missions/{mission}/inspections.geojson").json()
    observed, charted = document["features"]
    assert observed["geometry"]["coordinates"] == [12.0002, 55.0005] and observed["properties"]["located"] == "observed"
    assert charted["geometry"]["coordinates"] == [12.0008, 55.0] and charted["properties"]["located"] == "charted"


def test_a_fleet_missions_inspections_gather_its_parts_and_a_re_shared_buoy_takes_the_inspecting_vehicles(stored):
    client, _, fleet, second = stored
    inspections = client.get(f"/missions/{fleet}/inspections").json()
    assert [(i["index"], i["buoy"], i["verdict"]) for i in inspections] == [
        (0, "=HYPERLINK(1)", "not_inspected"),
        (1, "B2", "defect"),  # the part that inspected it, not the lost one's "not reached"
    ]
    assert inspections[1]["best_frame"].startswith(f"/missions/{second}/frames/")  # its frames are its part's


def test_deleting_a_mission_takes_its_frames_and_records_and_a_flying_one_is_refused(stored, tmp_path):
    client, mission, fleet, second = stored
    frame_url = client.get(f"/missions/{mission}/inspections").json()[0]["best_frame"]
    assert client.get(f"/missions/{mission}/report").status_code == 200  # drawn: a report folder to remove
    assert (tmp_path / "reports" / f"mission-{mission}" / "index.html").is_file()
    assert client.delete(f"/missions/{mission}").status_code == 204
    assert client.get(f"/missions/{mission}").status_code == 404
    assert client.get(frame_url).status_code == 404
    assert client.get(f"/missions/{mission}/inspections").status_code == 404
    assert not (tmp_path / "reports" / f"mission-{mission}").exists()
    assert client.delete(f"/missions/{mission}").status_code == 404
    storage = open_storage(tmp_path / "gcs.sqlite")
    storage.set_status(second, "flying")
    storage.close()
    refused = client.delete(f"/missions/{fleet}")
    assert refused.status_code == 409 and f"mission {second} is flying" in refused.json()["detail"][0]["msg"]
    assert client.get(f"/missions/{fleet}/inspections").status_code == 200


@pytest.mark.parametrize(
    ("buoy", "field", "message"),
    [
        ({"light": "Fl(2) X 6s"}, "light", "not a light character"),
        ({"kind": "cardinal"}, "kind", "Input should be"),
        ({"swing_radius_m": -1.0}, "swing_radius_m", "greater than or equal"),
    ],
)
def test_a_charted_buoy_the_chart_cannot_mean_is_refused_naming_its_field(tmp_path, buoy, field, message):
    with make_client(tmp_path) as client:
        body = {"buoys": [{"lat": 55.0, "lon": 12.0} | buoy], "start": False}
        errors = errors_of(client.post("/missions", json=body))
    assert errors[0][0][-2:] == [0, field] and message in errors[0][1]
    with make_client(tmp_path) as client:
        errors = errors_of(client.post("/missions", json={"buoys": [{"lat": 55.0, "lon": 12.0}],
                                                          "inspection_range_m": 2}))  # fmt: skip
    assert errors[0][0][-1] == "inspection_range_m"
