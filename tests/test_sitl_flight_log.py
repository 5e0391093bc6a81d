"""The vehicle's ULog flight log, one per arming, read back with pyulog (PX4's own parser): in process, then over
UDP, downloaded by MAVSDK's LogFiles plugin after a flight that MAVSDK's Failure plugin cut short (GPS off)."""

from __future__ import annotations

import struct
import threading
import time
from pathlib import Path

import numpy as np
import pytest
from pyulog import ULog
from test_sitl_vehicle import HOME, item

from sitl_quad.config import VehicleConfig
from sitl_quad.flight_logs import FAILURE_GPS, TOPICS, FlightLogs
from sitl_quad.ulog import Topic, ULogEncoder, ULogError
from sitl_quad.vehicle import CommandResult, Vehicle
from uavcore.mission import MavCmd


def test_encoder_refuses_what_ulog_cannot_carry():
    with pytest.raises(ULogError, match="unknown field type"):
        Topic("t", (("float16", "x"),)).struct()
    encoder = ULogEncoder([Topic("t", (("float", "x"),))])
    with pytest.raises(ULogError, match="unknown topic"):
        encoder.sample("u", 0, (1.0,))
    with pytest.raises(ULogError, match="t:"):
        encoder.sample("t", 0, (1.0, 2.0))
    text = encoder.text(3, 5, "hi")
    assert struct.unpack("<HB", text[:3]) == (len(text) - 3, ord("L")) and text[3:4] == b"3"


def fly_logged(vehicle: Vehicle, logs: FlightLogs, until, max_s: float) -> None:
    end = vehicle.t + max_s
    while vehicle.t < end and not until(vehicle):
        record = vehicle.tick()
        for event in vehicle.events:
            if event.kind == "text":
                logs.text(event.severity, event.text, vehicle.t)
        vehicle.events.clear()
        logs.tick(vehicle, record)


def test_one_log_per_arming_with_the_flight_in_it(tmp_path):
    vehicle = Vehicle(VehicleConfig(), home=HOME, seed=3)
    logs = FlightLogs(tmp_path, None, boot_unix_us=1_764_000_000_000_000)
    vehicle.set_mission([item(0, MavCmd.NAV_TAKEOFF, alt=8.0), item(1, MavCmd.NAV_LAND, 0.0, 0.0, alt=0.0)])
    fly_logged(vehicle, logs, lambda v: False, 1.0)
    assert logs.entries() == [] and not logs.writing  # nothing before arming
    assert vehicle.arm() == CommandResult.ACCEPTED and vehicle.start_mission() == CommandResult.ACCEPTED
    fly_logged(vehicle, logs, lambda v: not v.armed, 120.0)
    fly_logged(vehicle, logs, lambda v: False, 0.1)
    (entry,) = logs.entries()
    assert entry.path.name.startswith("log_0001_") and entry.time_utc >= 1_764_000_000
    assert entry.size == entry.path.stat().st_size and not list(tmp_path.glob("*.part"))

    ulog = ULog(str(entry.path))
    assert {d.name for d in ulog.data_list} == {t.name for t in TOPICS}
    position = ulog.get_dataset("vehicle_local_position").data
    assert -position["z"].min() == pytest.approx(8.0, abs=0.5)  # the takeoff altitude, then down again
    assert -position["z"][-1] < 0.3
    status = ulog.get_dataset("vehicle_status").data
    assert status["arming_state"][0] == 2 and status["arming_state"][-1] == 1  # armed ... disarmed
    assert set(status["nav_state"]) == {3}  # AUTO.MISSION throughout: its last item lands
    stamps = position["timestamp"]
    assert np.all(np.diff(stamps) > 0) and np.median(np.diff(stamps)) == pytest.approx(100_000, abs=1000)
    assert any("Landing detected" in m.message for m in ulog.logged_messages)
    battery = ulog.get_dataset("battery_status").data
    assert battery["remaining"][-1] < battery["remaining"][0] <= 1.0

    assert vehicle.arm() == CommandResult.ACCEPTED  # a second arming, a second log
    fly_logged(vehicle, logs, lambda v: not v.armed, 30.0)
    fly_logged(vehicle, logs, lambda v: False, 0.1)
    assert [e.path.name[:8] for e in logs.entries()] == ["log_0001", "log_0002"]
    assert logs.erase() == 2 and logs.entries() == []


# ----- over UDP: MAVSDK injects the failure and downloads the log


def wait_for(condition, timeout: float, what: str) -> None:
    deadline = time.monotonic() + timeout
    while not condition():
        assert time.monotonic() < deadline, f"timed out waiting for {what}"
        time.sleep(0.05)


@pytest.mark.integration
@pytest.mark.timeout(300)
def test_mavsdk_injects_gps_off_and_downloads_the_flight_log(start_sitl, tmp_path):
    from mavsdk.plugins.failure import Failure, FailureError, FailureResult, FailureType, FailureUnit
    from mavsdk.plugins.log_files import LogFiles, LogFilesResult
    from sitl_process import WAIT_S, GroundStation, mission_item
    from test_sitl_mavsdk import mavsdk_system

    from sitl_quad.params import INT32, decode_value, encode_value
    from uavcore.geodesy import DEFAULT_HOME, LocalFrame
    from uavcore.mavlink import mavlink

    log_dir = tmp_path / "logs"
    vehicle = start_sitl(speed=20, extra_args=("--log-dir", str(log_dir)))
    gcs = GroundStation(vehicle.port)
    try:
        gcs.connect()
        inject = mavlink.MAV_CMD_INJECT_FAILURE
        gps_off = (mavlink.FAILURE_UNIT_SENSOR_GPS, mavlink.FAILURE_TYPE_OFF, 0)
        assert gcs.command(inject, *gps_off).result == mavlink.MAV_RESULT_DENIED  # SYS_FAILURE_EN 0, as PX4
        enabled = gcs.set_param("SYS_FAILURE_EN", encode_value(1, INT32), mavlink.MAV_PARAM_TYPE_INT32)
        assert enabled is not None and decode_value(enabled.param_value, INT32) == 1
        with mavsdk_system(vehicle.port) as system:
            # MAVSDK's Failure plugin reads SYS_FAILURE_EN when it starts and refuses by itself while it is 0
            failure, log_files = Failure(system), LogFiles(system)
            with pytest.raises(FailureError) as unsupported:
                failure.inject(FailureUnit.SENSOR_MAG, FailureType.OFF, 0)
            assert unsupported.value.result == FailureResult.UNSUPPORTED

            far = LocalFrame(*DEFAULT_HOME).from_ned(300.0, 0.0, 0.0)
            mission = [
                mission_item(0, mavlink.MAV_CMD_NAV_TAKEOFF, DEFAULT_HOME[0], DEFAULT_HOME[1], 10.0),
                mission_item(1, mavlink.MAV_CMD_NAV_WAYPOINT, float(far[0]), float(far[1]), 10.0),
            ]
            assert gcs.upload_mission(mission).type == mavlink.MAV_MISSION_ACCEPTED
            assert gcs.command(mavlink.MAV_CMD_COMPONENT_ARM_DISARM, 1).result == mavlink.MAV_RESULT_ACCEPTED
            assert gcs.command(mavlink.MAV_CMD_MISSION_START).result == mavlink.MAV_RESULT_ACCEPTED
            leg = gcs.recv("MISSION_CURRENT", timeout=WAIT_S, condition=lambda m: m.seq == 1)
            assert leg is not None
            assert gcs.recv("LOCAL_POSITION_NED", timeout=WAIT_S, condition=lambda m: m.x > 20.0)  # on its way

            failure.inject(FailureUnit.SENSOR_GPS, FailureType.OFF, 0)
            no_fix = gcs.recv("GPS_RAW_INT", timeout=WAIT_S, condition=lambda m: m.fix_type < 2)
            assert no_fix is not None and no_fix.satellites_visible == 0
            status = gcs.recv("SYS_STATUS", timeout=WAIT_S)
            assert not status.onboard_control_sensors_health & mavlink.MAV_SYS_STATUS_SENSOR_GPS
            disarmed = gcs.wait_heartbeat(lambda m: not m.base_mode & mavlink.MAV_MODE_FLAG_SAFETY_ARMED, WAIT_S)
            assert disarmed is not None  # descended where it was and landed

            wait_for(lambda: any(log_dir.glob("*.ulg")), WAIT_S, "the log to be finished")
            (entry,) = log_files.get_entries()
            assert entry.id == 0 and entry.size_bytes == next(log_dir.glob("*.ulg")).stat().st_size
            done = threading.Event()
            results: list[LogFilesResult] = []

            def progress(result, data, user_data) -> None:
                if result != LogFilesResult.NEXT:
                    results.append(result)
                    done.set()

            downloaded = tmp_path / "downloaded.ulg"
            log_files.download_log_file_async(entry, str(downloaded), progress)
            assert done.wait(WAIT_S) and results == [LogFilesResult.SUCCESS]
    finally:
        gcs.close()
    assert downloaded.read_bytes() == next(log_dir.glob("*.ulg")).read_bytes()
    check_gps_loss_log(downloaded)
    assert "Traceback" not in vehicle.stderr()


def check_gps_loss_log(path: Path) -> None:
    ulog = ULog(str(path))
    position = ulog.get_dataset("vehicle_local_position").data
    assert -position["z"].min() == pytest.approx(10.0, abs=0.6)  # the mission's altitude
    assert 20.0 < position["x"].max() < 250.0  # on the way north when the GPS went, far short of 300 m
    status = ulog.get_dataset("vehicle_status").data
    gps_lost = (status["failure_flags"] & FAILURE_GPS) != 0
    assert gps_lost.any() and not gps_lost[0]
    assert status["nav_state"][np.argmax(gps_lost) :].tolist().count(18) > 0  # then AUTO.LAND (Descend)
    texts = [m.message for m in ulog.logged_messages]
    assert "Failure injection: GPS off" in texts
    assert "Failsafe: GPS lost, no position: AUTO.LAND" in texts
    assert ulog.initial_parameters["SYS_FAILURE_EN"] == 1
