"""End to end: PX4's failure injection during a mission, through the whole stack (the simulated PX4 in lockstep with
SYS_FAILURE_EN 1, its offboard controller, the service driven through its REST API). The test injects each failure
as a PX4 SITL user does (MAV_CMD_INJECT_FAILURE from a second ground station, as MAVSDK's Failure plugin or
`failure gps off` in PX4's shell sends it), and the service's answer is asserted: the mission ends with the cause
in its reason, and the vehicle's flight log is downloaded, served by GET /missions/{id}/log and linked from the
report (or, when the link itself failed, a note says why not).
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from pyulog import ULog
from sitl_process import GroundStation
from test_e2e_stack import FLIGHT_S, TERMINAL, WAIT_S, Stack, near_buoys, running_stack, wait_until

from sitl_quad.flight_logs import FAILURE_GPS
from uavcore.mavlink import mavlink

pytestmark = [pytest.mark.integration, pytest.mark.slow, pytest.mark.timeout(900)]

GPS, MOTOR = mavlink.FAILURE_UNIT_SENSOR_GPS, mavlink.FAILURE_UNIT_SYSTEM_MOTOR
BATTERY, MAVLINK_SIGNAL = mavlink.FAILURE_UNIT_SYSTEM_BATTERY, mavlink.FAILURE_UNIT_SYSTEM_MAVLINK_SIGNAL
OFF, OK = mavlink.FAILURE_TYPE_OFF, mavlink.FAILURE_TYPE_OK


@pytest.fixture
def stack(tmp_path):
    yield from running_stack(tmp_path)


def fly_until_out(stack: Stack, *vehicle_params: str) -> int:
    """Vehicle (failure injection enabled, its logs in the test's directory), controller and service; a mission of
    three buoys flown until its first buoy is visited. Returns the mission's id."""
    stack.start_gcs()
    params = [a for p in ("SYS_FAILURE_EN=1", *vehicle_params) for a in ("--param", p)]
    stack.start_vehicle(*params, "--log-dir", str(stack.dir / "vehicle-logs"))
    stack.start_offboard()
    stack.wait_connected()
    mission_id = stack.fly(near_buoys(3))
    stack.wait_mission(mission_id, lambda m: m["progress"].get("visited", 0) >= 1, timeout_s=FLIGHT_S)
    return mission_id


def inject(stack: Stack, unit: int, kind: int, instance: int = 0, vehicle_silent: bool = False) -> None:
    """MAV_CMD_INJECT_FAILURE from a second ground station, acknowledged ACCEPTED (to a silent vehicle, whose
    MAVLink signal is failed, the command is sent without waiting for its heartbeat first)."""
    station = GroundStation(stack.vehicle_port, sysid=254)
    try:
        if not vehicle_silent:
            station.connect()
        ack = station.command(mavlink.MAV_CMD_INJECT_FAILURE, unit, kind, instance)
        assert ack is not None and ack.result == mavlink.MAV_RESULT_ACCEPTED, ack
    finally:
        station.close()


def ended(stack: Stack, mission_id: int) -> dict:
    return stack.wait_mission(mission_id, lambda m: m["status"] in TERMINAL, timeout_s=FLIGHT_S)


def downloaded_log(stack: Stack, mission_id: int, path) -> ULog:
    """The mission's flight log as GET /missions/{id}/log serves it (fetched just after the mission ended)."""
    response = wait_until(
        lambda: (r := stack.api.get(f"/missions/{mission_id}/log")).status_code == 200 and r,
        WAIT_S,
        lambda: stack.api.get(f"/missions/{mission_id}/log").text,
    )
    assert response.headers["content-type"] == "application/octet-stream"
    assert f'filename="mission-{mission_id}.ulg"' in response.headers["content-disposition"]
    path.write_bytes(response.content)
    report = stack.api.get(f"/missions/{mission_id}/report").text
    assert f'href="/missions/{mission_id}/log"' in report
    return ULog(str(path))


def test_gps_off_in_flight_descends_out_there_and_the_mission_fails_naming_the_gps(stack, tmp_path):
    mission_id = fly_until_out(stack)
    inject(stack, GPS, OFF)
    mission = ended(stack, mission_id)
    assert mission["status"] == "failed", mission
    assert "Failsafe: GPS lost, no position: AUTO.LAND" in mission["reason"], mission["reason"]
    assert mission["progress"]["visited"] < 3
    vehicle = stack.api.get("/vehicle").json()
    assert not vehicle["armed"] and math.hypot(vehicle["north"], vehicle["east"]) > 5.0  # down out there, not home

    ulog = downloaded_log(stack, mission_id, tmp_path / "gps.ulg")
    status = ulog.get_dataset("vehicle_status").data
    lost = (status["failure_flags"] & FAILURE_GPS) != 0
    assert lost.any() and not lost[0]
    assert 18 in status["nav_state"][np.argmax(lost) :]  # AUTO.LAND (Descend) after the loss
    assert "Failsafe: GPS lost, no position: AUTO.LAND" in [m.message for m in ulog.logged_messages]
    # the estimate held the last fix while the truth came down to the ground, level (PX4's Descend)
    estimate = ulog.get_dataset("vehicle_local_position").data
    truth = ulog.get_dataset("vehicle_local_position_groundtruth").data
    after = np.argmax(lost)
    assert np.ptp(estimate["x"][after:]) < 0.5 and np.ptp(estimate["y"][after:]) < 0.5
    assert truth["z"][after] < -3.0 and truth["z"][-1] > -0.3


def test_a_motor_off_brings_the_vehicle_down_and_the_mission_fails_naming_the_motor(stack, tmp_path):
    mission_id = fly_until_out(stack)
    inject(stack, MOTOR, OFF, 3)
    mission = ended(stack, mission_id)
    assert mission["status"] == "failed", mission
    assert "Failsafe: motor 3 failure" in mission["reason"], mission["reason"]
    ulog = downloaded_log(stack, mission_id, tmp_path / "motor.ulg")
    rotors = ulog.get_dataset("sim_rotors").data
    status = ulog.get_dataset("vehicle_status").data
    blocked = (status["motors_off_mask"] & 0b100) != 0
    assert blocked.any()
    # from 0.3 s after the block (the motor's time constant is 20 ms) until the disarm: rotor 3 stopped, the others
    # driven by the mixer as the vehicle tumbles down
    falling = np.arange(len(blocked)) >= np.argmax(blocked) + 3
    falling &= status["arming_state"] == 2
    assert falling.any()
    assert rotors["speed_rad_s[2]"][falling].max() < 5.0
    others = np.max([rotors[f"speed_rad_s[{i}]"][falling] for i in (0, 1, 3)], axis=0)
    assert others.min() > 100.0  # the mixer drives what it can (its diagonal partner it may idle)


def test_battery_off_triggers_the_battery_failsafe_and_the_mission_ends_on_it(stack, tmp_path):
    mission_id = fly_until_out(stack, "COM_LOW_BAT_ACT=2")  # 2: land at the critical and emergency levels
    inject(stack, BATTERY, OFF)
    mission = ended(stack, mission_id)
    assert mission["status"] == "aborted", mission  # a battery failsafe: aborted, as the service words it
    assert "battery failsafe" in mission["reason"] and "Emergency battery level" in mission["reason"], mission
    ulog = downloaded_log(stack, mission_id, tmp_path / "battery.ulg")
    battery = ulog.get_dataset("battery_status").data
    assert battery["remaining"][0] > 0.5 and battery["remaining"][-1] == 0.0  # read as empty from the injection


def test_mavlink_signal_off_the_service_fails_the_mission_link_lost_and_the_vehicle_returns_by_itself(stack):
    mission_id = fly_until_out(stack, "NAV_DLL_ACT=2", "COM_DL_LOSS_T=5")  # 2: return once 5 s without a GCS
    inject(stack, MAVLINK_SIGNAL, OFF)
    mission = ended(stack, mission_id)
    assert mission["status"] == "failed", mission
    assert mission["reason"] == "link lost: no heartbeat from the vehicle", mission
    note = wait_until(
        lambda: (
            (r := stack.api.get(f"/missions/{mission_id}/log")).status_code == 404
            and "flight log not downloaded: no link to the vehicle" in r.text
            and r.json()
        ),
        WAIT_S,
        "no note on the flight log",
    )
    assert note["detail"][0]["loc"] == ["path", "mission_id"], note
    # the vehicle, unheard, returned and landed by itself (NAV_DLL_ACT): its own log says so
    logs = stack.dir / "vehicle-logs"
    (finished,) = wait_until(lambda: list(logs.glob("*.ulg")), FLIGHT_S, "the vehicle's log never finished")
    ulog = ULog(str(finished))
    texts = [m.message for m in ulog.logged_messages]
    assert any(t.startswith("Failsafe: no ground station for") and t.endswith("AUTO.RTL") for t in texts), texts
    assert 5 in ulog.get_dataset("vehicle_status").data["nav_state"]  # AUTO_RTL
    inject(
        stack, MAVLINK_SIGNAL, OK, vehicle_silent=True
    )  # the one command a failed signal still hears: the link comes back
    stack.wait_connected()
