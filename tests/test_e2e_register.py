"""End to end: the buoy register's round trip, chart -> register -> mission -> inspection -> history, through the
whole stack as real processes on loopback UDP.

The world the vehicle flies in is made of a real NOAA cell's buoys (tests/data/enc/US4MD81M: three Greenwood Creek
buoys within 430 m, written as a world file by `python -m gcs chart --geojson`, in IALA region B's colours as the
chart has them), one of them dragged off station.
The same cell fills the service's register (POST /buoys/imports), a mission takes the buoys from the register by
area (POST /missions' from_register) and flies with the camera, and the register then holds each buoy's inspection
in its history, the off-station buoy's open defect and its alarm.
"""

from __future__ import annotations

import json
import math
import subprocess
import sys
from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pytest
from test_e2e_stack import FLIGHT_S, TERMINAL, Stack, running_stack

from gcs.charts import read_cell

pytestmark = [pytest.mark.integration, pytest.mark.slow, pytest.mark.timeout(1500)]

CELL = Path(__file__).parent / "data" / "enc" / "US4MD81M" / "US4MD81M.000"
AREA = (-76.2000, 38.8922, -76.1970, 38.8962)  # west, south, east, north: Greenwood Creek buoys 10, 12 and 13
DEPOT = (38.8915, -76.2008)  # on the creek's shore, 130 m from the nearest buoy
DRAGGED = "Greenwood Creek Buoy 12"
OFFSET_M = 20.0  # four of the world's default 5 m swing radii


@pytest.fixture
def stack(tmp_path) -> Iterator[Stack]:
    yield from running_stack(tmp_path)


def chart_world(path: Path) -> list[dict]:
    """The area's marks as the vehicle's world, written by the CLI: its features."""
    area = ",".join(str(v) for v in AREA)
    made = subprocess.run([sys.executable, "-m", "gcs", "chart", str(CELL), f"--area={area}", "--geojson", str(path)],
                          capture_output=True, text=True)  # fmt: skip
    assert made.returncode == 0, made.stderr
    return json.loads(path.read_text())["features"]


def drag(path: Path, plan: dict) -> dict:
    """Moor DRAGGED OFFSET_M farther along the way the planned tour comes to it (so it stays in the camera's view:
    moved sideways it would be out of the frame); its properties."""
    document = json.loads(path.read_text())
    dragged_id = next(mark.id for mark in read_cell(CELL).marks if mark.name == DRAGGED)  # the world has ids only
    index = next(b["index"] for b in plan["buoys"] if b["register_id"] == dragged_id)
    local = {b["index"]: np.array([b["east_m"], b["north_m"]]) for b in plan["buoys"]}
    route = [np.zeros(2), *(local[i] for i in plan["order"])]
    before = route[plan["order"].index(index)]
    east, north = (local[index] - before) / math.dist(local[index], before)
    feature = next(f for f in document["features"] if f["properties"]["id"] == dragged_id)
    feature["properties"]["offset_m"] = [OFFSET_M * north, OFFSET_M * east]
    path.write_text(json.dumps(document))
    return feature["properties"]


def test_a_chart_fills_the_register_a_mission_inspects_its_buoys_and_their_history_keeps_it(stack, tmp_path):
    world = tmp_path / "world.geojson"
    features = chart_world(world)
    stack.start_gcs()  # first: a lockstep vehicle and its controller would spin on the ground while it starts
    area = ",".join(str(v) for v in AREA)
    imported = stack.api.post(f"/buoys/imports?filename=US4MD81M.000&area={area}", content=CELL.read_bytes())
    assert imported.status_code == 200, imported.text
    registered = sorted(imported.json()["created"])
    assert registered == sorted(f["properties"]["id"] for f in features)
    assert {f["properties"]["region"] for f in features} == {"B"}  # a US cell: port green, starboard red
    request = {"from_register": {"bbox": list(AREA)}, "depot": {"lat": DEPOT[0], "lon": DEPOT[1]}}
    planned = stack.api.post("/plans", json=request)  # the tour the mission will fly (the planner is seeded)
    assert planned.status_code == 200, planned.text
    moved = drag(world, planned.json())
    stack.start_vehicle("--home", f"{DEPOT[0]},{DEPOT[1]},0", "--world", str(world), "--image-dir",
                        str(tmp_path / "images"))  # fmt: skip
    stack.start_offboard()
    stack.wait_connected()

    mission_id = stack.fly(request)
    mission = stack.wait_mission(mission_id, lambda m: m["status"] in TERMINAL, timeout_s=FLIGHT_S)
    assert (mission["status"], mission["reason"]) == ("completed", None), mission["events"]
    assert sorted(b["register_id"] for b in mission["buoys"]) == registered
    assert mission["order"] == planned.json()["order"]

    inspections = stack.api.get(f"/missions/{mission_id}/inspections").json()
    assert {i["charted"]["region"] for i in inspections} == {"B"}  # colours checked as the chart's region has them
    verdicts = {}
    for register_id in registered:
        buoy = stack.api.get(f"/buoys/{register_id}").json()
        assert [event["kind"] for event in buoy["history"]][:2] == ["registered", "inspection"]
        assert buoy["latest_inspection"]["mission_id"] == mission_id and buoy["last_inspected_at"] is not None
        verdicts[register_id] = buoy["latest_inspection"]["verdict"]
        if register_id == moved["id"]:
            (defect,) = buoy["defects"]
            assert (defect["code"], defect["state"], defect["mission_id"]) == ("off_station", "open", mission_id)
            assert OFFSET_M - 2.0 < defect["finding"]["offset_m"] < OFFSET_M + 2.0
            assert buoy["history"][-1]["kind"] == "defect_opened"
        else:
            assert buoy["defects"] == [] and len(buoy["history"]) == 2
    assert verdicts == {register_id: "defect" if register_id == moved["id"] else "ok" for register_id in registered}
    (alarm,) = stack.api.get("/alarms").json()
    assert (alarm["buoy"], alarm["source"], alarm["mission_id"]) == (moved["id"], "inspection", mission_id)
    # inspected today: none of them is overdue any more
    assert stack.api.get("/buoys", params={"bbox": area, "overdue_days": 1}).json() == []
