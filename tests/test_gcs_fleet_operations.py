"""A fleet mission within batteries and a geofence, and a vehicle its failsafe brings down, flown by real vehicle
processes (`python -m sitl_quad --sysid N`, sped up) through the service's REST API:

- two vehicles with small packs share six buoys inside a fence with an exclusion zone: each share flies in sorties
  within its vehicle's pack, the operator confirms each swap, every buoy is visited, every sample is inside the
  fence, and each vehicle holds the request's fence and rally point, read back over MAVLink;
- a vehicle whose battery failsafe returns it mid-share (COM_LOW_BAT_ACT 1, a pack flown near empty) is lost as a
  vehicle whose link falls silent is: its buoys not visited go to the vehicle still flying, and the fleet mission
  completes.
"""

from __future__ import annotations

import asyncio
import contextlib
import itertools
import math
import time
from collections.abc import Iterator
from dataclasses import replace

import numpy as np
import pytest
from fastapi.testclient import TestClient
from sitl_process import GroundStation
from test_gcs_fleet_links import CONNECT_S, _wait_all_connected, _wait_ended, _wait_homes

from gcs.api.app import create_app
from gcs.domain.schemas import FenceZoneIn
from gcs.missions.validation import fence_from_request
from gcs.settings import Settings
from gcs.vehicle.link import LinkManager
from gcs.vehicle.mission_protocol import MissionRejectedError, upload_items
from uavcore.geodesy import DEFAULT_HOME, LocalFrame
from uavcore.geofence import Geofence
from uavcore.mavlink import mavlink
from uavcore.mission import MissionType, rally_point_items

pytestmark = pytest.mark.integration

FRAME = LocalFrame(*DEFAULT_HOME)
SPEED = 10.0  # the vehicles' pace: simulated seconds per wall second (slower when the machine is loaded)


def _point(north: float, east: float) -> dict:
    lat, lon, _ = FRAME.from_ned(north, east, 0.0)
    return {"lat": float(lat), "lon": float(lon)}


def _home_arg(north: float, east: float) -> str:
    return ",".join(f"{v:.8f}" for v in FRAME.from_ned(north, east, 0.0))


def _fleet(start_sitl, *per_vehicle: tuple[str, ...], speed: float = SPEED) -> list[str]:
    """Vehicles 1, 2, ... at homes 160 m apart along east, each with its own extra arguments: their links."""
    links = []
    for k, extra in enumerate(per_vehicle):
        sysid = k + 1
        vehicle = start_sitl(speed=speed, extra_args=("--sysid", str(sysid), "--home", _home_arg(0.0, 160.0 * k),
                                                      *extra))  # fmt: skip
        links.append(f"{sysid}=udpout:127.0.0.1:{vehicle.port}")
    return links


def _part(client: TestClient, part_id: int) -> dict:
    return client.get(f"/missions/{part_id}").json()


@contextlib.contextmanager
def _fleet_service(tmp_path, links: list[str]) -> Iterator[TestClient]:
    """The service linked to the fleet's vehicles, once it hears every one and knows their homes."""
    with TestClient(create_app(Settings(data_dir=tmp_path, vehicles=links, vehicle_wait_s=30.0))) as client:
        _wait_all_connected(client, len(links))
        _wait_homes(client)
        yield client


def _posted(client: TestClient, request: dict) -> dict:
    created = client.post("/missions", json=request)
    assert created.status_code == 201, created.text
    return created.json()


# six buoys two columns wide, far enough north that vehicle 2 comes down (or is brought down) with some left
RESHARE_BUOYS = [{"id": f"B{i + 1}", **_point(n, e)} for i, (n, e) in enumerate((n, e) for n in (60, 200, 340)
                 for e in (0, 160))]  # fmt: skip


def _reshared_to_vehicle_1(mission: dict, buoys: list[dict]) -> dict:
    """Vehicle 2's share as the completed fleet mission ends: every buoy inspected by someone, its buoys not
    visited handed to vehicle 1, which inspected them. Returned for what the test says of why it was lost."""
    assert (mission["status"], mission["reason"]) == ("completed", None), mission["events"]
    fleet = mission["fleet"]
    assert set(fleet["inspected_by"]) == {b["id"] for b in buoys}  # every buoy, by someone
    lost = next(s for s in fleet["shares"] if s["sysid"] == 2)
    handed = [b for taken in lost["handed_over"].values() for b in taken]
    assert handed and set(handed) == set(lost["buoys"]) - set(lost["visited_buoys"])
    assert all(fleet["inspected_by"][buoys[b]["id"]] == 1 for b in handed)
    return lost


def _fly_with_swaps(client: TestClient, fleet_id: int, shares: list[dict]) -> dict:
    """Follow a fleet mission to its end as its operator: a part waiting for its battery gets the swap confirmed
    (POST /vehicles/{sysid}/battery-swap). Returns the ended fleet mission."""
    deadline = time.monotonic() + 8 * CONNECT_S
    while (mission := client.get(f"/missions/{fleet_id}").json())["status"] not in ("completed", "failed", "aborted"):
        for share in shares:
            if _part(client, share["mission_id"])["status"] == "waiting_for_battery":
                swapped = client.post(f"/vehicles/{share['sysid']}/battery-swap", json={})
                assert swapped.status_code == 200, swapped.text
        assert time.monotonic() < deadline, f"fleet mission {fleet_id} still {mission['status']}"
        time.sleep(0.25)
    return mission


async def _lists_on_board(url: str) -> tuple[Geofence, list]:
    link = LinkManager(url, 5.0)
    await link.start()
    try:
        assert await link.wait_connected(CONNECT_S)
        return await link.download_fence(), await link.download_rally_points()
    finally:
        await link.stop()


# an inclusion square around both homes and every buoy; an exclusion square between the middle buoys of the two
# rows (B2, B5), which the legs from either home pass by
INCLUSION = {"kind": "polygon", "inclusion": True, "vertices": [_point(-60, -60), _point(-60, 220), _point(260, 220),
             _point(260, -60)]}  # fmt: skip
EXCLUSION = {"kind": "polygon", "inclusion": False, "vertices": [_point(95, 70), _point(105, 70), _point(105, 90),
             _point(95, 90)]}  # fmt: skip
# closer to B4 (108 m) than vehicle 1's home (140 m): a sortie ending with an RTL would land here (PX4, RTL_TYPE 0,
# lands at the closest of home and the rally points), so a mission given rally points ends by a waypoint at its
# depot and NAV_LAND there, and its next sortie takes off from the depot
RALLY = {**_point(240, -40), "alt_m": 12.0}


def test_the_vehicle_takes_the_fence_and_rally_points_as_uploaded_and_refuses_bad_ones_by_their_result(start_sitl):
    """The lists the service uploads, against the vehicle's own acceptance: read back as sent; a polygon whose
    vertex count (param1) does not add up is MAV_MISSION_INVALID_PARAM1, a rally point without an altitude
    MAV_MISSION_INVALID_PARAM7, each error naming the list."""
    vehicle = start_sitl(speed=SPEED)
    fence = fence_from_request([FenceZoneIn.model_validate(zone) for zone in (INCLUSION, EXCLUSION)])

    async def scenario() -> None:
        link = LinkManager(f"udpout://127.0.0.1:{vehicle.port}", 5.0)
        await link.start()
        try:
            assert await link.wait_connected(CONNECT_S)
            await link.upload_fence(fence)
            await link.upload_rally_points([(RALLY["lat"], RALLY["lon"], RALLY["alt_m"])])
            on_board = await link.download_fence()
            assert [(z.inclusion, len(z.vertices)) for z in on_board.zones] == [(True, 4), (False, 4)]
            assert np.allclose(on_board.zones[1].vertices, fence.zones[1].vertices, rtol=0, atol=1.5e-7)
            (rally,) = await link.download_rally_points()
            assert rally.z == RALLY["alt_m"]
            short = [replace(item, param1=5.0) for item in fence.to_items()[:4]]  # says 5 vertices, has 4
            with pytest.raises(MissionRejectedError, match=r"refused the geofence \(MAV_MISSION_INVALID_PARAM1\)"):
                await upload_items(link, short, mission_type=MissionType.FENCE)
            (no_altitude,) = rally_point_items([(RALLY["lat"], RALLY["lon"], math.nan)])
            with pytest.raises(MissionRejectedError, match=r"refused the rally points \(MAV_MISSION_INVALID_PARAM7\)"):
                await upload_items(link, [no_altitude], mission_type=MissionType.RALLY)
            assert len((await link.download_fence()).zones) == 2  # a refused list changes nothing on board
        finally:
            await link.stop()

    asyncio.run(scenario())


@pytest.mark.slow
def test_a_fleet_flies_its_shares_in_sorties_within_its_packs_inside_the_fence_it_uploaded(tmp_path, start_sitl):
    small_pack = ("--param", "BAT1_CAPACITY=350")  # 4.4 Wh a sortie: two sorties for three of these buoys
    links = _fleet(start_sitl, small_pack, small_pack)
    buoys = [{"id": f"B{i + 1}", **_point(n, e)} for i, (n, e) in enumerate((n, e) for n in (60, 140)
             for e in (0, 80, 160))]  # fmt: skip
    request = {
        "vehicles": "fleet", "buoys": buoys, "dwell_s": 5.0, "inspect": False, "battery": "vehicle",
        "geofence": [INCLUSION, EXCLUSION], "rally_points": [RALLY],
    }  # fmt: skip
    with _fleet_service(tmp_path, links) as client:
        created = _posted(client, request)
        fleet_id, shares = created["id"], created["fleet"]["shares"]
        mission = _fly_with_swaps(client, fleet_id, shares)
        assert (mission["status"], mission["reason"]) == ("completed", None), mission["events"]
        assert set(mission["fleet"]["inspected_by"]) == {b["id"] for b in buoys}
        fence = fence_from_request([FenceZoneIn.model_validate(zone) for zone in request["geofence"]])
        sorties_flown = {}
        for share in shares:
            part = _part(client, share["mission_id"])
            assert part["status"] == "completed", part["reason"]
            statuses = [event["status"] for event in part["events"]]
            sorties = part["sorties"]
            sorties_flown[share["sysid"]] = len(sorties)
            # each sortie flown within its pack, swapped between: as many waits for a battery as sorties after the first
            assert statuses.count("waiting_for_battery") == len(sorties) - 1, part["events"]
            assert all(s["used_energy_wh"] is not None and s["battery_warning"] is None for s in sorties), sorties
            assert all(s["used_energy_wh"] <= s["predicted_energy_wh"] + s["margin_wh"] for s in sorties), sorties
            samples = client.get(f"/missions/{share['mission_id']}/telemetry").json()
            outside = [(s["lat"], s["lon"]) for s in samples if not fence.contains(s["lat"], s["lon"])]
            assert samples and not outside, outside[:5]
            for sortie in sorties:  # planned inside: no leg through the exclusion zone
                route = [tuple(p) for p in sortie["route"]]
                assert all(fence.segment_violation(a, b) is None for a, b in itertools.pairwise(route))
        assert max(sorties_flown.values()) >= 2, sorties_flown
    for link in links:  # each vehicle holds the request's fence and rally point, read back over MAVLink
        on_board, rally = asyncio.run(_lists_on_board(link.partition("=")[2]))
        assert [(z.inclusion, len(z.vertices)) for z in on_board.zones] == [(True, 4), (False, 4)]
        for zone, asked in zip(on_board.zones, request["geofence"], strict=True):
            expected = [(v["lat"], v["lon"]) for v in asked["vertices"]]
            assert np.allclose(zone.vertices, expected, rtol=0, atol=1.5e-7)
        (point,) = rally
        assert (point.lat, point.lon, point.z) == (
            pytest.approx(RALLY["lat"], abs=1.5e-7), pytest.approx(RALLY["lon"], abs=1.5e-7), RALLY["alt_m"]
        )  # fmt: skip


@pytest.mark.slow
def test_a_vehicle_its_battery_failsafe_brings_down_is_lost_and_its_buoys_reshared(tmp_path, start_sitl):
    """Vehicle 2 takes off on a nearly empty small pack (the pre-flight check overridden): at the critical level
    its failsafe returns it (COM_LOW_BAT_ACT 1, PX4's "Return"), its part ends "battery failsafe", and its buoys not
    visited are uploaded in flight to vehicle 1, which completes the fleet mission."""
    failing = ("--param", "BAT1_CAPACITY=500", "--param", "COM_LOW_BAT_ACT=1", "--battery-percent", "16")
    # at half the pace, with shares of some 100 simulated seconds: vehicle 2 comes down in its first 30 or so, and
    # its part ends (the service's disarm grace and polls are wall-clock) long before vehicle 1 is home
    links = _fleet(start_sitl, (), failing, speed=SPEED / 2)
    request = {"vehicles": "fleet", "buoys": RESHARE_BUOYS, "dwell_s": 2.0, "inspect": False, "override": True}
    with _fleet_service(tmp_path, links) as client:
        created = _posted(client, request)
        lost_share = next(s for s in created["fleet"]["shares"] if s["sysid"] == 2)
        assert len(lost_share["buoys"]) >= 2
        mission = _wait_ended(client, created["id"])
        lost = _reshared_to_vehicle_1(mission, RESHARE_BUOYS)
        assert lost["status"] == "aborted" and lost["lost"].startswith(
            "battery failsafe (Critical battery level! Executing RTL"
        )
        fleet = mission["fleet"]
        assert any("vehicle 2 lost (battery failsafe" in (e["reason"] or "") for e in mission["events"])
        part = _part(client, next(s["mission_id"] for s in fleet["shares"] if s["sysid"] == 1))
        assert part["status"] == "completed"
        assert any((e["reason"] or "").startswith("re-planned in flight") for e in part["events"])


@pytest.mark.slow
def test_a_vehicle_an_injected_motor_failure_brings_down_is_lost_and_its_buoys_reshared(tmp_path, start_sitl):
    """PX4's failure injection on a fleet: once vehicle 2 has inspected its first buoy, a second ground station (as
    MAVSDK's Failure plugin) turns its motor 1 off; it comes down, its part fails naming the motor, and its buoys
    not visited are uploaded in flight to vehicle 1, which completes the fleet mission."""
    links = _fleet(start_sitl, (), ("--param", "SYS_FAILURE_EN=1"), speed=SPEED / 2)
    port = int(links[1].rsplit(":", 1)[1])
    request = {"vehicles": "fleet", "buoys": RESHARE_BUOYS, "dwell_s": 2.0, "inspect": False}
    with _fleet_service(tmp_path, links) as client:
        created = _posted(client, request)
        second = next(s for s in created["fleet"]["shares"] if s["sysid"] == 2)
        assert len(second["buoys"]) >= 2
        deadline = time.monotonic() + 8 * CONNECT_S
        while _part(client, second["mission_id"])["progress"]["visited"] < 1:
            assert time.monotonic() < deadline, "vehicle 2 never inspected its first buoy"
            time.sleep(0.1)
        station = GroundStation(port, sysid=254, vehicle_sysid=2)
        try:
            station.connect()
            ack = station.command(mavlink.MAV_CMD_INJECT_FAILURE, mavlink.FAILURE_UNIT_SYSTEM_MOTOR,
                                  mavlink.FAILURE_TYPE_OFF, 1, target_system=2)  # fmt: skip
            assert ack is not None and ack.result == mavlink.MAV_RESULT_ACCEPTED, ack
        finally:
            station.close()
        lost = _reshared_to_vehicle_1(_wait_ended(client, created["id"]), RESHARE_BUOYS)
        assert lost["status"] == "failed" and "motor 1 failure" in lost["lost"], lost
