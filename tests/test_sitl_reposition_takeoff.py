"""DO_REPOSITION while taking off (MAVSDK's goto_location right after takeoff): accepted, as PX4 does, even
during the motors' spool-up; the climb finishes first, then the vehicle goes. MAVSDK's goto_location switches
to hold before it sends DO_REPOSITION, and one second after takeoff() that hold lands during the spool-up and
cancels the takeoff: armed on the ground in AUTO_LOITER, the vehicle then takes off toward the place, as PX4's
position controller does with a loiter setpoint above a landed vehicle."""

from __future__ import annotations

import math

import pytest
from sitl_process import WAIT_S, GroundStation
from test_sitl_vehicle import FRAME, HOME, fly_until

from sitl_quad.config import VehicleConfig
from sitl_quad.vehicle import CommandResult, LandedState, Vehicle
from uavcore.mavlink import mavlink
from uavcore.modes import FlightMode


def test_reposition_during_spool_up_flies_after_the_climb():
    vehicle = Vehicle(VehicleConfig(), home=HOME, seed=3)
    vehicle.arm()
    assert vehicle.takeoff(5.0) == CommandResult.ACCEPTED
    vehicle.tick()
    assert vehicle.arming.pending_climb is not None  # still spooling up, on the ground
    lat, lon, _ = FRAME.from_ned(40.0, -30.0, 0.0)
    assert vehicle.reposition(float(lat), float(lon), HOME[2] + 12.0, math.nan) == CommandResult.ACCEPTED
    assert vehicle.mode == FlightMode.AUTO_TAKEOFF  # the climb goes on
    fly_until(vehicle, lambda v: v.mode != FlightMode.AUTO_TAKEOFF, 20.0)
    assert vehicle.mode == FlightMode.AUTO_LOITER
    north, east, down = vehicle.truth.position
    assert math.hypot(north, east) < 0.5 and abs(-down - 5.0) < 1.1  # climbed straight up first
    fly_until(vehicle, lambda v: False, 30.0)
    assert math.dist(vehicle.truth.position, (40.0, -30.0, -12.0)) < 0.5


def test_reposition_during_the_climb_and_refusals():
    vehicle = Vehicle(VehicleConfig(), home=HOME, seed=3)
    lat, lon, _ = FRAME.from_ned(10.0, 0.0, 0.0)
    assert vehicle.reposition(float(lat), float(lon), HOME[2] + 5.0, math.nan) == CommandResult.DENIED  # disarmed
    vehicle.arm()
    vehicle.takeoff(5.0)
    fly_until(vehicle, lambda v: v.landed_state == LandedState.TAKEOFF and -v.truth.position[2] > 1.0, 10.0)
    assert vehicle.reposition(95.0, 0.0, HOME[2] + 5.0, math.nan) == CommandResult.DENIED  # not a latitude
    assert vehicle.reposition(float(lat), float(lon), HOME[2] + 5.0, math.nan) == CommandResult.ACCEPTED
    assert vehicle.takeoff(5.0) == CommandResult.ACCEPTED  # a new command drops the pending place
    fly_until(vehicle, lambda v: v.landed_state == LandedState.IN_AIR, 20.0)
    fly_until(vehicle, lambda v: False, 5.0)
    assert vehicle.mode == FlightMode.AUTO_TAKEOFF and math.hypot(*vehicle.truth.position[:2]) < 0.5


def test_hold_during_spool_up_then_reposition_takes_off_toward_the_place():
    """MAVSDK's goto_location one second after takeoff(): DO_SET_MODE hold, then DO_REPOSITION."""
    vehicle = Vehicle(VehicleConfig(), home=HOME, seed=3)
    vehicle.arm()
    assert vehicle.takeoff() == CommandResult.ACCEPTED
    fly_until(vehicle, lambda v: False, 0.5)
    assert vehicle.set_mode(FlightMode.AUTO_LOITER) == CommandResult.ACCEPTED
    assert vehicle.sim.on_ground and vehicle.arming.pending_climb is None  # the hold cancelled the takeoff
    lat, lon, _ = FRAME.from_ned(-15.0, -40.0, 0.0)
    assert vehicle.reposition(float(lat), float(lon), HOME[2] + 20.0, math.nan) == CommandResult.ACCEPTED
    assert vehicle.mode == FlightMode.AUTO_LOITER
    fly_until(vehicle, lambda v: False, 40.0)
    assert vehicle.mode == FlightMode.AUTO_LOITER and vehicle.landed_state == LandedState.IN_AIR
    assert math.dist(vehicle.truth.position, (-15.0, -40.0, -20.0)) < 0.5


def test_hold_on_the_climbs_first_ticks_then_reposition_takes_off_toward_the_place():
    """The hold arriving just after the climb began, the vehicle still on the ground (its landed state already
    TAKEOFF): the hold idles the rotors there, and the reposition takes off toward the place."""
    vehicle = Vehicle(VehicleConfig(), home=HOME, seed=3)
    vehicle.arm()
    vehicle.takeoff()
    fly_until(vehicle, lambda v: v.landed_state == LandedState.TAKEOFF, 5.0)
    assert vehicle.sim.on_ground and not vehicle.arming.was_airborne
    assert vehicle.set_mode(FlightMode.AUTO_LOITER) == CommandResult.ACCEPTED
    lat, lon, _ = FRAME.from_ned(-15.0, -40.0, 0.0)
    assert vehicle.reposition(float(lat), float(lon), HOME[2] + 20.0, math.nan) == CommandResult.ACCEPTED
    fly_until(vehicle, lambda v: False, 40.0)
    assert vehicle.armed and vehicle.landed_state == LandedState.IN_AIR
    assert math.dist(vehicle.truth.position, (-15.0, -40.0, -20.0)) < 0.5


def test_reposition_armed_on_the_ground_without_a_place_height_climbs_to_the_takeoff_altitude():
    vehicle = Vehicle(VehicleConfig(), home=HOME, seed=3)
    vehicle.arm()
    lat, lon, _ = FRAME.from_ned(10.0, 0.0, 0.0)
    assert vehicle.reposition(float(lat), float(lon), math.nan, math.nan) == CommandResult.ACCEPTED  # height kept: 0
    fly_until(vehicle, lambda v: False, 30.0)
    north, east, down = vehicle.truth.position
    assert math.hypot(north - 10.0, east) < 0.5
    assert abs(-down - vehicle.config.navigator.takeoff_altitude) < 0.5


@pytest.mark.integration
def test_goto_one_second_after_takeoff_over_udp(start_sitl):
    """MAVSDK's goto example at the MAVLink level: arm, NAV_TAKEOFF, and within the motors' 1 s spool-up the
    hold switch (DO_SET_MODE AUTO_LOITER) and DO_REPOSITION as a COMMAND_INT: all accepted, the vehicle flies
    to the place 20 m above home."""
    # 4x: the spool-up lasts 0.25 s of wall clock, the three acknowledged commands take milliseconds (the
    # in-process tests above pin the hold's windows exactly; this one is the sequence over UDP)
    vehicle = start_sitl(speed=4.0)
    gcs = GroundStation(vehicle.port)
    try:
        gcs.connect()
        for command, params in (
            (mavlink.MAV_CMD_COMPONENT_ARM_DISARM, (1,)),
            (mavlink.MAV_CMD_NAV_TAKEOFF, ()),
            (mavlink.MAV_CMD_DO_SET_MODE, (mavlink.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED, *FlightMode.AUTO_LOITER.value)),
        ):
            ack = gcs.command(command, *params)
            assert ack is not None and ack.result == mavlink.MAV_RESULT_ACCEPTED, (command, ack)
        lat, lon, _ = FRAME.from_ned(-15.0, -40.0, 0.0)
        place = (math.nan, 1, 0, math.nan, float(lat) * 1e7, float(lon) * 1e7, HOME[2] + 20.0)
        ack = gcs.command(mavlink.MAV_CMD_DO_REPOSITION, *place, use_int=True)
        assert ack is not None and ack.result == mavlink.MAV_RESULT_ACCEPTED, ack

        def there(msg) -> bool:
            north, east, _ = FRAME.to_ned(msg.lat * 1e-7, msg.lon * 1e-7)
            return math.dist((north, east, msg.relative_alt * 1e-3), (-15.0, -40.0, 20.0)) < 1.0

        assert gcs.recv("GLOBAL_POSITION_INT", timeout=WAIT_S, condition=there) is not None
        assert gcs.wait_heartbeat(lambda m: FlightMode.from_custom_mode(m.custom_mode) == FlightMode.AUTO_LOITER)
    finally:
        gcs.close()
