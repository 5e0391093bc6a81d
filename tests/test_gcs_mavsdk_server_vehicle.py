"""The ground station against a vehicle nobody here wrote: MAVSDK's server plugins (tests/mavsdk_server_vehicle.py).

MAVSDK 4.1's MissionRawServer, ActionServer, TelemetryServer and ParamServer speak the protocols; the double only
moves in straight lines between the items it was given. It pushes its MAVLink to the service's `udpin` port, as
PX4 SITL does to QGroundControl on 14550. Each test picks free ports; every wait polls a condition against a
generous deadline.

What MAVSDK's autopilot does differently from PX4, and the link copes with: its heartbeat says autopilot GENERIC
(so the link speaks PX4 to it); MISSION_CURRENT comes only when the item changes, without `total`, and after the
last item says seq = number of items; SET_MESSAGE_INTERVAL is acknowledged but changes no rate.
"""

from __future__ import annotations

import asyncio
import json
import math
import time
from collections.abc import Callable, Iterator
from pathlib import Path

import numpy as np
import pytest
from fastapi.testclient import TestClient
from peer_process import PeerProcess, peers_stopped_cleanly
from sitl_process import REPO

from bench.processes import free_udp_port
from gcs.api.app import create_app
from gcs.domain.planning import FlightParams, make_plan, mission_items
from gcs.settings import Settings
from gcs.vehicle.link import LinkManager
from planner.scenario import ALTITUDE_M, CRUISE_SPEED_M_S, reference_scenario
from uavcore.geodesy import LocalFrame
from uavcore.mavlink import mavlink
from uavcore.mission import MissionItem

pytestmark = [pytest.mark.integration, pytest.mark.slow, pytest.mark.timeout(600)]

VEHICLE_SCRIPT = REPO / "tests" / "mavsdk_server_vehicle.py"
SPEED_M_S = 100.0  # the double's speed: the 3 km reference tour in about 30 s of wall clock (+ 13 s of dwells)
CONNECT_S = 60.0
FLIGHT_S = 400.0
ACCEPTANCE_RADIUS_M = 2.0
DWELL_S = 1.0
ON_GROUND = mavlink.MAV_LANDED_STATE_ON_GROUND
SCENARIO = reference_scenario()
BUOY_IDS = [f"B{i + 1}" for i in range(len(SCENARIO.buoys_lat_lon))]


class MavsdkVehicle(PeerProcess):
    """The double as a process, pushing MAVLink to 127.0.0.1:port; the items it received land in `items_path`."""

    def __init__(self, directory: Path, port: int, extra_args: tuple[str, ...] = ()) -> None:
        self.items_path = directory / f"received-items-{port}.json"
        args = ["--connect", f"udpout://127.0.0.1:{port}", "--items-out", str(self.items_path)]
        args += ["--speed", str(SPEED_M_S), *extra_args]
        super().__init__(directory, VEHICLE_SCRIPT, *args, log_name=f"mavsdk-vehicle-{port}.log")

    def received_items(self, timeout_s: float = 30.0) -> list[MissionItem]:
        deadline = time.monotonic() + timeout_s
        while not self.items_path.exists():
            assert time.monotonic() < deadline, f"the vehicle wrote no mission items:\n{self.log()}"
            time.sleep(0.1)
        return [MissionItem(**fields) for fields in json.loads(self.items_path.read_text())]

    def log(self) -> str:
        return super().log()[-3000:]


@pytest.fixture
def start_vehicle(tmp_path) -> Iterator[Callable[..., MavsdkVehicle]]:
    """start_vehicle(port, *extra_args); each vehicle must exit cleanly on SIGTERM, without a traceback."""
    started: list[MavsdkVehicle] = []

    def start(port: int, *extra_args: str) -> MavsdkVehicle:
        started.append(MavsdkVehicle(tmp_path, port, extra_args))
        return started[-1]

    yield start
    peers_stopped_cleanly(started)


def planned_items() -> list[MissionItem]:
    """The reference scenario's 13 buoys, planned and laid out as the service does."""
    plan = make_plan(SCENARIO.depot_lat_lon, [tuple(p) for p in SCENARIO.buoys_lat_lon], BUOY_IDS)
    return mission_items(plan, FlightParams(ALTITUDE_M, CRUISE_SPEED_M_S, DWELL_S, ACCEPTANCE_RADIUS_M))


def as_on_the_wire(item: MissionItem) -> tuple:
    """The item's fields as MISSION_ITEM_INT carries them: params and z are float32 there (NaN as a marker,
    since NaN != NaN)."""

    def wire(value: object) -> object:
        if not isinstance(value, float):
            return value
        return "NaN" if math.isnan(value) else float(np.float32(value))

    return tuple(wire(value) for value in vars(item).values())


def distances_to_buoys_m(track: list[tuple[float, float]]) -> np.ndarray:
    """For each buoy, how close the track came (metres)."""
    frame = LocalFrame(*SCENARIO.home)
    track_local = frame.project(np.asarray(track))
    buoys_local = frame.project(SCENARIO.buoys_lat_lon)
    return np.min(np.linalg.norm(buoys_local[:, None, :] - track_local[None, :, :], axis=2), axis=1)


async def wait_until(condition: Callable[[], bool], timeout_s: float, what: str) -> None:
    deadline = time.monotonic() + timeout_s
    while not condition():
        assert time.monotonic() < deadline, f"{what} not within {timeout_s:g} s"
        await asyncio.sleep(0.05)


# ----- the link alone


async def fly_with_the_link(start_vehicle) -> None:
    port = free_udp_port()
    link = LinkManager(f"udpin://127.0.0.1:{port}", heartbeat_timeout_s=5.0)
    await link.start()
    vehicle = start_vehicle(port)
    try:
        assert await link.wait_connected(CONNECT_S), f"no heartbeat from the MAVSDK vehicle:\n{vehicle.log()}"
        # MAVSDK's autopilot heartbeat: autopilot GENERIC (it never claims PX4), our MAV_TYPE, system 1 component 1
        assert (link.vehicle.sysid, link.vehicle.compid) == (1, 1)
        assert (link.status.autopilot, link.status.vehicle_type) == ("GENERIC", "QUADROTOR")
        await wait_until(lambda: link.status.home is not None, 30.0, "HOME_POSITION")
        assert link.status.home[:2] == pytest.approx(SCENARIO.home[:2], abs=1e-7)

        items = planned_items()
        assert len(items) == 16  # takeoff, speed, 13 buoys, return
        await link.upload_mission(items, SCENARIO.home)
        received = vehicle.received_items()
        assert len(received) == len(items)
        for planned, got in zip(items, received, strict=True):
            assert as_on_the_wire(got) == as_on_the_wire(planned), (planned, got)
        # MissionRawServer serves the same mission back
        assert [as_on_the_wire(i) for i in await link.download_mission()] == [as_on_the_wire(i) for i in items]

        reached: list[int] = []
        link.add_listener(lambda m: reached.append(m.seq) if m.get_type() == "MISSION_ITEM_REACHED" else None)
        await link.arm()
        await wait_until(lambda: link.status.armed, 10.0, "the heartbeat showing the vehicle armed")
        await link.start_mission(items)

        track: list[tuple[float, float]] = []
        seqs: list[int] = []
        altitudes: list[float] = []
        s = link.status
        finished = lambda: s.mission_seq == len(items) and s.landed_state == ON_GROUND and not s.armed  # noqa: E731
        deadline = time.monotonic() + FLIGHT_S
        while not finished():
            assert time.monotonic() < deadline, f"the flight did not end: seq {s.mission_seq}, {vehicle.log()}"
            assert s.connected and s.reboots == 0
            track.append((s.lat, s.lon))
            altitudes.append(s.alt_m)
            if s.mission_seq is not None:
                seqs.append(s.mission_seq)
            await asyncio.sleep(0.05)
        seqs.append(s.mission_seq)  # the state that ended the loop (it can change between a sample and the check)
        assert s.mode == "AUTO.MISSION"
        # every item current in turn and reached in order; MAVSDK ends with seq = the number of items
        assert seqs == sorted(seqs) and seqs[-1] == len(items)
        assert reached == list(range(len(items)))
        # over every buoy within the acceptance radius, at the planned altitude, and back down at home
        assert np.all(distances_to_buoys_m(track) <= ACCEPTANCE_RADIUS_M)
        assert max(altitudes) == pytest.approx(ALTITUDE_M, abs=0.01)
        assert (s.lat, s.lon) == pytest.approx(SCENARIO.home[:2], abs=1e-7)
        assert s.alt_m == pytest.approx(0.0, abs=0.01)
    finally:
        await link.stop()


def test_the_link_uploads_arms_starts_and_follows_a_mavsdk_autopilot(start_vehicle):
    asyncio.run(fly_with_the_link(start_vehicle))


async def count_reboots(start_vehicle, watch_s: float) -> int:
    port = free_udp_port()
    link = LinkManager(f"udpin://127.0.0.1:{port}", heartbeat_timeout_s=5.0)
    await link.start()
    vehicle = start_vehicle(port, "--unix-time")
    try:
        assert await link.wait_connected(CONNECT_S), f"no heartbeat from the MAVSDK vehicle:\n{vehicle.log()}"
        await asyncio.sleep(watch_s)
        return link.status.reboots
    finally:
        await link.stop()


def test_a_vehicle_sending_system_time_without_boot_time_is_not_rebooting(start_vehicle):
    """MAVSDK 4.1's TelemetryServer sends SYSTEM_TIME with time_boot_ms = 0 (not stamped): no new boot."""
    assert asyncio.run(count_reboots(start_vehicle, watch_s=6.0)) == 0


# ----- the whole service


def test_the_service_flies_the_reference_mission_on_a_mavsdk_autopilot(tmp_path, start_vehicle):
    port = free_udp_port()
    settings = Settings(db_path=tmp_path / "gcs.sqlite", vehicle_url=f"udpin://127.0.0.1:{port}", vehicle_wait_s=60.0)
    with TestClient(create_app(settings)) as client:
        vehicle = start_vehicle(port)
        deadline = time.monotonic() + CONNECT_S
        while not client.get("/vehicle").json()["connected"]:
            assert time.monotonic() < deadline, f"the service never saw the MAVSDK vehicle:\n{vehicle.log()}"
            time.sleep(0.2)
        buoys = [
            {"id": i, "lat": lat, "lon": lon} for i, (lat, lon) in zip(BUOY_IDS, SCENARIO.buoys_lat_lon, strict=True)
        ]
        created = client.post(
            "/missions", json={"buoys": buoys, "acceptance_radius_m": ACCEPTANCE_RADIUS_M, "dwell_s": DWELL_S}
        )
        assert created.status_code == 201, created.text
        mission_id = created.json()["id"]
        deadline = time.monotonic() + FLIGHT_S
        while (mission := client.get(f"/missions/{mission_id}").json())["status"] not in (
            "completed",
            "failed",
            "aborted",
        ):
            assert time.monotonic() < deadline, f"mission still {mission['status']}: {mission['progress']}"
            time.sleep(0.5)
        assert (mission["status"], mission["reason"]) == ("completed", None), vehicle.log()
        # what the service uploaded is what it planned, item for item, as MissionRawServer received it
        assert [as_on_the_wire(i) for i in vehicle.received_items()] == [as_on_the_wire(i) for i in planned_items()]
        assert len(mission["buoy_results"]) == 13
        assert all(r["reached"] and r["closest_m"] <= ACCEPTANCE_RADIUS_M for r in mission["buoy_results"])
        assert mission["progress"]["visited"] == 13
        state = client.get("/vehicle").json()
        assert state["connected"] and not state["armed"] and state["reboots"] == 0
