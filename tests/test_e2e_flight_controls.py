"""End to end: the operator's hold, resume, return and land, flown by the whole stack (the simulated PX4 in lockstep,
its offboard controller flying the mission in OFFBOARD, the service driven through its REST API), each seen in
the vehicle's mode as the service reports it (GET /vehicle). Deadlines are backstops against a hang; what is
measured runs on the vehicle's simulated time (GET /vehicle's `t_s`).
"""

from __future__ import annotations

import math
from collections.abc import Iterator

import pytest
from test_e2e_stack import (
    FLIGHT_S,
    TERMINAL,
    WAIT_S,
    Stack,
    assert_landed_at_depot,
    near_buoys,
    running_stack,
    wait_until,
)

from gcs.domain.planning import FIRST_BUOY_SEQ
from gcs.missions.lifecycle import CLIMB_RATE_M_S, LANDED_BY_OPERATOR, RETURNED_BY_OPERATOR

pytestmark = [pytest.mark.integration, pytest.mark.slow, pytest.mark.timeout(1500)]

IN_MISSION = ("OFFBOARD", "AUTO.MISSION")  # the mission mode, and the offboard controller's once it takes over
HOLD_SETTLE_S = 3.0  # simulated seconds for the vehicle to brake to a stop in its hold
HOLD_WATCH_S = 6.0  # simulated seconds the held vehicle is watched
HOLD_DRIFT_M = 2.0  # how far a held vehicle may move (wind and turbulence)
SEQ_REPORT_S = 1.0  # simulated seconds for the vehicle's MISSION_CURRENT (2 Hz) to report a new item
LANDED_WITHIN_M = 25.0  # from where the vehicle was as its landing began


@pytest.fixture
def stack(tmp_path) -> Iterator[Stack]:
    yield from running_stack(tmp_path)


def command(stack: Stack, mission_id: int, what: str) -> dict:
    response = stack.api.post(f"/missions/{mission_id}/{what}")
    assert response.status_code == 200, response.text
    return response.json()


def wait_mode(stack: Stack, *modes: str) -> dict:
    return wait_until(
        lambda: (v := stack.api.get("/vehicle").json())["mode"] in modes and v,
        WAIT_S,
        lambda: f"the vehicle never in {modes}: {stack.api.get('/vehicle').json()['mode']}",
    )


def wait_vehicle_time(stack: Stack, t_s: float, seen: list[dict] | None = None) -> dict:
    """The vehicle's state once its simulated time reaches t_s; every state read on the way into `seen`."""

    def probe() -> dict | None:
        vehicle = stack.api.get("/vehicle").json()
        if seen is not None:
            seen.append(vehicle)
        return vehicle if vehicle["t_s"] >= t_s else None

    return wait_until(probe, WAIT_S, f"the vehicle's time never reached {t_s} s")


def resume_and_see_the_next_buoy(stack: Stack, mission_id: int) -> dict:
    """Resume: the mission mode comes back, the vehicle's current item from then on is never before the first buoy
    not visited, and the next buoy visited is that one (the mission read once one is: a poll may find the ones
    after it visited too, never one before it skipped)."""
    before = stack.mission(mission_id)
    visited = set(before["progress"]["visited_buoys"])
    remaining = [b for b in before["order"] if b not in visited]
    resumed_at = stack.api.get("/vehicle").json()["t_s"]
    resumed = command(stack, mission_id, "resume")
    assert resumed["status"] == "flying" and resumed["progress"]["command"] is None, resumed["progress"]
    texts = [e["text"] for e in resumed["progress"]["vehicle_events"]]
    assert f"operator: resume from buoy {before['buoys'][remaining[0]]['id']}" in texts, texts
    wait_mode(stack, *IN_MISSION)
    mission = stack.wait_mission(
        mission_id, lambda m: set(m["progress"]["visited_buoys"]) != visited, timeout_s=FLIGHT_S
    )
    new = set(mission["progress"]["visited_buoys"]) - visited
    assert new == set(remaining[: len(new)]), (remaining, mission["progress"])
    # one waypoint a buoy (the vehicle has no camera): the first not visited is item FIRST_BUOY_SEQ + its position
    first_seq = FIRST_BUOY_SEQ + before["order"].index(remaining[0])
    samples = stack.api.get(f"/missions/{mission_id}/telemetry").json()
    seqs = [s["mission_seq"] for s in samples if s["t_s"] > resumed_at + SEQ_REPORT_S and s["mission_seq"] is not None]
    assert seqs and min(seqs) >= first_seq, (first_seq, seqs)
    return mission


def far_enough(stack: Stack, metres: float) -> dict:
    return wait_until(
        lambda: math.hypot((v := stack.api.get("/vehicle").json())["north"] or 0, v["east"] or 0) > metres and v,
        FLIGHT_S,
        f"the vehicle never {metres} m from the depot",
    )


def test_a_mission_held_resumed_and_returned_ends_aborted_at_the_depot_and_another_returned_resumed_and_landed(stack):
    stack.start_gcs()
    stack.start_vehicle()
    stack.start_offboard()
    stack.wait_connected()
    request = near_buoys(4)
    first = stack.fly(request)
    stack.wait_mission(first, lambda m: m["progress"].get("visited", 0) >= 1, timeout_s=FLIGHT_S)

    # hold: the vehicle's hold mode, where it is; the mission flying, its progress naming the command
    held = command(stack, first, "hold")
    assert held["status"] == "flying" and held["progress"]["command"] == "hold", held["progress"]
    seen = wait_mode(stack, "AUTO.LOITER")
    settled = wait_vehicle_time(stack, seen["t_s"] + HOLD_SETTLE_S)
    visited_held = stack.mission(first)["progress"]["visited_buoys"]
    watched: list[dict] = []
    wait_vehicle_time(stack, settled["t_s"] + HOLD_WATCH_S, watched)
    drift = max(math.hypot(v["north"] - settled["north"], v["east"] - settled["east"]) for v in watched)
    assert drift <= HOLD_DRIFT_M, (drift, settled, watched[-1])
    assert all(v["mode"] == "AUTO.LOITER" and v["armed"] for v in watched), watched[-1]
    mission = stack.mission(first)
    assert mission["status"] == "flying" and mission["progress"]["visited_buoys"] == visited_held

    # resume: back in the mission, on to the first buoy not visited
    resume_and_see_the_next_buoy(stack, first)

    # return: RTL, resumable until landed; landed at the depot, the mission ends aborted naming what is left
    returning = command(stack, first, "return")
    assert returning["progress"]["command"] == "return", returning["progress"]
    wait_mode(stack, "AUTO.RTL")
    mission = stack.wait_mission(first, lambda m: m["status"] in TERMINAL, timeout_s=FLIGHT_S)
    missing = [request["buoys"][b]["id"] for b in mission["order"] if b not in mission["progress"]["visited_buoys"]]
    assert missing, mission["progress"]  # the return cut the tour short
    assert mission["status"] == "aborted", mission
    assert mission["reason"] == (
        f"{RETURNED_BY_OPERATOR}; {len(missing)} buoy{'s' if len(missing) > 1 else ''} not inspected "
        f"({', '.join(missing)})"
    )
    texts = [e["text"] for e in mission["progress"]["vehicle_events"]]
    operator = [t for t in texts if t.startswith("operator: ")]
    assert operator[0] == "operator: hold" and operator[2] == "operator: return", operator
    assert operator[1].startswith("operator: resume from buoy "), operator
    assert "mode OFFBOARD -> AUTO.LOITER" in texts and "mode AUTO.LOITER -> AUTO.MISSION" in texts, texts
    reasons = [e["reason"] for e in mission["events"] if e["status"] == "flying"]
    assert "operator: hold" in reasons and "operator: return" in reasons, reasons
    assert_landed_at_depot(stack, 3.0)
    assert command_refused(stack, first, "resume") == f"mission {first} is aborted, not in the air: nothing to resume"

    # another mission: returned, resumed on the way home, then landed where it was
    second = stack.fly(request)
    stack.wait_mission(second, lambda m: m["status"] == "flying", timeout_s=WAIT_S)
    far_enough(stack, 30.0)
    command(stack, second, "return")
    wait_mode(stack, "AUTO.RTL")
    assert command_refused(stack, second, "return") is None  # a command repeated is sent again, harmlessly
    resume_and_see_the_next_buoy(stack, second)
    landing = command(stack, second, "land")
    assert landing["progress"]["command"] == "land", landing["progress"]
    where = wait_mode(stack, "AUTO.LAND")
    assert (
        command_refused(stack, second, "resume")
        == f"mission {second} has nothing to resume: it is landing where it was"
    )
    mission = stack.wait_mission(second, lambda m: m["status"] in TERMINAL, timeout_s=FLIGHT_S)
    assert mission["status"] == "aborted" and mission["reason"].startswith(f"{LANDED_BY_OPERATOR}; "), mission
    vehicle = stack.api.get("/vehicle").json()
    assert not vehicle["armed"] and vehicle["mode"] != "AUTO.RTL", vehicle
    # down where it was: within the braking distance from cruise speed (10 m/s at 3 m/s^2: 17 m), no return
    assert math.hypot(vehicle["north"] - where["north"], vehicle["east"] - where["east"]) < LANDED_WITHIN_M, vehicle
    texts = [e["text"] for e in mission["progress"]["vehicle_events"]]
    after_land = texts[texts.index("operator: land") :]
    assert "mode AUTO.RTL -> AUTO.MISSION" in texts and not any("-> AUTO.RTL" in t for t in after_land), texts
    assert mission["progress"]["command"] == "land"


def command_refused(stack: Stack, mission_id: int, what: str) -> str | None:
    """The 409's message for a command, or None when it was taken."""
    response = stack.api.post(f"/missions/{mission_id}/{what}")
    if response.status_code == 200:
        return None
    assert response.status_code == 409, response.text
    return response.json()["detail"][0]["msg"]


def test_a_hold_longer_than_the_whole_flight_time_budget_neither_fails_the_mission_nor_keeps_it_from_completing(
    stack, monkeypatch
):
    """Held time is not flight time: a mission held for longer than its whole budget (gcs.missions.lifecycle
    .flight_budget_s, with a 60 s margin here) flies on when resumed and completes."""
    margin_s = 60.0
    monkeypatch.setenv("BUOY_GCS_MISSION_TIMEOUT_MARGIN_S", str(margin_s))
    stack.start_gcs()
    stack.start_vehicle()
    stack.start_offboard()
    stack.wait_connected()
    request = near_buoys(3)
    mission_id = stack.fly(request)
    mission = stack.wait_mission(mission_id, lambda m: m["progress"].get("visited", 0) >= 1, timeout_s=FLIGHT_S)
    budget_s = (
        mission["length_m"] / request["speed_m_s"]
        + len(request["buoys"]) * request["dwell_s"]
        + 2 * request["altitude_m"] / CLIMB_RATE_M_S
        + margin_s
    )
    command(stack, mission_id, "hold")
    held = wait_mode(stack, "AUTO.LOITER")
    wait_vehicle_time(stack, held["t_s"] + budget_s + 5.0)
    assert stack.mission(mission_id)["status"] == "flying"
    resume_and_see_the_next_buoy(stack, mission_id)
    mission = stack.wait_mission(mission_id, lambda m: m["status"] in TERMINAL, timeout_s=FLIGHT_S)
    assert (mission["status"], mission["reason"]) == ("completed", None), mission["events"]
    assert mission["progress"]["visited"] == 3 and mission["progress"]["command"] is None
    assert_landed_at_depot(stack, request["acceptance_radius_m"])
