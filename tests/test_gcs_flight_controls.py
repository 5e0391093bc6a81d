"""The operator's commands in flight (hold, resume, return, land) without a vehicle: each command's mode on PX4 and
ArduPilot Copter, the flight-time budget under a command, where a resume flies on from, how a returned or landed
mission's reason reads, and the answers to a mission that is not flying (409 in the one error shape, naming a
fleet's parts), an unknown one (404) and a request without the token (401).

Flown against the vehicles: tests/test_e2e_flight_controls.py (the simulated PX4 with its offboard controller) and
tests/test_gcs_ardupilot.py (the ArduCopter double)."""

from __future__ import annotations

from types import SimpleNamespace

import pytest
from stored_missions import FLIGHT, PLAN
from test_gcs_api import make_client

from gcs.domain.planning import FIRST_BUOY_SEQ, INSPECTION_GROUP, MissionLayout
from gcs.domain.status import MissionStatus
from gcs.missions.lifecycle import (
    COMMAND_PURPOSES,
    LANDED_BY_OPERATOR,
    RETURNED_BY_OPERATOR,
    budget_step,
    operator_end,
)
from gcs.missions.recorder import MissionRecorder
from gcs.storage import open_storage
from gcs.vehicle.autopilots import ArduCopter, Px4
from gcs.vehicle.link import LinkManager

COMMANDS = ("hold", "resume", "return", "land")


def test_each_command_is_the_autopilots_own_mode_on_px4_and_arducopter():
    px4, copter = Px4(), ArduCopter()
    assert {c: px4.mode_name(px4.custom_mode(COMMAND_PURPOSES[c])) for c in COMMANDS} == {
        "hold": "AUTO.LOITER",
        "resume": "AUTO.MISSION",
        "return": "AUTO.RTL",
        "land": "AUTO.LAND",
    }
    # ArduCopter's mode numbers (ArduCopter/mode.h): LOITER 5, AUTO 3, RTL 6, LAND 9
    assert {c: copter.custom_mode(COMMAND_PURPOSES[c]) for c in COMMANDS} == {
        "hold": 5,
        "resume": 3,
        "return": 6,
        "land": 9,
    }
    assert {c: copter.mode_name(copter.custom_mode(COMMAND_PURPOSES[c])) for c in COMMANDS} == {
        "hold": "LOITER",
        "resume": "AUTO",
        "return": "RTL",
        "land": "LAND",
    }


def test_the_budget_counts_no_held_or_landing_time_and_gives_a_return_its_way_back_out():
    assert budget_step(2.0, None) == 2.0
    assert budget_step(2.0, "hold") == 0.0
    assert budget_step(2.0, "land") == 0.0
    # 10 s flown, 5 s held, 4 s returning, resumed: 10 s counted, 4 s of the way back out not
    steps = [(10.0, None), (5.0, "hold"), (4.0, "return"), (4.0, None)]
    assert sum(budget_step(step, command) for step, command in steps) == pytest.approx(10.0)


@pytest.mark.parametrize("inspected", [False, True])
def test_a_resume_flies_on_from_the_first_item_of_the_first_buoy_not_visited(inspected):
    recorder = MissionRecorder(LinkManager(), PLAN, 0.1, 2.0)  # PLAN visits buoy 1, then buoy 0
    recorder.layout = MissionLayout(2, inspected)
    group = INSPECTION_GROUP if inspected else 1
    assert recorder.resume_point() == (FIRST_BUOY_SEQ, 1)
    recorder.visited = {1}
    assert recorder.resume_point() == (FIRST_BUOY_SEQ + group, 0)
    recorder.visited = {0}  # the second visited on the way to the first (they are close): the first is still due
    assert recorder.resume_point() == (FIRST_BUOY_SEQ, 1)
    recorder.visited = {0, 1}
    assert recorder.resume_point() == (FIRST_BUOY_SEQ + 2 * group, None)  # the way home


def test_a_returned_or_landed_mission_ends_aborted_naming_what_was_not_inspected():
    recorder = SimpleNamespace(not_inspected=lambda: ["B3", "B7"])
    returned = operator_end(recorder, "return")  # type: ignore[arg-type]
    assert returned.status == MissionStatus.ABORTED
    assert returned.reason == f"{RETURNED_BY_OPERATOR}; 2 buoys not inspected (B3, B7)"
    landed = operator_end(SimpleNamespace(not_inspected=lambda: ["B3"]), "land")  # type: ignore[arg-type]
    assert landed.reason == f"{LANDED_BY_OPERATOR}; 1 buoy not inspected (B3)"


@pytest.fixture
def stored(tmp_path):
    """A planned mission and a planned fleet mission of two parts, and the service over them (no vehicle)."""
    storage = open_storage(tmp_path / "gcs.sqlite")
    planned = storage.create_mission(FLIGHT, PLAN)
    fleet, parts = storage.create_fleet_mission(FLIGHT, PLAN, [(FLIGHT, PLAN, 1), (FLIGHT, PLAN, 2)])
    storage.close()
    with make_client(tmp_path) as client:
        yield client, planned, fleet, parts


@pytest.mark.parametrize("command", COMMANDS)
def test_a_mission_not_in_the_air_is_a_409_and_a_fleet_mission_names_its_parts(stored, command):
    client, planned, fleet, parts = stored
    response = client.post(f"/missions/{planned}/{command}")
    assert response.status_code == 409, response.text
    (problem,) = response.json()["detail"]
    assert (problem["type"], problem["loc"]) == ("conflict", [])
    assert problem["msg"] == f"mission {planned} is planned, not in the air: nothing to {command}"
    assert client.get(f"/missions/{planned}").json()["progress"]["command"] is None
    response = client.post(f"/missions/{fleet}/{command}")
    assert response.status_code == 409
    msg = response.json()["detail"][0]["msg"]
    assert msg.startswith(f"mission {fleet} is a fleet mission: a fleet's parts are commanded one by one"), msg
    assert f"POST /missions/{{part}}/{command}; its parts: {parts[0]}, {parts[1]})" in msg
    assert client.post(f"/missions/9999/{command}").status_code == 404


def test_the_commands_need_the_token_and_are_linked_from_a_new_mission(tmp_path):
    with make_client(tmp_path, token="s3cret") as client:
        for command in COMMANDS:
            response = client.post(f"/missions/1/{command}")
            assert response.status_code == 401 and response.headers["www-authenticate"] == "Bearer"
        document = client.get("/openapi.json").json()
    links = document["paths"]["/missions"]["post"]["responses"]["201"]["links"]
    for command in COMMANDS:
        operation = document["paths"][f"/missions/{{mission_id}}/{command}"]["post"]
        assert operation["operationId"] == f"{command}_mission" and f"{command}_mission" in links
        assert {"200", "401", "404", "409", "502", "503"} <= set(operation["responses"])
