"""DO_REPOSITION while taking off (MAVSDK's goto_location right after takeoff): accepted, as PX4 does, even
during the motors' spool-up; the climb finishes first, then the vehicle goes."""

from __future__ import annotations

import math

from test_sitl_vehicle import FRAME, HOME, fly_until

from sitl_quad.config import VehicleConfig
from sitl_quad.vehicle import CommandResult, LandedState, Vehicle
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
    assert vehicle.reposition(float(lat), float(lon), HOME[2] + 5.0, math.nan) == CommandResult.DENIED  # no takeoff
    vehicle.takeoff(5.0)
    fly_until(vehicle, lambda v: v.landed_state == LandedState.TAKEOFF and -v.truth.position[2] > 1.0, 10.0)
    assert vehicle.reposition(95.0, 0.0, HOME[2] + 5.0, math.nan) == CommandResult.DENIED  # not a latitude
    assert vehicle.reposition(float(lat), float(lon), HOME[2] + 5.0, math.nan) == CommandResult.ACCEPTED
    assert vehicle.takeoff(5.0) == CommandResult.ACCEPTED  # a new command drops the pending place
    fly_until(vehicle, lambda v: v.landed_state == LandedState.IN_AIR, 20.0)
    fly_until(vehicle, lambda v: False, 5.0)
    assert vehicle.mode == FlightMode.AUTO_TAKEOFF and math.hypot(*vehicle.truth.position[:2]) < 0.5
