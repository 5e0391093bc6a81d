"""Loopback integration: the GCS flies the real vehicle (`python -m sitl_quad --lockstep`) over MAVLink/UDP.

No fake vehicle here: the vehicle is the project's SITL process on a free port, the GCS is the real app
(FastAPI lifespan, link manager, storage on disk) driven through its HTTP API.
"""

import subprocess
import sys
import time
from datetime import UTC, datetime

import pytest
from fastapi.testclient import TestClient

from bench.processes import free_udp_port, stop_process
from gcs.api.app import create_app
from gcs.settings import Settings
from planner import plan_tour
from planner.scenario import reference_scenario
from uavcore.geodesy import LocalFrame

pytestmark = [pytest.mark.integration, pytest.mark.slow]

SCENARIO = reference_scenario(1)
BUOYS = [{"id": f"B{i + 1}", "lat": lat, "lon": lon} for i, (lat, lon) in enumerate(SCENARIO.buoys_lat_lon)]
TERMINAL = {"completed", "failed", "aborted"}
# A wait's deadline: a vehicle starting on a loaded machine (numba on a cold cache) or flying in lockstep at the
# CPU's pace takes several times what it takes on a quiet one; only a behaviour that never comes reaches it.
WAIT_S = 120.0


@pytest.fixture
def vehicle(tmp_path):
    """The real vehicle in lockstep on a free port; yields (port, process)."""
    port = free_udp_port()
    log = open(tmp_path / "vehicle.log", "w")  # noqa: SIM115 - closed below
    process = subprocess.Popen(
        [sys.executable, "-m", "sitl_quad", "--port", str(port), "--lockstep", "--seed", "1"],
        stdout=log,
        stderr=subprocess.STDOUT,
    )
    yield port, process
    stop_process(process)
    log.close()


def settings_for(tmp_path, port: int) -> Settings:
    return Settings(db_path=tmp_path / "gcs.sqlite", vehicle_url=f"udpout:127.0.0.1:{port}", vehicle_wait_s=30.0)


def wait_for(client, mission_id, done, timeout_s):
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        mission = client.get(f"/missions/{mission_id}").json()
        if done(mission):
            return mission
        time.sleep(0.25)
    raise AssertionError(f"mission {mission_id} still {mission['status']} after {timeout_s} s: {mission['progress']}")


def test_reference_mission_flies_to_completion_and_survives_a_restart(tmp_path, vehicle):
    port, _ = vehicle
    with TestClient(create_app(settings_for(tmp_path, port))) as client:
        posted = datetime.now(UTC)
        created = client.post("/missions", json={"buoys": BUOYS, "acceptance_radius_m": 2.0})
        assert created.status_code == 201
        mission_id = created.json()["id"]
        mission = wait_for(client, mission_id, lambda m: m["status"] in TERMINAL, timeout_s=400)
        ended = datetime.now(UTC)
        assert (mission["status"], mission["reason"]) == ("completed", None)
        assert [e["status"] for e in mission["events"]] == ["planned", "uploading", "uploaded", "flying", "completed"]
        # the plan is the exact optimum of the reference instance
        local = LocalFrame(*SCENARIO.home).project(SCENARIO.buoys_lat_lon)  # the GCS plans from lat/lon
        optimum = plan_tour([[0.0, 0.0], *local.tolist()], method="exact").length
        assert mission["length_m"] == pytest.approx(optimum, rel=1e-9)
        # every buoy reached within its acceptance radius, by the recorded track
        assert len(mission["buoy_results"]) == 13
        for result in mission["buoy_results"]:
            assert result["reached"] and result["closest_m"] <= 2.0, result
            assert result["arrival_s"] is not None
        # and when, by the wall clock (UTC, the service's): in visiting order, within the flight
        by_visit = sorted(mission["buoy_results"], key=lambda r: r["arrival_s"])
        heard = [datetime.fromisoformat(r["arrival_at"]) for r in by_visit]
        assert posted <= heard[0] and heard == sorted(heard) and heard[-1] <= ended
        events = mission["progress"]["vehicle_events"]
        assert events and all(posted <= datetime.fromisoformat(e["at"]) <= ended for e in events)
        assert mission["progress"]["visited"] == 13
        tracking = mission["tracking"]
        assert tracking["flight_time_s"] > 0
        assert tracking["distance_flown_m"] == pytest.approx(tracking["planned_length_m"], rel=0.1)
        assert len(tracking["legs"]) == 14 and all(leg["samples"] > 0 for leg in tracking["legs"])
        # the vehicle is back on the ground and disarmed
        vehicle_state = client.get("/vehicle").json()
        assert vehicle_state["connected"] and not vehicle_state["armed"]
        samples = client.get(f"/missions/{mission_id}/telemetry").json()
        times = [s["t_s"] for s in samples]
        assert times == sorted(times) and len(samples) > 10 * tracking["flight_time_s"] * 0.9  # ~10 Hz
        track = client.get(f"/missions/{mission_id}/track.geojson").json()
        assert len(track["geometry"]["coordinates"]) == len(samples)

    # a new service on the same database still has the mission, its figures and its telemetry
    with TestClient(create_app(settings_for(tmp_path, port))) as client:
        again = client.get(f"/missions/{mission_id}").json()
        assert again["status"] == "completed" and again["tracking"] == tracking
        assert len(client.get(f"/missions/{mission_id}/telemetry").json()) == len(samples)
        assert [m["id"] for m in client.get("/missions").json()] == [mission_id]


def test_vehicle_lost_mid_flight_ends_failed_and_the_link_reconnects_after_restart(tmp_path, vehicle):
    port, process = vehicle
    with TestClient(create_app(settings_for(tmp_path, port))) as client:
        mission_id = client.post("/missions", json={"buoys": BUOYS[:3]}).json()["id"]
        wait_for(client, mission_id, lambda m: m["status"] == "flying", timeout_s=WAIT_S)
        process.kill()
        process.wait()
        mission = wait_for(client, mission_id, lambda m: m["status"] in TERMINAL, timeout_s=WAIT_S)
        assert mission["status"] == "failed" and "link lost" in mission["reason"]
        assert client.get("/vehicle").json()["connected"] is False
        # the vehicle comes back on the same port: the link reconnects by itself and sees the restart. Paced at
        # real time: the restart shows as time_boot_ms going back, and a free-running lockstep vehicle's clock
        # can overtake the old one before the service's next heartbeat makes it a peer again.
        restarted = subprocess.Popen(
            [sys.executable, "-m", "sitl_quad", "--port", str(port), "--speed", "1"],
            stdout=subprocess.DEVNULL,
            stderr=subprocess.DEVNULL,
        )
        try:
            deadline = time.monotonic() + WAIT_S
            while not (state := client.get("/vehicle").json())["connected"] and time.monotonic() < deadline:
                time.sleep(0.2)
            while state["connected"] and state["reboots"] == 0 and time.monotonic() < deadline:
                time.sleep(0.2)  # the first state messages with the new time_boot_ms show the restart
                state = client.get("/vehicle").json()
            assert state["connected"] and state["reboots"] == 1
        finally:
            stop_process(restarted)


def test_mission_with_the_offboard_controller_records_its_eso_estimates(tmp_path, vehicle):
    port, _ = vehicle
    log = open(tmp_path / "offboard.log", "w")  # noqa: SIM115 - closed below
    offboard = subprocess.Popen(
        [sys.executable, "-m", "adrc_offboard", "--connect", f"udpout:127.0.0.1:{port}"],
        stdout=log,
        stderr=subprocess.STDOUT,
    )
    try:
        with TestClient(create_app(settings_for(tmp_path, port))) as client:
            # Start once the controller answers the vehicle's ticks (its estimates reach the service): a mission
            # started before would fly its first, free-running part on the vehicle's own loop.
            deadline = time.monotonic() + WAIT_S
            while not client.get("/vehicle").json().get("estimates") and time.monotonic() < deadline:
                time.sleep(0.2)
            mission_id = client.post("/missions", json={"buoys": BUOYS[:3]}).json()["id"]
            mission = wait_for(client, mission_id, lambda m: m["status"] in TERMINAL, timeout_s=300)
            assert (mission["status"], mission["reason"]) == ("completed", None)
            assert all(result["reached"] for result in mission["buoy_results"])
            samples = client.get(f"/missions/{mission_id}/telemetry").json()
            airborne = [s for s in samples if s["landed_state"] == 2]
            # the controller's DEBUG_VECT estimates, forwarded by the vehicle, are in the recorded samples
            with_estimates = [s for s in airborne if s["eso"] and any(s["eso"].get("ESO_Z3") or [])]
            assert len(with_estimates) > 0.9 * len(airborne) > 0
    finally:
        stop_process(offboard)
        log.close()
