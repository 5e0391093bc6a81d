"""A fleet's links: one service holding a link per vehicle, each by its own connection or several on one shared
connection (as a MAVLink router delivers a fleet), and GET /vehicles, GET /vehicles/{sysid} over real vehicle
processes (`python -m sitl_quad --sysid N`)."""

from __future__ import annotations

import asyncio
import time

import numpy as np
import pytest
from fastapi.testclient import TestClient
from sitl_process import SitlProcess

from bench.processes import free_tcp_port, free_udp_port, free_udp_port_block, stop_reading_output
from gcs.api.app import create_app
from gcs.settings import Settings
from gcs.vehicle.connection import TransportHub
from gcs.vehicle.link import LinkManager
from uavcore.geodesy import DEFAULT_HOME, LocalFrame
from uavcore.mavlink import mavlink

pytestmark = pytest.mark.integration

CONNECT_S = 60.0


@pytest.fixture
def vehicles(start_sitl):
    """Start vehicle processes at 5x real time: vehicles(*extra_args) -> SitlProcess (each must stop cleanly)."""
    return lambda *extra: start_sitl(speed=5.0, extra_args=extra)


def _wait_all_connected(client: TestClient, count: int) -> list[dict]:
    deadline = time.monotonic() + CONNECT_S
    while True:
        fleet = client.get("/vehicles").json()
        if len(fleet) == count and all(v["connected"] for v in fleet):
            return fleet
        assert time.monotonic() < deadline, f"not every vehicle connected: {fleet}"
        time.sleep(0.2)


def test_the_service_holds_a_link_per_vehicle_and_lists_the_fleet(tmp_path, vehicles):
    first, second = vehicles("--sysid", "1"), vehicles("--sysid", "2")
    settings = Settings(
        data_dir=tmp_path,
        vehicles=[f"1=udpout:127.0.0.1:{first.port}", f"2=udpout:127.0.0.1:{second.port}"],
    )
    with TestClient(create_app(settings)) as client:
        fleet = _wait_all_connected(client, 2)
        assert [v["sysid"] for v in fleet] == [1, 2]
        assert [v["active_mission"] for v in fleet] == [None, None]
        assert [v["link"] for v in fleet] == [f"udpout://127.0.0.1:{p.port}" for p in (first, second)]
        one = client.get("/vehicles/2").json()
        assert one["sysid"] == 2 and one["connected"] and one["autopilot"] == "PX4"
        assert client.get("/vehicle").json()["sysid"] == 1  # the single-vehicle view is the first
        missing = client.get("/vehicles/9")
        assert missing.status_code == 404
        assert missing.json()["detail"] == [
            {"type": "not_found", "loc": ["path", "sysid"], "msg": "no vehicle with system id 9"}
        ]
        assert client.get("/vehicles/0").status_code == 422  # not a system id


def test_vehicles_sharing_one_connection_each_get_their_own_link_and_commands(vehicles):
    """Two vehicles stream to one ground port, as a router delivers them: the two links read one socket, and
    each answers its own vehicle (an ARM from link 2 arms vehicle 2 only)."""
    port = free_udp_port()

    async def scenario() -> None:
        hub = TransportHub()
        url = f"udpin://127.0.0.1:{port}"
        one, two = (LinkManager(url, 5.0, sysid=n, transports=hub.open_transport) for n in (1, 2))
        await one.start()
        await two.start()  # the same port: a second socket could not bind it
        try:
            vehicles("--sysid", "1", "--out", f"127.0.0.1:{port}")
            vehicles("--sysid", "2", "--out", f"127.0.0.1:{port}")
            assert await one.wait_connected(CONNECT_S) and await two.wait_connected(CONNECT_S)
            assert (one.vehicle.sysid, two.vehicle.sysid) == (1, 2)
            assert await two.command_long(mavlink.MAV_CMD_COMPONENT_ARM_DISARM, [1]) == mavlink.MAV_RESULT_ACCEPTED
            deadline = time.monotonic() + CONNECT_S
            while not two.status.armed:
                assert time.monotonic() < deadline, "vehicle 2 never showed armed"
                await asyncio.sleep(0.1)
            await asyncio.sleep(1.5)  # a heartbeat or more of vehicle 1 since
            assert not one.status.armed
            assert await two.command_long(mavlink.MAV_CMD_COMPONENT_ARM_DISARM, [0]) == mavlink.MAV_RESULT_ACCEPTED
        finally:
            await one.stop()
            await two.stop()
        await one.start()  # the last view closed the shared socket: the port can be taken again
        await one.stop()

    asyncio.run(scenario())


@pytest.mark.slow
def test_up_starts_a_fleet_that_the_service_lists_and_stops_it_whole(tmp_path):
    """`buoy-gcs up --vehicles 3`: three vehicles (system ids 1-3, each with its offboard controller) on their
    own pads at the depot, one service linked to each; SIGTERM stops every child."""
    import json
    import os
    import subprocess
    import sys
    import urllib.request

    first_port, http_port = free_udp_port_block(3), free_tcp_port()
    env = {k: v for k, v in os.environ.items() if not k.startswith("BUOY_GCS_")}
    argv = [sys.executable, "-m", "stack", "up", "--vehicles", "3", "--speed", "1", "--vehicle-port", str(first_port)]
    up = subprocess.Popen(
        [*argv, "--port", str(http_port), "--data", str(tmp_path)],
        env=env,
        stdout=subprocess.PIPE,
        stderr=subprocess.STDOUT,
        text=True,
        start_new_session=True,
    )
    try:
        deadline = time.monotonic() + 2 * CONNECT_S
        while True:
            try:
                with urllib.request.urlopen(f"http://127.0.0.1:{http_port}/vehicles", timeout=2) as response:
                    fleet = json.load(response)
                if len(fleet) == 3 and all(v["connected"] and v["home"] for v in fleet):
                    break
            except OSError:
                pass
            assert up.poll() is None, f"buoy-gcs up exited: {up.stdout.read()}"
            assert time.monotonic() < deadline, "the service never heard the whole fleet"
            time.sleep(0.5)
        assert [v["sysid"] for v in fleet] == [1, 2, 3]
        homes = [(v["home"]["lat"], v["home"]["lon"]) for v in fleet]
        assert len(set(homes)) == 3  # each on its own pad
        for name in ("sitl_quad", "sitl_quad-2", "sitl_quad-3", "adrc_offboard-3"):
            assert (tmp_path / "logs" / f"{name}.log").is_file()
    finally:
        output, _ = stop_reading_output(up, 60)  # SIGTERM; a SIGKILL 60 s later would show in the exit code
    assert up.returncode == 0, output
    assert "starting 3 vehicles, system ids 1-3" in output and "stopped" in output


def _buoys_near(home: tuple[float, float, float], tag: str) -> list[dict]:
    frame = LocalFrame(*home)
    places = [frame.from_ned(north, east, 0.0) for north, east in ((30.0, 0.0), (30.0, 30.0))]
    return [{"id": f"{tag}{i + 1}", "lat": float(lat), "lon": float(lon)} for i, (lat, lon, _) in enumerate(places)]


def test_missions_fly_on_the_vehicles_they_name_at_the_same_time(tmp_path, vehicles):
    homes = {1: DEFAULT_HOME, 2: LocalFrame(*DEFAULT_HOME).from_ned(0.0, 400.0, 0.0)}
    started = {
        sysid: vehicles("--sysid", str(sysid), "--home", ",".join(f"{v:.8f}" for v in home))
        for sysid, home in homes.items()
    }
    links = [f"{sysid}=udpout:127.0.0.1:{process.port}" for sysid, process in started.items()]
    with TestClient(create_app(Settings(data_dir=tmp_path, vehicles=links, vehicle_wait_s=30.0))) as client:
        _wait_all_connected(client, 2)
        _wait_homes(client)
        unknown = client.post("/missions", json={"vehicle": 9, "buoys": _buoys_near(DEFAULT_HOME, "X")})
        assert unknown.status_code == 422 and unknown.json()["detail"][0]["loc"] == ["body", "vehicle"]
        assert client.get("/missions").json() == []  # nothing stored
        ids = {}
        for sysid in (1, 2):  # the second starts while the first flies: each vehicle is free
            created = client.post("/missions", json={"vehicle": sysid, "buoys": _buoys_near(homes[sysid], "B")})
            assert created.status_code == 201, created.text
            ids[sysid] = created.json()["id"]
        for sysid, mission_id in ids.items():
            mission = _wait_ended(client, mission_id)
            assert (mission["status"], mission["vehicle_sysid"]) == ("completed", sysid), mission["reason"]
            depot = (mission["depot"]["lat"], mission["depot"]["lon"])
            assert depot == pytest.approx(homes[sysid][:2])  # the named vehicle's home is its default depot
            samples = client.get(f"/missions/{mission_id}/telemetry").json()
            frame = LocalFrame(*homes[sysid])
            north_east = frame.project(np.array([[s["lat"], s["lon"]] for s in samples]))
            assert np.abs(north_east).max() < 60.0  # recorded from that vehicle, 400 m from the other
        assert [m["vehicle_sysid"] for m in client.get("/missions").json()] == [2, 1]


def _wait_homes(client: TestClient) -> bool:
    deadline = time.monotonic() + CONNECT_S
    while not all(v["home"] for v in client.get("/vehicles").json()):
        assert time.monotonic() < deadline, "a vehicle never sent its home"
        time.sleep(0.2)
    return True


def _wait_ended(client: TestClient, mission_id: int) -> dict:
    deadline = time.monotonic() + 4 * CONNECT_S
    while (mission := client.get(f"/missions/{mission_id}").json())["status"] not in ("completed", "failed", "aborted"):
        assert time.monotonic() < deadline, f"mission {mission_id} still {mission['status']}"
        time.sleep(0.25)
    return mission


def test_a_fleet_mission_shares_the_buoys_flies_each_share_at_its_layer_and_completes(tmp_path, vehicles):
    frame = LocalFrame(*DEFAULT_HOME)
    homes = {1: DEFAULT_HOME, 2: frame.from_ned(0.0, 160.0, 0.0), 3: frame.from_ned(160.0, 0.0, 0.0)}
    started = {
        sysid: vehicles("--sysid", str(sysid), "--home", ",".join(f"{v:.8f}" for v in home))
        for sysid, home in homes.items()
    }
    links = [f"{sysid}=udpout:127.0.0.1:{process.port}" for sysid, process in started.items()]
    places = [(n, e) for n in (30.0, 90.0, 150.0) for e in (40.0, 100.0, 170.0)]
    buoys = [
        {"id": f"B{i + 1}", "lat": float(lat), "lon": float(lon)}
        for i, (lat, lon, _) in enumerate(frame.from_ned(n, e, 0.0) for n, e in places)
    ]
    with TestClient(create_app(Settings(data_dir=tmp_path, vehicles=links, vehicle_wait_s=30.0))) as client:
        _wait_all_connected(client, 3)
        _wait_homes(client)
        depot = {"lat": buoys[0]["lat"], "lon": buoys[0]["lon"]}  # a fleet flies from its vehicles' homes
        bad = client.post("/missions", json={"vehicles": [1, 7], "buoys": buoys, "depot": depot})
        assert bad.status_code == 422
        assert {tuple(e["loc"]) for e in bad.json()["detail"]} == {("body", "depot"), ("body", "vehicles", 1)}
        # the preview (POST /plans): the same sharing, nothing stored
        preview = client.post("/plans", json={"vehicles": "fleet", "buoys": buoys, "layer_gap_m": 4.0})
        assert preview.status_code == 200, preview.text
        shares = preview.json()["fleet"]["shares"]
        assert sorted(b for share in shares for b in share["buoys"]) == list(range(9))
        assert all(share["altitude_m"] == 5.0 + 4.0 * (share["sysid"] - 1) for share in shares)
        for share in shares:  # each from its own home, and back
            home = pytest.approx(list(homes[share["sysid"]][:2]), abs=1e-6)
            assert share["route"][0] == home and share["route"][-1] == home
        assert client.get("/missions").json() == []
        created = client.post("/missions", json={"vehicles": "fleet", "buoys": buoys, "layer_gap_m": 4.0})
        assert created.status_code == 201, created.text
        fleet_id = created.json()["id"]
        mission = _wait_ended(client, fleet_id)
        assert (mission["status"], mission["reason"]) == ("completed", None)
        # `fleet_id` means one thing in every document: the fleet mission a part belongs to
        listed = next(m for m in client.get("/missions").json() if m["id"] == fleet_id)
        for document in (mission, listed):
            assert (document["kind"], document["fleet_id"]) == ("fleet", None)
        fleet = mission["fleet"]
        assert sorted(b for share in fleet["shares"] for b in share["buoys"]) == list(range(9))
        assert set(fleet["inspected_by"]) == {b["id"] for b in buoys}  # each buoy inspected by someone
        for share in fleet["shares"]:
            part = client.get(f"/missions/{share['mission_id']}").json()
            assert (part["status"], part["vehicle_sysid"], part["fleet_id"]) == ("completed", share["sysid"], fleet_id)
            assert part["kind"] == "fleet_part"
            assert part["altitude_m"] == 5.0 + 4.0 * (share["sysid"] - 1)  # its layer
            assert all(fleet["inspected_by"][buoys[b]["id"]] == share["sysid"] for b in share["buoys"])
        separation = fleet["separation"]  # homes 160 m apart: they climb far apart, and cross a layer apart
        assert len(fleet["shares"]) >= 2 and separation["min_distance_m"] > fleet["layer_gap_m"]
        assert separation["min_horizontal_m"] <= separation["min_distance_m"]


def test_a_lost_vehicles_buoys_are_reshared_in_flight_and_the_fleet_mission_completes(tmp_path, vehicles):
    """Three vehicles share 30 buoys; vehicle 2's process is killed (SIGKILL) after its first buoy: its part
    fails "link lost", its buoys not inspected are uploaded in flight to the vehicles still flying, and the fleet
    mission completes with every buoy inspected by someone and vehicle 2 reported lost."""
    frame = LocalFrame(*DEFAULT_HOME)
    homes = {1: DEFAULT_HOME, 2: frame.from_ned(0.0, 160.0, 0.0), 3: frame.from_ned(160.0, 0.0, 0.0)}
    home_arg = {n: ",".join(f"{v:.8f}" for v in home) for n, home in homes.items()}
    doomed = SitlProcess(speed=5.0, extra_args=("--sysid", "2", "--home", home_arg[2])).start()
    try:
        started = {1: vehicles("--sysid", "1", "--home", home_arg[1]), 2: doomed}
        started[3] = vehicles("--sysid", "3", "--home", home_arg[3])
        links = [f"{n}=udpout:127.0.0.1:{started[n].port}" for n in (1, 2, 3)]
        places = [(n, e) for n in np.linspace(20.0, 220.0, 6) for e in np.linspace(30.0, 230.0, 5)]
        buoys = [
            {"id": f"B{i + 1}", "lat": float(lat), "lon": float(lon)}
            for i, (lat, lon, _) in enumerate(frame.from_ned(n, e, 0.0) for n, e in places)
        ]
        settings = Settings(data_dir=tmp_path, vehicles=links, vehicle_wait_s=30.0)
        with TestClient(create_app(settings)) as client:
            _wait_all_connected(client, 3)
            _wait_homes(client)
            created = client.post("/missions", json={"vehicles": "fleet", "buoys": buoys, "layer_gap_m": 4.0})
            assert created.status_code == 201, created.text
            fleet_id = created.json()["id"]
            share = next(s for s in created.json()["fleet"]["shares"] if s["sysid"] == 2)
            assert len(share["buoys"]) >= 2  # something left for the others once it is lost after its first
            deadline = time.monotonic() + 4 * CONNECT_S
            while client.get(f"/missions/{share['mission_id']}").json()["progress"]["visited"] < 1:
                assert time.monotonic() < deadline, "vehicle 2 never reached its first buoy"
                time.sleep(0.1)
            doomed.process.kill()  # no goodbye: its link falls silent
            mission = _wait_ended(client, fleet_id)
            assert (mission["status"], mission["reason"]) == ("completed", None), mission["events"]
            fleet = mission["fleet"]
            assert set(fleet["inspected_by"]) == {b["id"] for b in buoys}  # every buoy, by someone
            lost = next(s for s in fleet["shares"] if s["sysid"] == 2)
            assert lost["lost"].startswith("link lost") and lost["status"] == "failed"
            handed = [b for taken in lost["handed_over"].values() for b in taken]
            assert handed and set(handed) == set(lost["buoys"]) - set(lost["visited_buoys"])
            assert all(fleet["inspected_by"][buoys[b]["id"]] != 2 for b in handed)
            assert any("vehicle 2 lost (link lost" in (e["reason"] or "") for e in mission["events"])
            assert fleet["separation"]["min_distance_m"] > fleet["layer_gap_m"]
            # the fleet report: vehicle 2 lost and who took its buoys, every buoy with the vehicle that inspected it
            page = client.get(f"/missions/{fleet_id}/report/index.html")
            assert page.status_code == 200 and "link lost" in page.text and "to vehicle" in page.text
            assert page.text.count("<tr><td>B") == 30 and ">nobody<" not in page.text
            assert client.get(f"/missions/{fleet_id}/report/fleet.png").headers["content-type"] == "image/png"
            for sysid, taken in lost["handed_over"].items():
                part_id = next(s["mission_id"] for s in fleet["shares"] if s["sysid"] == int(sysid))
                part = client.get(f"/missions/{part_id}").json()
                assert part["status"] == "completed" and len(part["buoys"]) > len(taken)
                assert any((e["reason"] or "").startswith("re-planned in flight") for e in part["events"])
    finally:
        doomed.cleanup()
