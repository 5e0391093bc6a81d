"""PX4's other fences and its safe points, at the MAVLink level: GF_MAX_HOR_DIST (horizontal distance from home)
and GF_MAX_VER_DIST (height above home), 0 = off, breached -> GF_ACTION with PX4's critical STATUSTEXT; rally
points (MAV_MISSION_TYPE_RALLY) as the places a return (RTL) may go to, the closest of them and home, as PX4's
RTL picks its destination with RTL_TYPE 0."""

from __future__ import annotations

import math

import pytest
from sitl_process import WAIT_S, GroundStation, mission_item
from test_sitl_vehicle import FRAME

from sitl_quad.config import FailsafeConfig
from sitl_quad.failsafe import HomeDistanceLimit, home_distance_breach
from uavcore.mavlink import mavlink
from uavcore.modes import FlightMode

SPEED = 10.0  # simulated seconds per wall second: the flights below are 20-40 s of simulated time


def test_home_distance_limits_are_off_at_zero_and_strict_beyond():
    off = FailsafeConfig()
    assert home_distance_breach(5000.0, 0.0, 900.0, off) is None
    limits = FailsafeConfig(geofence_max_horizontal_m=30.0, geofence_max_vertical_m=15.0)
    assert home_distance_breach(18.0, 24.0, 15.0, limits) is None  # exactly 30 m away and 15 m up: still inside
    horizontal = home_distance_breach(18.0, 24.1, 10.0, limits)
    assert horizontal == HomeDistanceLimit("max distance", 30.0)
    assert horizontal.px4_text == "Maximum distance from home reached (30.00000)"
    vertical = home_distance_breach(0.0, 0.0, 15.1, limits)
    assert vertical is not None and vertical.px4_text == "Maximum altitude above home reached (15.00000)"


def _fly_to(gcs: GroundStation, north: float, east: float, height: float) -> None:
    """Arm, take off and go to a place (NED m from home, height above home) with DO_REPOSITION."""
    for command, params in ((mavlink.MAV_CMD_COMPONENT_ARM_DISARM, (1,)), (mavlink.MAV_CMD_NAV_TAKEOFF, ())):
        ack = gcs.command(command, *params)
        assert ack is not None and ack.result == mavlink.MAV_RESULT_ACCEPTED, (command, ack)
    lat, lon, _ = FRAME.from_ned(north, east, 0.0)
    place = (math.nan, 1, 0, math.nan, float(lat) * 1e7, float(lon) * 1e7, FRAME.alt0 + height)
    ack = gcs.command(mavlink.MAV_CMD_DO_REPOSITION, *place, use_int=True)
    assert ack is not None and ack.result == mavlink.MAV_RESULT_ACCEPTED, ack


def _texts_until(gcs: GroundStation, last: str) -> list:
    """STATUSTEXTs up to the one starting with `last`."""
    texts = []
    while not (texts and texts[-1].text.startswith(last)):
        text = gcs.recv("STATUSTEXT", timeout=WAIT_S)
        assert text is not None, f"no STATUSTEXT starting {last!r}; got {[t.text for t in texts]}"
        texts.append(text)
    return texts


def _in_mode(mode: FlightMode):
    return lambda m: FlightMode.from_custom_mode(m.custom_mode) == mode


@pytest.mark.integration
def test_gf_max_hor_dist_set_over_mavlink_returns_a_vehicle_flying_beyond_it(start_sitl):
    vehicle = start_sitl(speed=SPEED, extra_args=("--param", "GF_ACTION=3"))
    gcs = GroundStation(vehicle.port)
    try:
        gcs.connect()
        assert gcs.set_param("GF_MAX_HOR_DIST", 30.0, mavlink.MAV_PARAM_TYPE_REAL32).param_value == 30.0
        _fly_to(gcs, 60.0, 0.0, 10.0)
        texts = _texts_until(gcs, "Geofence breached")
        limit, breach = texts[-2:]
        assert (limit.text, limit.severity) == ("Maximum distance from home reached (30.00000)", 2)
        assert breach.text == "Geofence breached (max distance): AUTO.RTL"
        assert gcs.wait_heartbeat(_in_mode(FlightMode.AUTO_RTL), WAIT_S)
        position = gcs.recv("GLOBAL_POSITION_INT", timeout=5)
        north, east, _ = FRAME.to_ned(position.lat * 1e-7, position.lon * 1e-7)
        assert 30.0 < math.hypot(north, east) < 45.0  # turned back just beyond the limit, far from 60 m
    finally:
        gcs.close()


@pytest.mark.integration
def test_gf_max_ver_dist_holds_a_vehicle_climbing_above_it(start_sitl):
    vehicle = start_sitl(speed=SPEED, extra_args=("--param", "GF_MAX_VER_DIST=15"))  # GF_ACTION: hold
    gcs = GroundStation(vehicle.port)
    try:
        gcs.connect()
        _fly_to(gcs, 0.0, 0.0, 40.0)
        texts = _texts_until(gcs, "Geofence breached")
        assert [t.text for t in texts[-2:]] == [
            "Maximum altitude above home reached (15.00000)",
            "Geofence breached (max altitude): AUTO.LOITER",
        ]

        def holding(msg) -> bool:
            return abs(msg.vz) < 10 and msg.relative_alt * 1e-3 > 15.0  # still (cm/s), above the limit

        held = gcs.recv("GLOBAL_POSITION_INT", timeout=WAIT_S, condition=holding)
        assert held is not None and held.relative_alt * 1e-3 < 20.0  # stopped by its braking distance, not 40 m
    finally:
        gcs.close()


@pytest.mark.integration
def test_rtl_goes_to_the_closest_of_home_and_the_rally_points(start_sitl):
    vehicle = start_sitl(speed=SPEED)
    gcs = GroundStation(vehicle.port)
    try:
        gcs.connect()
        rally = [(0.0, 40.0), (200.0, 0.0)]  # north, east m: the first is the closest to where the vehicle goes
        items = [
            mission_item(
                seq,
                mavlink.MAV_CMD_NAV_RALLY_POINT,
                *(float(c) for c in FRAME.from_ned(north, east, 0.0)[:2]),
                15.0,
                params=(0.0, 0.0, 0.0, 0.0),
                mission_type=mavlink.MAV_MISSION_TYPE_RALLY,
            )
            for seq, (north, east) in enumerate(rally)
        ]
        ack = gcs.upload_mission(items, mission_type=mavlink.MAV_MISSION_TYPE_RALLY, timeout=WAIT_S)
        assert ack is not None and ack.type == mavlink.MAV_MISSION_ACCEPTED
        _fly_to(gcs, 50.0, 60.0, 10.0)  # 78 m from home, 51 m from the first rally point

        def at(msg, north: float, east: float, radius: float) -> bool:
            n, e, _ = FRAME.to_ned(msg.lat * 1e-7, msg.lon * 1e-7)
            return math.hypot(n - north, e - east) < radius

        assert gcs.recv("GLOBAL_POSITION_INT", timeout=WAIT_S, condition=lambda m: at(m, 50.0, 60.0, 1.0))
        assert gcs.command(mavlink.MAV_CMD_NAV_RETURN_TO_LAUNCH).result == mavlink.MAV_RESULT_ACCEPTED
        landed = gcs.recv(
            "EXTENDED_SYS_STATE",
            timeout=2 * WAIT_S,
            condition=lambda m: m.landed_state == mavlink.MAV_LANDED_STATE_ON_GROUND,
        )
        assert landed is not None
        position = gcs.recv("GLOBAL_POSITION_INT", timeout=5)
        assert at(position, 0.0, 40.0, 1.0), FRAME.to_ned(position.lat * 1e-7, position.lon * 1e-7)
        assert position.relative_alt * 1e-3 < 0.5
    finally:
        gcs.close()
