"""MAV_CMD_DO_ORBIT: a circle flown by the position loop, reported as PX4's POSCTL.ORBIT, ended by another
command; in-process and over UDP."""

from __future__ import annotations

import math

import pytest
from sitl_process import WAIT_S, GroundStation
from test_sitl_vehicle import FRAME, HOME, fly_until

from sitl_quad.config import VehicleConfig
from sitl_quad.orbit import MAX_RADIUS_M, Orbit, OrbitYaw, orbit_from_command
from sitl_quad.vehicle import CommandResult, LandedState, Vehicle
from uavcore.mavlink import mavlink
from uavcore.modes import FlightMode, Px4MainMode, Px4PosctlSubMode
from uavcore.rotation import euler_from_quat, wrap_pi

CENTRE_NE = (30.0, 0.0)


@pytest.fixture
def flying() -> Vehicle:
    vehicle = Vehicle(VehicleConfig(), home=HOME, seed=3)
    vehicle.arm()
    vehicle.takeoff(5.0)
    fly_until(vehicle, lambda v: v.landed_state == LandedState.IN_AIR, 20.0)
    return vehicle


def angle_from(vehicle: Vehicle, centre: tuple[float, float]) -> float:
    north, east, _ = vehicle.truth.position
    return math.atan2(east - centre[1], north - centre[0])


def distance_from(vehicle: Vehicle, centre: tuple[float, float]) -> float:
    north, east, _ = vehicle.truth.position
    return math.hypot(north - centre[0], east - centre[1])


def test_orbit_flies_the_circle_clockwise_facing_the_centre(flying):
    lat, lon, _ = FRAME.from_ned(*CENTRE_NE, 0.0)
    result = flying.orbit(10.0, 2.0, OrbitYaw.HOLD_FRONT_TO_CIRCLE_CENTER, float(lat), float(lon), HOME[2] + 10.0)
    assert result == CommandResult.ACCEPTED
    assert flying.mode == FlightMode.ORBIT and flying.mode.custom_mode == (1 << 24) | (3 << 16)  # POSCTL.ORBIT
    fly_until(flying, lambda v: False, 40.0)  # out to the circle and around
    previous = angle_from(flying, CENTRE_NE)
    swept = 0.0
    for _ in range(round(15.0 / flying.outer_dt)):
        flying.tick()
        assert abs(distance_from(flying, CENTRE_NE) - 10.0) < 0.5
        assert abs(-flying.truth.position[2] - 10.0) < 0.3
        facing = euler_from_quat(flying.truth.quaternion)[2]
        assert abs(wrap_pi(facing - (angle_from(flying, CENTRE_NE) + math.pi))) < math.radians(10)
        now = angle_from(flying, CENTRE_NE)
        swept += wrap_pi(now - previous)
        previous = now
    assert swept == pytest.approx(2.0 * 15.0 / 10.0, rel=0.05)  # clockwise (angle increasing) at 2 m/s


def test_negative_radius_orbits_counter_clockwise_around_here_and_reposition_ends_it(flying):
    here = tuple(float(c) for c in flying.truth.position[:2])
    nan = math.nan
    assert flying.orbit(-8.0, 1.5, OrbitYaw.HOLD_INITIAL_HEADING, nan, nan, nan) == CommandResult.ACCEPTED
    heading = euler_from_quat(flying.truth.quaternion)[2]
    fly_until(flying, lambda v: False, 25.0)
    assert abs(distance_from(flying, here) - 8.0) < 0.5
    before = angle_from(flying, here)
    fly_until(flying, lambda v: False, 2.0)
    assert wrap_pi(angle_from(flying, here) - before) == pytest.approx(-1.5 * 2.0 / 8.0, rel=0.1)
    assert abs(wrap_pi(euler_from_quat(flying.truth.quaternion)[2] - heading)) < math.radians(5)
    lat, lon, _ = FRAME.from_ned(0.0, 0.0, 0.0)
    assert flying.reposition(float(lat), float(lon), HOME[2] + 5.0, nan) == CommandResult.ACCEPTED
    assert flying.mode == FlightMode.AUTO_LOITER and flying.navigator.orbit is None


def test_orbit_is_refused_on_the_ground_and_for_impossible_radii():
    vehicle = Vehicle(VehicleConfig(), home=HOME, seed=3)
    nan = math.nan
    assert vehicle.orbit(10.0, 2.0, 0, nan, nan, nan) == CommandResult.DENIED
    with pytest.raises(ValueError):
        orbit_from_command(None, (0.0, 0.0, -5.0), MAX_RADIUS_M * 2, 1.0, nan, None, None, 3.0, 12.0)


def test_nan_parameters_keep_the_orbit_under_way_and_speed_is_capped():
    current = Orbit((5.0, 5.0), -8.0, 20.0, 3.0, clockwise=False, yaw=OrbitYaw.HOLD_FRONT_TANGENT_TO_CIRCLE)
    nan = math.nan
    same = orbit_from_command(current, (0.0, 0.0, -5.0), nan, nan, OrbitYaw.UNCHANGED, None, None, 3.0, 12.0)
    assert same == current
    fast = orbit_from_command(None, (1.0, 2.0, -5.0), 3.0, 10.0, nan, None, None, 3.0, 12.0)
    assert fast.speed == pytest.approx(3.0)  # centripetal limit: sqrt(r a) = sqrt(3 * 3)
    assert fast.center == (1.0, 2.0) and fast.down == -5.0 and fast.clockwise
    reversed_by_speed = orbit_from_command(None, (0.0, 0.0, -5.0), 10.0, -2.0, nan, None, None, 3.0, 12.0)
    assert not reversed_by_speed.clockwise


@pytest.mark.integration
def test_do_orbit_over_udp_reports_posctl_orbit(start_sitl):
    vehicle = start_sitl(speed=5.0)
    gcs = GroundStation(vehicle.port)
    try:
        gcs.connect()
        assert gcs.command(mavlink.MAV_CMD_COMPONENT_ARM_DISARM, 1).result == mavlink.MAV_RESULT_ACCEPTED
        assert gcs.command(mavlink.MAV_CMD_NAV_TAKEOFF).result == mavlink.MAV_RESULT_ACCEPTED
        landed = gcs.recv("EXTENDED_SYS_STATE", timeout=WAIT_S, condition=lambda m: m.landed_state == 2)  # in air
        assert landed is not None
        lat, lon, _ = FRAME.from_ned(*CENTRE_NE, 0.0)
        ack = gcs.command(mavlink.MAV_CMD_DO_ORBIT, 10.0, 2.0, 0, math.nan, float(lat), float(lon), HOME[2] + 10.0)
        assert ack.result == mavlink.MAV_RESULT_ACCEPTED
        heartbeat = gcs.wait_heartbeat(lambda m: m.custom_mode >> 16 & 0xFF == Px4MainMode.POSCTL, timeout=WAIT_S)
        assert heartbeat is not None and heartbeat.custom_mode >> 24 == Px4PosctlSubMode.ORBIT
        on_circle = gcs.recv(
            "LOCAL_POSITION_NED",
            timeout=WAIT_S,
            condition=lambda m: (
                abs(math.hypot(m.x - CENTRE_NE[0], m.y - CENTRE_NE[1]) - 10.0) < 0.5 and abs(m.z + 10.0) < 0.5
            ),
        )
        assert on_circle is not None
        assert gcs.command(mavlink.MAV_CMD_NAV_RETURN_TO_LAUNCH).result == mavlink.MAV_RESULT_ACCEPTED
        assert gcs.wait_heartbeat(lambda m: FlightMode.from_custom_mode(m.custom_mode) == FlightMode.AUTO_RTL, WAIT_S)
    finally:
        gcs.close()
