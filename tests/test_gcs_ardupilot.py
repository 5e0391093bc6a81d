"""Integration: the ground station flies ArduPilot Copter (its ArduCopter flavour) against a scripted double.

No ArduPilot SITL binary can be installed here, so `tests/ardupilot_double.py` plays ArduCopter as its sources
describe it (see its docstring): Copter mode numbers, REQUEST_DATA_STREAM streams only, item 0 = home, takeoff in
GUIDED then AUTO, MISSION_START with first/last item 0 only. The double runs in a thread of the test process on
its own UDP socket and sends to the service's `udpin` port, as SITL does to a GCS. Each test picks a free port;
every wait polls a condition against a generous deadline.
"""

from __future__ import annotations

import asyncio
import contextlib
import json
import math
import time
from collections.abc import AsyncIterator, Callable, Iterator
from pathlib import Path

import numpy as np
import pytest
from ardupilot_double import ArduCopterDouble
from fastapi.testclient import TestClient

from bench.processes import free_udp_port
from gcs.api.app import create_app
from gcs.domain.planning import FIRST_BUOY_SEQ, FlightParams, make_plan, mission_items
from gcs.missions.lifecycle import LANDED_BY_OPERATOR
from gcs.settings import Settings
from gcs.vehicle.autopilots import ArduCopter
from gcs.vehicle.link import LinkManager
from planner.scenario import ALTITUDE_M, CRUISE_SPEED_M_S, reference_scenario
from uavcore.mavlink import mavlink
from uavcore.mission import MavCmd, MissionItem

pytestmark = [pytest.mark.integration, pytest.mark.slow, pytest.mark.timeout(600)]

CONNECT_S = 60.0  # the service hearing the double, or a mission reaching "flying": a backstop on a loaded machine
FLIGHT_S = 300.0
ACCEPTANCE_RADIUS_M = 2.0
DWELL_S = 0.5
SCENARIO = reference_scenario()
BUOY_IDS = [f"B{i + 1}" for i in range(len(SCENARIO.buoys_lat_lon))]
FEW_BUOYS = 4  # the service tests fly the first few buoys: about a kilometre
RETURNED = "aborted by the operator: returned to the depot"


@pytest.fixture
def start_double(tmp_path) -> Iterator[Callable[[int], ArduCopterDouble]]:
    started: list[ArduCopterDouble] = []

    def start(gcs_port: int) -> ArduCopterDouble:
        started.append(ArduCopterDouble(gcs_port, items_out=tmp_path / f"received-{gcs_port}.json").start())
        return started[-1]

    yield start
    for double in started:
        double.stop()


def planned_items() -> list[MissionItem]:
    """The reference scenario's 13 buoys, planned and laid out as the service does."""
    plan = make_plan(SCENARIO.depot_lat_lon, [tuple(p) for p in SCENARIO.buoys_lat_lon], BUOY_IDS)
    return mission_items(plan, FlightParams(ALTITUDE_M, CRUISE_SPEED_M_S, DWELL_S, ACCEPTANCE_RADIUS_M))


def on_the_wire(item: MissionItem, seq: int) -> tuple:
    """The item's fields as MISSION_ITEM_INT carries them (float32 params and z; NaN as a marker), renumbered."""

    def wire(value: object) -> object:
        if not isinstance(value, float):
            return value
        return "NaN" if math.isnan(value) else float(np.float32(value))

    fields = {**vars(item), "seq": seq, "current": 0}
    return tuple(wire(value) for value in fields.values())


def received_items(path: Path) -> list[MissionItem]:
    return [MissionItem(**fields) for fields in json.loads(path.read_text())]


async def wait_until(condition: Callable[[], bool], timeout_s: float, what: str) -> None:
    deadline = time.monotonic() + timeout_s
    while not condition():
        assert time.monotonic() < deadline, f"{what} not within {timeout_s:g} s"
        await asyncio.sleep(0.05)


@contextlib.asynccontextmanager
async def connected_link(start_double) -> AsyncIterator[tuple[LinkManager, ArduCopterDouble]]:
    """A link on a free port with a double talking to it, once the double's heartbeat is seen."""
    port = free_udp_port()
    link = LinkManager(f"udpin://127.0.0.1:{port}", heartbeat_timeout_s=5.0)
    await link.start()
    double = start_double(port)
    try:
        assert await link.wait_connected(CONNECT_S), "no heartbeat from the ArduCopter double"
        yield link, double
    finally:
        await link.stop()


# ----- the link alone


async def link_session(start_double) -> None:
    async with connected_link(start_double) as (link, double):
        assert (link.status.autopilot, link.status.vehicle_type) == ("ARDUPILOTMEGA", "QUADROTOR")
        assert isinstance(link.autopilot, ArduCopter)
        assert link.status.mode == "STABILIZE"

        # streams come only because the link fell back to REQUEST_DATA_STREAM after the refusals
        await wait_until(lambda: link.status.lat is not None, 30.0, "GLOBAL_POSITION_INT")
        await wait_until(lambda: link.status.home is not None, 30.0, "HOME_POSITION")
        await wait_until(lambda: link.status.landed_state is not None, 30.0, "EXTENDED_SYS_STATE")
        assert double.set_message_interval_refusals > 0
        assert (mavlink.MAV_DATA_STREAM_ALL, 10, 1) in double.data_stream_requests
        assert link.status.home[:2] == pytest.approx(SCENARIO.home[:2], abs=1e-7)
        assert link.status.on_ground and not link.status.armed

        items = planned_items()
        await link.upload_mission(items, SCENARIO.home)
        stored = received_items(double.items_out)
        assert len(stored) == len(items) + 1
        home_item = stored[0]
        assert (home_item.command, home_item.x, home_item.y) == (
            MavCmd.NAV_WAYPOINT,
            round(SCENARIO.home[0] * 1e7),
            round(SCENARIO.home[1] * 1e7),
        )
        assert [on_the_wire(i, i.seq) for i in stored[1:]] == [on_the_wire(i, i.seq + 1) for i in items]
        downloaded = await link.download_mission()
        assert [on_the_wire(i, i.seq) for i in downloaded] == [on_the_wire(i, i.seq) for i in items]
        # MISSION_CURRENT.total excludes ArduPilot's home item: the planned count
        await wait_until(lambda: link.status.mission_total == len(items), 10.0, "MISSION_CURRENT with the new total")


def test_the_link_speaks_arducopter_streams_by_request_data_stream_and_shifts_the_mission(start_double):
    asyncio.run(link_session(start_double))


async def mission_start_refusals(start_double) -> None:
    """What the double refuses, as ArduCopter does: arming in AUTO, MISSION_START naming first/last items."""
    async with connected_link(start_double) as (link, double):
        await link.upload_mission(planned_items(), SCENARIO.home)
        await link.set_mode("mission")
        await wait_until(lambda: link.status.mode == "AUTO", 10.0, "AUTO in the heartbeat")
        result = await link.command_long(mavlink.MAV_CMD_COMPONENT_ARM_DISARM, [1])
        assert result == mavlink.MAV_RESULT_FAILED
        result = await link.command_long(mavlink.MAV_CMD_MISSION_START, [1, len(planned_items())])
        assert result == mavlink.MAV_RESULT_DENIED
        assert not double.armed


def test_the_double_refuses_what_arducopter_refuses(start_double):
    asyncio.run(mission_start_refusals(start_double))


# ----- the whole service


def post_mission(client: TestClient, n_buoys: int) -> int:
    buoys = [
        {"id": i, "lat": lat, "lon": lon}
        for i, (lat, lon) in list(zip(BUOY_IDS, SCENARIO.buoys_lat_lon, strict=True))[:n_buoys]
    ]
    created = client.post(
        "/missions", json={"buoys": buoys, "acceptance_radius_m": ACCEPTANCE_RADIUS_M, "dwell_s": DWELL_S}
    )
    assert created.status_code == 201, created.text
    return created.json()["id"]


def wait_for_mission(client: TestClient, mission_id: int, done: Callable[[dict], bool], timeout_s: float) -> dict:
    deadline = time.monotonic() + timeout_s
    while not done(mission := client.get(f"/missions/{mission_id}").json()):
        assert time.monotonic() < deadline, f"mission still {mission['status']}: {mission['progress']}"
        time.sleep(0.2)
    return mission


def ended(mission: dict) -> bool:
    """Finished for good: an aborted mission is "aborted" already while returning, so its reason says when."""
    return mission["status"] in ("completed", "failed") or mission["reason"] == RETURNED


def flying(mission: dict) -> bool:
    return mission["status"] == "flying"


@contextlib.contextmanager
def service_with_a_mission(tmp_path: Path, start_double) -> Iterator[tuple[TestClient, ArduCopterDouble, int]]:
    """The service on a free port, a double talking to it, and a mission over the first few buoys posted."""
    port = free_udp_port()
    settings = Settings(db_path=tmp_path / "gcs.sqlite", vehicle_url=f"udpin://127.0.0.1:{port}", vehicle_wait_s=60.0)
    with TestClient(create_app(settings)) as client:
        double = start_double(port)
        deadline = time.monotonic() + CONNECT_S
        while not client.get("/vehicle").json()["connected"]:
            assert time.monotonic() < deadline, "the service never saw the ArduCopter double"
            time.sleep(0.2)
        yield client, double, post_mission(client, FEW_BUOYS)


def test_the_service_flies_a_mission_on_arducopter(tmp_path, start_double):
    with service_with_a_mission(tmp_path, start_double) as (client, double, mission_id):
        mission = wait_for_mission(client, mission_id, ended, FLIGHT_S)
        assert (mission["status"], mission["reason"]) == ("completed", None)
        assert len(mission["buoy_results"]) == FEW_BUOYS
        assert all(r["reached"] and r["closest_m"] <= ACCEPTANCE_RADIUS_M for r in mission["buoy_results"])
        assert mission["progress"]["visited"] == FEW_BUOYS
        # armed in GUIDED, took off there, flew the mission in AUTO; ended landed and disarmed at home
        assert double.mode_history == ["STABILIZE", "GUIDED", "AUTO"]
        assert double.mission_state == mavlink.MISSION_STATE_COMPLETE
        assert double.landed and not double.armed
        assert (double.north, double.east) == pytest.approx((0.0, 0.0), abs=0.01)
        stored = received_items(double.items_out)
        assert stored[0].command == MavCmd.NAV_WAYPOINT and stored[-1].command == MavCmd.NAV_RETURN_TO_LAUNCH
        state = client.get("/vehicle").json()
        assert state["connected"] and not state["armed"] and state["reboots"] == 0


def test_an_aborted_mission_returns_the_arducopter_home(tmp_path, start_double):
    with service_with_a_mission(tmp_path, start_double) as (client, double, mission_id):
        wait_for_mission(client, mission_id, flying, CONNECT_S)
        deadline = time.monotonic() + FLIGHT_S
        while math.hypot(double.north, double.east) < 100.0:  # well on its way to the first buoy
            assert time.monotonic() < deadline, "the double never left home"
            time.sleep(0.1)
        aborted = client.post(f"/missions/{mission_id}/abort")
        assert aborted.status_code in (200, 202), aborted.text
        mission = wait_for_mission(client, mission_id, ended, FLIGHT_S)
        assert (mission["status"], mission["reason"]) == ("aborted", RETURNED)
        assert double.mode_history == ["STABILIZE", "GUIDED", "AUTO", "RTL"]
        assert double.landed and not double.armed
        assert (double.north, double.east) == pytest.approx((0.0, 0.0), abs=0.01)
        assert mission["progress"]["visited"] < FEW_BUOYS


def test_the_operator_holds_returns_resumes_and_lands_the_arducopter_in_its_own_modes(tmp_path, start_double):
    """Hold is LOITER, return RTL, land LAND and a resume AUTO from the first buoy not visited
    (DO_SET_MISSION_CURRENT in ArduPilot's numbering, home being item 0); landed, the mission ends aborted."""
    with service_with_a_mission(tmp_path, start_double) as (client, double, mission_id):
        wait_for_mission(client, mission_id, lambda m: m["progress"]["visited"] >= 1, FLIGHT_S)

        def command(what: str, mode: str) -> None:
            answer = client.post(f"/missions/{mission_id}/{what}")
            assert answer.status_code == 200, answer.text
            deadline = time.monotonic() + CONNECT_S
            while client.get("/vehicle").json()["mode"] != mode:
                assert time.monotonic() < deadline, f"the double never in {mode}: {double.mode_history}"
                time.sleep(0.1)

        def resume() -> None:
            mission = client.get(f"/missions/{mission_id}").json()
            visited = mission["progress"]["visited_buoys"]
            position = next(p for p, b in enumerate(mission["order"]) if b not in visited)
            command("resume", "AUTO")
            # the buoy's waypoint: the planned item FIRST_BUOY_SEQ + position, one up on board behind home
            assert double.current_requests[-1] == FIRST_BUOY_SEQ + position + 1, (double.current_requests, position)
            after = wait_for_mission(client, mission_id, lambda m: m["progress"]["visited_buoys"] != visited, FLIGHT_S)
            assert set(after["progress"]["visited_buoys"]) == {*visited, mission["order"][position]}

        command("hold", "LOITER")
        assert double.velocity == (0.0, 0.0, 0.0) and not double.landed
        resume()
        command("return", "RTL")
        resume()
        command("land", "LAND")
        mission = wait_for_mission(client, mission_id, lambda m: m["status"] in ("completed", "failed", "aborted"),
                                   FLIGHT_S)  # fmt: skip
        assert mission["status"] == "aborted" and mission["reason"].startswith(LANDED_BY_OPERATOR), mission
        assert double.mode_history == ["STABILIZE", "GUIDED", "AUTO", "LOITER", "AUTO", "RTL", "AUTO", "LAND"]
        assert double.landed and not double.armed
