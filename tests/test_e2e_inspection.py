"""End to end: buoy inspection through the whole stack, as real processes on loopback UDP.

The vehicle carries its camera on its gimbal and sees a world of buoys (`sitl_quad --world`), two of them faulty;
the service is given the buoys as charted (the world file itself, through POST /imports) and flies the mission:
the verdicts must name the faults the world has and no others, with their evidence served (frames, exports), and
the mission's deletion must take all of it. A vehicle without a camera flies the same request and every buoy says
why it was not inspected.
"""

from __future__ import annotations

import csv
import io
import json
import math
import sqlite3
import time
from collections.abc import Iterator

import numpy as np
import pytest
from PIL import Image
from test_e2e_stack import FLIGHT_S, TERMINAL, Stack, running_stack

from gcs.domain.planning import make_plan
from gcs.missions.inspector import NO_CAMERA
from uavcore.buoy_world import World
from uavcore.geodesy import DEFAULT_HOME, LocalFrame

pytestmark = [pytest.mark.integration, pytest.mark.slow, pytest.mark.timeout(1500)]

HOME = LocalFrame(DEFAULT_HOME[0], DEFAULT_HOME[1])
POSITIONS_NE = [(70.0, 10.0), (120.0, 60.0), (40.0, 90.0)]  # a triangle off the depot: one shortest tour
OFFSET_M = 20.0  # four swing radii


@pytest.fixture
def stack(tmp_path) -> Iterator[Stack]:
    yield from running_stack(tmp_path)


def world_document() -> dict:
    """Three buoys with fixed lights (the shortest burst: 20 frames each): the first fault-free, the second's light
    out, the third moored OFFSET_M beyond its charted position along the way the vehicle comes in (so it stays in
    the camera's view: a buoy moved sideways out of the frame is `not_found`, another finding)."""
    lat_lon = [HOME.from_ned(n, e)[:2] for n, e in POSITIONS_NE]
    document = World.default(np.array(lat_lon), ["A", "B", "C"]).to_geojson()
    for feature, (kind, light) in zip(document["features"], [("starboard", "F G"), ("port", "F R"),
                                                            ("special", "F Y")], strict=True):  # fmt: skip
        feature["properties"] |= {"kind": kind, "light": light}
    plan = make_plan(DEFAULT_HOME[:2], lat_lon, ["A", "B", "C"])
    route = [(0.0, 0.0), *(POSITIONS_NE[i] for i in plan.order)]
    before = route[plan.order.index(2)]  # the point the vehicle comes to C from
    way_in = np.subtract(POSITIONS_NE[2], before) / math.dist(POSITIONS_NE[2], before)
    document["features"][1]["properties"]["shows"] = "dark"
    document["features"][2]["properties"]["offset_m"] = list(OFFSET_M * way_in)
    return document


def test_an_inspection_mission_finds_the_worlds_faults_serves_the_evidence_and_deletes_with_it(stack, tmp_path):
    world = tmp_path / "world.geojson"
    world.write_text(json.dumps(world_document()))
    stack.start_gcs()  # first: a lockstep vehicle and its controller would spin on the ground while it starts
    stack.start_vehicle("--world", str(world), "--image-dir", str(tmp_path / "images"))
    stack.start_offboard()
    stack.wait_connected()
    imported = stack.api.post("/imports?filename=world.geojson", content=world.read_bytes())
    buoys = imported.json()["buoys"]
    assert [b["light"] for b in buoys] == ["F G", "F R", "F Y"] and "shows" not in buoys[1]
    mission_id = stack.fly({"buoys": buoys})
    mission = stack.wait_mission(mission_id, lambda m: m["status"] in TERMINAL, timeout_s=FLIGHT_S)
    assert (mission["status"], mission["reason"]) == ("completed", None), mission["events"]
    assert mission["progress"]["camera"].startswith("component 100: ")
    assert mission["progress"]["visited"] == 3  # the visits are the route's, as ever

    inspections = stack.api.get(f"/missions/{mission_id}/inspections").json()
    by_id = {i["buoy"]: i for i in inspections}
    assert [(i["buoy"], i["verdict"]) for i in inspections] == [("A", "ok"), ("B", "defect"), ("C", "defect")]
    assert by_id["A"]["findings"] == [] and by_id["A"]["offset_m"] < 1.5
    assert by_id["A"]["light_seen"].startswith("fixed G")
    assert [f["code"] for f in by_id["B"]["findings"]] == ["light_out"] and by_id["B"]["light_seen"] == "dark"
    (off_station,) = by_id["C"]["findings"]
    assert off_station["code"] == "off_station" and abs(off_station["offset_m"] - OFFSET_M) < 2.0
    assert abs(by_id["C"]["offset_m"] - OFFSET_M) < 2.0
    for inspection in inspections:
        assert len(inspection["frames"]) >= 18 and inspection["best_frame"] in inspection["frames"]

    best = stack.api.get(by_id["A"]["best_frame"])
    assert best.headers["content-type"] == "image/jpeg"
    assert Image.open(io.BytesIO(best.content)).size == (1280, 720)
    rows = list(csv.DictReader(io.StringIO(stack.api.get(f"/missions/{mission_id}/inspections.csv").text)))
    assert [(r["buoy"], r["verdict"], r["findings"]) for r in rows] == [
        ("A", "ok", ""),
        ("B", "defect", "light_out"),
        ("C", "defect", "off_station"),
    ]
    geojson = stack.api.get(f"/missions/{mission_id}/inspections.geojson").json()
    assert [f["properties"]["located"] for f in geojson["features"]] == ["observed"] * 3

    assert stack.api.delete(f"/missions/{mission_id}").status_code == 204
    assert stack.api.get(f"/missions/{mission_id}").status_code == 404
    assert stack.api.get(by_id["A"]["best_frame"]).status_code == 404
    with sqlite3.connect(stack.dir / "gcs.sqlite") as db:
        for table in ("frames", "inspections", "telemetry", "mission_events"):
            assert db.execute(f"SELECT COUNT(*) FROM {table} WHERE mission_id = ?", (mission_id,)).fetchone() == (0,)


def test_a_vehicle_without_a_camera_flies_the_mission_and_every_buoy_says_it_was_not_inspected(stack):
    stack.start_gcs()
    stack.start_vehicle()  # no --world: no camera, no gimbal
    stack.start_offboard()
    stack.wait_connected()
    buoys = [
        dict(zip(("lat", "lon"), HOME.from_ned(n, e)[:2], strict=True)) | {"kind": "port"} for n, e in POSITIONS_NE
    ]
    mission_id = stack.fly({"buoys": buoys})
    mission = stack.wait_mission(mission_id, lambda m: m["status"] in TERMINAL, timeout_s=FLIGHT_S)
    assert (mission["status"], mission["progress"]["camera"]) == ("completed", None), mission["events"]
    inspections = stack.api.get(f"/missions/{mission_id}/inspections").json()
    assert [(i["index"], i["verdict"], i["reason"]) for i in inspections] == [
        (k, "not_inspected", NO_CAMERA) for k in range(3)
    ]
    assert mission["progress"]["visited"] == 3
    # while it flew, no mission item aimed or fired a camera: one waypoint per buoy
    assert mission["progress"]["total"] == 2 + 3 + 1


def test_frames_over_the_size_limit_are_refused_and_each_buoy_says_so_while_the_mission_completes(
    stack, tmp_path, monkeypatch
):
    world = tmp_path / "world.geojson"
    world.write_text(json.dumps(world_document()))
    monkeypatch.setenv("BUOY_GCS_MAX_FRAME_BYTES", "1000")  # a 1280x720 JPEG is some 70 kB
    stack.start_gcs()
    stack.start_vehicle("--world", str(world), "--image-dir", str(tmp_path / "images"))
    stack.start_offboard()
    stack.wait_connected()
    buoys = stack.api.post("/imports?filename=world.geojson", content=world.read_bytes()).json()["buoys"]
    mission_id = stack.fly({"buoys": buoys})
    mission = stack.wait_mission(mission_id, lambda m: m["status"] in TERMINAL, timeout_s=FLIGHT_S)
    assert (mission["status"], mission["reason"]) == ("completed", None), mission["events"]
    inspections = stack.api.get(f"/missions/{mission_id}/inspections").json()
    assert [i["verdict"] for i in inspections] == ["not_inspected"] * 3
    for inspection in inspections:
        assert inspection["frames"] == [] and inspection["best_frame"] is None
        assert inspection["reason"].startswith("no frame could be used: a frame could not be downloaded")
        assert "over the limit of 1000" in inspection["reason"], inspection["reason"]
    with sqlite3.connect(stack.dir / "gcs.sqlite") as db:
        assert db.execute("SELECT COUNT(*) FROM frames WHERE mission_id = ?", (mission_id,)).fetchone() == (0,)


def test_a_buoy_whose_burst_an_abort_cuts_short_is_not_judged_on_a_part_of_it(stack, tmp_path):
    """The operator aborts while the camera is half-way through the second buoy's burst (a long-period light: 21 s
    of frames): the first buoy is judged, the second is not (a part of a burst would misread its light) and says
    its burst was cut short, with the frames that came kept as evidence; the third was never reached."""
    document = world_document()
    for feature in document["features"]:
        feature["properties"].pop("shows", None)
        feature["properties"].pop("offset_m", None)
    lat_lon = [HOME.from_ned(n, e)[:2] for n, e in POSITIONS_NE]
    first, second, third = make_plan(DEFAULT_HOME[:2], lat_lon, ["A", "B", "C"]).order
    document["features"][second]["properties"] |= {"kind": "safe_water", "light": "LFl W 10s"}  # 210 frames
    world = tmp_path / "world.geojson"
    world.write_text(json.dumps(document))
    images = tmp_path / "images"
    stack.start_gcs()
    stack.start_vehicle("--world", str(world), "--image-dir", str(images))
    stack.start_offboard()
    stack.wait_connected()
    buoys = stack.api.post("/imports?filename=world.geojson", content=world.read_bytes()).json()["buoys"]
    mission_id = stack.fly({"buoys": buoys})
    # the first burst is 20 frames: 60 written means the second buoy's has 170 of its 210 to go (17 s of its time)
    deadline = time.monotonic() + FLIGHT_S
    while len(list(images.glob("IMG_*.jpg"))) < 60:
        assert time.monotonic() < deadline, "the second burst never started"
        time.sleep(0.05)
    assert stack.api.post(f"/missions/{mission_id}/abort").status_code == 200
    # "aborted" comes as the vehicle turns for home; the sortie's inspection closes once it has landed
    mission = stack.wait_mission(mission_id, lambda m: "returned" in (m["reason"] or ""), timeout_s=FLIGHT_S)
    assert mission["status"] == "aborted", mission["events"]

    by_index = {i["index"]: i for i in stack.api.get(f"/missions/{mission_id}/inspections").json()}
    assert sorted(by_index) == [0, 1, 2], (first, second, third, by_index)
    assert by_index[first]["verdict"] == "ok", by_index[first]
    cut = by_index[second]
    assert cut["verdict"] == "not_inspected" and cut["findings"] == [], cut
    assert cut["reason"].startswith("its burst was cut short"), cut["reason"]
    assert "of its 210 frames reported" in cut["reason"], cut["reason"]
    assert len(cut["frames"]) >= 40  # what came before the abort, kept as evidence
    assert by_index[third]["verdict"] == "not_inspected" and by_index[third]["frames"] == []
