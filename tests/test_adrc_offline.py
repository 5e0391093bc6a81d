"""The in-process lockstep harness flies exactly the flight of the real processes over UDP lockstep, although
the ground station's commands reach the two vehicles after different numbers of idle ticks."""

from __future__ import annotations

import csv
import math
import time

import pytest
from sitl_process import GroundStation, start_lockstep_pair

from adrc_offboard.cli import make_controller
from bench.processes import free_udp_port, stop_reading_output
from sitl_quad.config import VehicleConfig
from sitl_quad.lockstep_harness import LockstepHarness
from sitl_quad.server import VehicleServer
from sitl_quad.vehicle import Vehicle
from uavcore.geodesy import DEFAULT_HOME, LocalFrame
from uavcore.mavlink import item_message, mavlink
from uavcore.mission import MavCmd, MavFrame, MissionItem

pytestmark = pytest.mark.integration

SEED = 7
FRAME = LocalFrame(*DEFAULT_HOME)  # the vehicle's default home


def short_mission() -> list[MissionItem]:
    """Takeoff to 5 m, one 36 m leg with a 0.5 s dwell, land there."""
    items = []
    for seq, (command, north, east, alt) in enumerate(
        [(MavCmd.NAV_TAKEOFF, 0, 0, 5), (MavCmd.NAV_WAYPOINT, 30, 20, 5), (MavCmd.NAV_LAND, 30, 20, 0)]
    ):
        lat, lon, _ = FRAME.from_ned(north, east, 0.0)
        items.append(
            MissionItem(
                seq=seq,
                frame=MavFrame.GLOBAL_RELATIVE_ALT_INT,
                command=command,
                current=int(seq == 0),
                param1=0.5,
                param2=1.0,
                param3=0.0,
                x=round(float(lat) * 1e7),
                y=round(float(lon) * 1e7),
                z=float(alt),
            )
        )
    return items


def fly_over_udp(tmp_path) -> list[list[str]]:
    """`python -m sitl_quad --lockstep --log` + `python -m adrc_offboard`; a pymavlink GCS flies the mission."""
    port = free_udp_port()
    log = tmp_path / "udp.csv"
    vehicle, controller = start_lockstep_pair(port, SEED, log)
    gcs = GroundStation(port)
    try:
        gcs.connect(timeout=60)
        assert gcs.recv("HEARTBEAT", timeout=60, condition=lambda m: m.get_srcComponent() == 191) is not None
        items = [item_message(it, 1, 1) for it in short_mission()]
        assert gcs.upload_mission(items).type == mavlink.MAV_MISSION_ACCEPTED
        assert gcs.command(mavlink.MAV_CMD_COMPONENT_ARM_DISARM, 1).result == mavlink.MAV_RESULT_ACCEPTED
        assert gcs.command(mavlink.MAV_CMD_MISSION_START, 0, 0).result == mavlink.MAV_RESULT_ACCEPTED
        deadline = time.monotonic() + 300  # lockstep runs at the machine's pace: a loaded one is several times slower
        while time.monotonic() < deadline:
            gcs.send_heartbeat()
            hb = gcs.recv("HEARTBEAT", timeout=2, condition=lambda m: m.get_srcComponent() == 1)
            if hb is not None and not hb.base_mode & mavlink.MAV_MODE_FLAG_SAFETY_ARMED:
                break
        else:
            pytest.fail("the UDP mission did not finish")
    finally:
        gcs.close()
        errors = [stop_reading_output(p, 20)[1] for p in (controller, vehicle)]
    assert all("Traceback" not in e for e in errors), errors
    with open(log) as f:
        return list(csv.reader(f))


class LogRows:
    """Stands in for the vehicle server so that its own CSV row format (VehicleServer._write_log) is applied
    to the harness's ticks; rows come out as the strings csv.reader reads back."""

    def __init__(self, vehicle: Vehicle) -> None:
        self.vehicle = vehicle
        self._log_writer = self
        self.rows = [list(VehicleServer.LOG_COLUMNS)]

    def writerow(self, row: list) -> None:
        self.rows.append([str(x) for x in row])

    def __call__(self, record) -> None:
        VehicleServer._write_log(self, record)


def fly_in_process() -> list[list[str]]:
    vehicle = Vehicle(VehicleConfig(), home=DEFAULT_HOME, seed=SEED)
    harness = LockstepHarness(vehicle, make_controller("adrc", 50.0))
    log = LogRows(vehicle)
    harness.fly_mission(short_mission(), on_tick=log)  # idles 25 ticks: the GCS's gap is arbitrary
    return log.rows


def from_takeoff(rows: list[list[str]]) -> list[list[str]]:
    """Every column but absolute time, from the first tick flown by a position loop to the disarm."""
    col = {name: i for i, name in enumerate(rows[0])}
    body = rows[1:]
    start = next(i for i, r in enumerate(body) if r[col["source"]] in ("builtin", "offboard"))
    end = next(i for i in range(start, len(body)) if body[i][col["armed"]] == "0")
    return [r[1:] for r in body[start : end + 1]]


def test_harness_flight_equals_the_udp_lockstep_flight_tick_by_tick(tmp_path):
    udp = from_takeoff(fly_over_udp(tmp_path))
    offline = from_takeoff(fly_in_process())
    col = {name: i - 1 for i, name in enumerate(VehicleServer.LOG_COLUMNS)}
    flown = [r for r in udp if r[col["source"]] == "offboard"]
    assert len(flown) > 500  # the ADRC flew most of it
    assert max(math.dist([float(r[col[k]]) for k in ("x", "y", "z")], [30.0, 20.0, 0.0]) for r in udp[-5:]) < 1.0
    assert len(offline) == len(udp)
    first_difference = next((i for i, (a, b) in enumerate(zip(udp, offline, strict=True)) if a != b), None)
    assert first_difference is None, (first_difference, udp[first_difference], offline[first_difference])
