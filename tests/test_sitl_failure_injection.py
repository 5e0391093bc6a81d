"""PX4's failure injection in the vehicle, without sockets: SYS_FAILURE_EN, the command's answers, and what each
failure does to a vehicle flying a mission (GPS lost: descend; a motor off: the physics decides; the battery
read as empty: the battery failsafe; no ground station: NAV_DLL_ACT)."""

from __future__ import annotations

import dataclasses

import pytest
from test_sitl_vehicle import HOME, fly_until, item

from sitl_quad.battery import BatteryWarning
from sitl_quad.config import DataLinkLossAction, LowBatteryAction, VehicleConfig
from sitl_quad.failure_injection import Failures, FailureType, FailureUnit, inject
from sitl_quad.vehicle import CommandResult, Vehicle
from uavcore.mission import MavCmd
from uavcore.modes import FlightMode

GPS, MOTOR = FailureUnit.SENSOR_GPS, FailureUnit.SYSTEM_MOTOR
BATTERY, MAVLINK_SIGNAL = FailureUnit.SYSTEM_BATTERY, FailureUnit.SYSTEM_MAVLINK_SIGNAL
OK, OFF = FailureType.OK, FailureType.OFF


def test_injection_answers_as_px4_commander():
    none = Failures()
    assert inject(none, False, GPS, OFF, 0).result == CommandResult.DENIED  # SYS_FAILURE_EN 0
    assert inject(none, False, GPS, OFF, 0).failures == none
    assert inject(none, True, FailureUnit.SENSOR_GPS, FailureType.STUCK, 0).result == CommandResult.UNSUPPORTED
    assert inject(none, True, 2, OFF, 0).result == CommandResult.UNSUPPORTED  # the magnetometer: not simulated
    assert inject(none, True, 250, OFF, 0).result == CommandResult.UNSUPPORTED  # no such unit
    assert inject(none, True, GPS, float("nan"), 0).result == CommandResult.UNSUPPORTED
    assert inject(none, True, MOTOR, OFF, 5).result == CommandResult.DENIED  # a quad has motors 1..4
    assert inject(none, True, BATTERY, OFF, 1).result == CommandResult.DENIED  # PX4's battery sim: instance 0 only
    two_off = inject(none, True, MOTOR, OFF, 2)
    assert two_off.result == CommandResult.ACCEPTED and two_off.failures.motors_off == {2}
    all_off = inject(two_off.failures, True, MOTOR, OFF, 0).failures
    assert all_off.motors_off == {1, 2, 3, 4}
    assert inject(all_off, True, MOTOR, OK, 3).failures.motors_off == {1, 2, 4}
    gps = inject(none, True, GPS, OFF, float("nan"))  # instance unset: all
    assert gps.failures == Failures(gps_off=True) and gps.text == "Failure injection: GPS off"
    assert inject(gps.failures, True, GPS, OK, 0).failures == none


def mission_vehicle(**failsafe) -> Vehicle:
    config = VehicleConfig()
    config.failsafe = dataclasses.replace(config.failsafe, failure_injection_enabled=1, **failsafe)
    vehicle = Vehicle(config, home=HOME, seed=3)
    vehicle.set_mission(
        [item(0, MavCmd.NAV_TAKEOFF, 0, 0, alt=10.0), item(1, MavCmd.NAV_WAYPOINT, 300.0, 0.0, alt=10.0)]
    )
    assert vehicle.arm() == CommandResult.ACCEPTED
    assert vehicle.start_mission() == CommandResult.ACCEPTED
    fly_until(vehicle, lambda v: -v.truth.position[2] > 8.0 and v.truth.position[0] > 10.0, 60.0)
    return vehicle


def texts(events) -> list[str]:
    return [e.text for e in events if e.kind == "text"]


def test_disabled_injection_is_denied_and_changes_nothing():
    vehicle = Vehicle(VehicleConfig(), home=HOME, seed=3)
    assert vehicle.inject_failure(GPS, OFF, 0) == CommandResult.DENIED
    assert vehicle.failures == Failures()
    assert "Failure injection disabled (SYS_FAILURE_EN 0)" in texts(vehicle.events)


def test_gps_off_in_a_mission_descends_and_lands_where_it_is():
    vehicle = mission_vehicle()
    north_at_loss = vehicle.truth.position[0]
    assert vehicle.inject_failure(GPS, OFF, 0) == CommandResult.ACCEPTED
    events = fly_until(vehicle, lambda v: not v.armed, 60.0)
    assert "Failsafe: GPS lost, no position: AUTO.LAND" in texts(events)
    assert vehicle.mode == FlightMode.AUTO_MISSION  # the disarm went back to the user's mode, as PX4
    assert not vehicle.armed and vehicle.sim.on_ground
    # level, with no horizontal control (PX4's Descend): it coasted on, braked by drag alone, far short of 300 m
    assert north_at_loss + 10.0 < vehicle.truth.position[0] < north_at_loss + 100.0
    assert vehicle.estimate.position[0] == pytest.approx(north_at_loss, abs=1.0)  # the last fix, held
    assert vehicle.set_mode(FlightMode.AUTO_LOITER) == CommandResult.DENIED  # Hold needs a position
    assert vehicle.arm() == CommandResult.DENIED  # no GPS fix
    assert vehicle.inject_failure(GPS, OK, 0) == CommandResult.ACCEPTED
    assert vehicle.set_mode(FlightMode.AUTO_LOITER) == CommandResult.ACCEPTED


def test_one_motor_off_takes_its_rotor_down_and_the_quad_falls():
    vehicle = mission_vehicle()
    assert vehicle.inject_failure(MOTOR, OFF, 2) == CommandResult.ACCEPTED
    events = fly_until(vehicle, lambda v: v.sim.on_ground, 30.0)
    assert "Failsafe: motor 2 failure" in texts(events)
    assert vehicle.sim.rotor_speeds[1] < 1.0  # its rotor stopped; the others were left spinning by the mixer
    assert vehicle.sim.on_ground  # a quad cannot hold yaw and lift on three rotors: it came down


def test_battery_off_reads_empty_and_the_battery_failsafe_lands():
    vehicle = mission_vehicle(low_battery_action=LowBatteryAction.LAND)
    charge = vehicle.battery.state_of_charge
    assert vehicle.inject_failure(BATTERY, OFF, 0) == CommandResult.ACCEPTED
    assert vehicle.battery.warning == BatteryWarning.EMERGENCY and vehicle.battery.reported_charge == 0.0
    events = fly_until(vehicle, lambda v: v.mode == FlightMode.AUTO_LAND, 1.0)
    assert "Emergency battery level! Landing immediately" in texts(events)
    assert vehicle.battery.state_of_charge == pytest.approx(charge, abs=0.01)  # the pack itself is as it was
    assert vehicle.inject_failure(BATTERY, OK, 0) == CommandResult.ACCEPTED
    assert vehicle.battery.reported_charge == vehicle.battery.state_of_charge


def test_data_link_loss_acts_as_nav_dll_act_says():
    vehicle = mission_vehicle(data_link_loss_action=DataLinkLossAction.RETURN)
    vehicle.data_link_lost(10.0)
    assert vehicle.mode == FlightMode.AUTO_RTL
    assert "Failsafe: no ground station for 10 s, AUTO.RTL" in texts(vehicle.events)
    quiet = mission_vehicle()  # NAV_DLL_ACT 0 (PX4's default): nothing happens
    quiet.data_link_lost(10.0)
    assert quiet.mode == FlightMode.AUTO_MISSION


# ----- over UDP: the command's answers, and a vehicle whose MAVLink signal is failed


@pytest.mark.integration
def test_mavlink_signal_off_silences_the_vehicle_until_the_one_command_that_restores_it(start_sitl):
    from sitl_process import WAIT_S, GroundStation

    from sitl_quad.params import INT32, encode_value
    from uavcore.mavlink import mavlink

    vehicle = start_sitl(speed=20)
    gcs = GroundStation(vehicle.port)
    inject_failure = mavlink.MAV_CMD_INJECT_FAILURE
    try:
        gcs.connect()
        assert gcs.command(inject_failure, MAVLINK_SIGNAL, OFF, 0).result == mavlink.MAV_RESULT_DENIED  # disabled
        assert gcs.set_param("SYS_FAILURE_EN", encode_value(1, INT32), mavlink.MAV_PARAM_TYPE_INT32) is not None
        assert gcs.command(inject_failure, GPS, FailureType.STUCK, 0).result == mavlink.MAV_RESULT_UNSUPPORTED
        assert gcs.command(inject_failure, MOTOR, OFF, 5).result == mavlink.MAV_RESULT_DENIED  # a quad: 1..4
        assert gcs.command(inject_failure, MAVLINK_SIGNAL, OFF, 0).result == mavlink.MAV_RESULT_ACCEPTED
        gcs.drain()
        assert gcs.recv("HEARTBEAT", timeout=2.5) is None  # silent (heartbeats are 1 Hz of wall clock)
        assert gcs.command(mavlink.MAV_CMD_REQUEST_MESSAGE, 148, timeout=2.0) is None  # and deaf
        gcs.mav.command_long_send(1, 1, inject_failure, 0, MAVLINK_SIGNAL, OK, 0, 0, 0, 0, 0)  # sent once: its
        restored = gcs.recv("COMMAND_ACK", timeout=WAIT_S, condition=lambda m: m.command == inject_failure)  # ACK heard
        assert restored is not None and restored.result == mavlink.MAV_RESULT_ACCEPTED
        assert gcs.recv("HEARTBEAT", timeout=WAIT_S) is not None
    finally:
        gcs.close()
    assert "Traceback" not in vehicle.stderr()
