"""The vehicle's autopilot functions without sockets: arming checks, modes, missions, failsafe, landing."""

from __future__ import annotations

import math

import numpy as np
import pytest

from sitl_quad.config import FailsafeAction, FailsafeConfig, VehicleConfig
from sitl_quad.vehicle import PREFLIGHT_DISARM_S, CommandResult, LandedState, Vehicle
from uavcore.geodesy import LocalFrame
from uavcore.mission import MavCmd, MavFrame, MissionItem
from uavcore.modes import FlightMode

HOME = (38.9210, 121.6630, 0.0)
FRAME = LocalFrame(*HOME)


def item(seq: int, command: int, north: float = 0.0, east: float = 0.0, alt: float = 5.0, **params) -> MissionItem:
    lat, lon, _ = FRAME.from_ned(north, east, 0.0)
    return MissionItem(
        seq=seq,
        frame=MavFrame.GLOBAL_RELATIVE_ALT_INT,
        command=command,
        current=int(seq == 0),
        x=round(float(lat) * 1e7),
        y=round(float(lon) * 1e7),
        z=alt,
        **params,
    )


def short_mission() -> list[MissionItem]:
    return [
        item(0, MavCmd.NAV_TAKEOFF, 0, 0),
        item(1, MavCmd.NAV_WAYPOINT, 20.0, 10.0, param1=0.5, param2=1.0),
        item(2, MavCmd.NAV_LAND, 20.0, 10.0, alt=0.0),
    ]


def fly_until(vehicle: Vehicle, condition, max_s: float) -> list:
    """Tick until condition(vehicle) or max_s of simulated time; returns every event seen."""
    events = []
    end = vehicle.t + max_s
    while vehicle.t < end and not condition(vehicle):
        vehicle.tick()
        events.extend(vehicle.events)
        vehicle.events.clear()
    return events


@pytest.fixture
def vehicle() -> Vehicle:
    return Vehicle(VehicleConfig(), home=HOME, seed=3)


def test_arming_checks_refuse_with_the_right_results(vehicle):
    assert vehicle.start_mission() == CommandResult.DENIED  # no mission
    assert vehicle.set_mode(FlightMode.AUTO_MISSION) == CommandResult.DENIED
    assert vehicle.set_mode(FlightMode.OFFBOARD) == CommandResult.TEMPORARILY_REJECTED  # no setpoint stream
    assert vehicle.takeoff() == CommandResult.DENIED  # disarmed
    assert vehicle.arm() == CommandResult.ACCEPTED
    assert vehicle.arm() == CommandResult.TEMPORARILY_REJECTED  # already armed
    assert vehicle.armed


def test_disarm_in_the_air_needs_force(vehicle):
    vehicle.arm()
    assert vehicle.takeoff(5.0) == CommandResult.ACCEPTED
    fly_until(vehicle, lambda v: -v.truth.position[2] > 3.0, 20.0)
    assert vehicle.in_air
    assert vehicle.disarm() == CommandResult.DENIED
    assert vehicle.armed
    assert vehicle.disarm(force=True) == CommandResult.ACCEPTED
    assert not vehicle.armed


def test_armed_on_the_ground_without_takeoff_disarms_itself(vehicle):
    vehicle.arm()
    events = fly_until(vehicle, lambda v: not v.armed, PREFLIGHT_DISARM_S + 2)
    assert not vehicle.armed
    assert any(e.kind == "armed" and "no takeoff" in e.text for e in events)
    assert vehicle.truth.position[2] == pytest.approx(0.0, abs=1e-6)  # never left the ground


def test_short_mission_flies_lands_and_disarms_in_order(vehicle):
    vehicle.set_mission(short_mission())
    assert vehicle.arm() == CommandResult.ACCEPTED
    assert vehicle.start_mission() == CommandResult.ACCEPTED
    events = fly_until(vehicle, lambda v: not v.armed, 90.0)
    reached = [e.seq for e in events if e.kind == "item_reached"]
    assert reached == [0, 1, 2]
    assert any(e.kind == "mission_complete" for e in events)
    assert not vehicle.armed and vehicle.landed_state == LandedState.ON_GROUND
    north, east, down = vehicle.truth.position
    assert math.hypot(north - 20.0, east - 10.0) < 1.0  # landed where the LAND item says
    assert down == pytest.approx(0.0, abs=0.05)


def test_mission_mode_waits_for_arming(vehicle):
    vehicle.set_mission(short_mission())
    assert vehicle.set_mode(FlightMode.AUTO_MISSION) == CommandResult.ACCEPTED
    fly_until(vehicle, lambda v: False, 1.0)
    assert vehicle.truth.position[2] == pytest.approx(0.0, abs=1e-6)  # disarmed: nothing flies
    vehicle.arm()
    fly_until(vehicle, lambda v: -v.truth.position[2] > 2.0, 15.0)
    assert -vehicle.truth.position[2] > 2.0  # arming in mission mode starts the mission


def test_return_and_land_refuse_arming_and_a_disarm_goes_back_to_the_users_mode(vehicle):
    """As PX4: no arming in Return or Land (it would fly them from the ground), and after a Return the vehicle
    is back in the last mode the user chose that allows arming (a failsafe's Return: test_sitl_battery_protocol)."""
    for mode in (FlightMode.AUTO_RTL, FlightMode.AUTO_LAND):
        assert vehicle.set_mode(mode) == CommandResult.ACCEPTED
        assert vehicle.arm() == CommandResult.DENIED and not vehicle.armed
    assert vehicle.set_mode(FlightMode.AUTO_LOITER) == CommandResult.ACCEPTED
    vehicle.set_mission(short_mission())
    assert vehicle.arm() == CommandResult.ACCEPTED
    assert vehicle.start_mission() == CommandResult.ACCEPTED
    fly_until(vehicle, lambda v: -v.truth.position[2] > 3.0, 20.0)
    assert vehicle.set_mode(FlightMode.AUTO_RTL) == CommandResult.ACCEPTED  # never a mode to go back to
    events = fly_until(vehicle, lambda v: not v.armed, 90.0)
    assert not vehicle.armed and any(e.kind == "armed" and "landing" in e.text for e in events)
    assert vehicle.mode == FlightMode.AUTO_MISSION  # the user's last choice; the takeoff mode never counts


def _feed_offboard_from_builtin(vehicle: Vehicle) -> None:
    """Stand in for an offboard controller: the built-in loop's answer, sent as an offboard target."""
    target = vehicle.position.update(vehicle.setpoint, vehicle.estimate, vehicle.outer_dt)
    vehicle.set_offboard_target(target, vehicle.time_boot_ms)


@pytest.mark.parametrize(
    ("action", "expected_mode"),
    [
        (FailsafeAction.HOLD, FlightMode.AUTO_LOITER),
        (FailsafeAction.LAND, FlightMode.AUTO_LAND),
    ],
)
def test_offboard_loss_triggers_the_failsafe_within_the_timeout(action, expected_mode):
    config = VehicleConfig(failsafe=FailsafeConfig(offboard_loss_timeout_s=0.5, offboard_loss_action=action))
    vehicle = Vehicle(config, home=HOME, seed=5)
    vehicle.arm()
    vehicle.takeoff(5.0)
    fly_until(vehicle, lambda v: v.landed_state == LandedState.IN_AIR, 20.0)
    _feed_offboard_from_builtin(vehicle)
    assert vehicle.set_mode(FlightMode.OFFBOARD) == CommandResult.ACCEPTED
    for _ in range(100):  # 2 s of offboard flight
        vehicle.tick()
        assert vehicle.source == "offboard"
        _feed_offboard_from_builtin(vehicle)
    stopped_at = vehicle.t
    fly_until(vehicle, lambda v: v.mode != FlightMode.OFFBOARD, 2.0)
    assert vehicle.mode == expected_mode
    assert vehicle.t - stopped_at <= 0.5 + 2 * vehicle.outer_dt
    # the built-in controller holds or lands: never hits the water faster than 1 m/s
    worst_descent_near_ground = 0.0
    end = vehicle.t + 40.0
    while vehicle.t < end and vehicle.armed:
        vehicle.tick()
        truth = vehicle.truth
        if -truth.position[2] < 0.5:
            worst_descent_near_ground = max(worst_descent_near_ground, truth.velocity[2])
    assert worst_descent_near_ground < 1.0
    if action == FailsafeAction.HOLD:
        assert vehicle.armed and -vehicle.truth.position[2] > 4.0
    else:
        assert not vehicle.armed


def test_set_current_item_and_clear(vehicle):
    vehicle.set_mission(short_mission())
    assert vehicle.set_current_item(1)
    assert vehicle.navigator.current_seq == 1
    assert not vehicle.set_current_item(7)
    vehicle.set_mission([])
    assert vehicle.start_mission() == CommandResult.DENIED


def test_same_seed_same_flight():
    def flight(seed: int) -> np.ndarray:
        v = Vehicle(VehicleConfig(), home=HOME, seed=seed)
        v.arm()
        v.takeoff(3.0)
        fly_until(v, lambda _: False, 3.0)
        return v.truth.position

    assert np.array_equal(flight(11), flight(11))
    assert not np.array_equal(flight(11), flight(12))


def test_mission_frame_item_without_position_is_not_a_place():
    rtl = MissionItem(seq=0, frame=MavFrame.MISSION, command=20)
    assert not rtl.has_position


def test_reposition_flies_to_the_place_and_holds(vehicle):
    assert vehicle.reposition(*FRAME.from_ned(30.0, -20.0, 0.0)[:2], 8.0, math.nan) == CommandResult.DENIED  # ground
    vehicle.arm()
    vehicle.takeoff(5.0)
    fly_until(vehicle, lambda v: v.landed_state == LandedState.IN_AIR, 20.0)
    lat, lon, _ = FRAME.from_ned(30.0, -20.0, 0.0)
    assert vehicle.reposition(float(lat), float(lon), 8.0, math.nan) == CommandResult.ACCEPTED
    assert vehicle.mode == FlightMode.AUTO_LOITER
    fly_until(vehicle, lambda v: False, 25.0)
    north, east, down = vehicle.truth.position
    assert math.dist((north, east, -down), (30.0, -20.0, 8.0)) < 0.5
    assert vehicle.reposition(95.0, 0.0, 8.0, math.nan) == CommandResult.DENIED  # not a latitude
    assert vehicle.reposition(float(lat), float(lon), -3.0, math.nan) == CommandResult.DENIED  # below home


def test_change_speed_sets_the_cruise_speed_of_later_legs(vehicle):
    assert vehicle.change_speed(4.0) == CommandResult.ACCEPTED
    assert vehicle.change_speed(-1.0) == CommandResult.DENIED
    assert vehicle.change_speed(float("nan")) == CommandResult.DENIED
    vehicle.set_mission([item(0, MavCmd.NAV_TAKEOFF), item(1, MavCmd.NAV_WAYPOINT, 80.0, 0.0, param1=0.0, param2=1.0)])
    vehicle.arm()
    vehicle.start_mission()
    fastest = 0.0
    end = vehicle.t + 60.0
    while vehicle.navigator.mission_state != "complete" and vehicle.t < end:
        vehicle.tick()
        fastest = max(fastest, float(np.hypot(*vehicle.setpoint.velocity[:2])))
    assert vehicle.navigator.mission_state == "complete"
    assert 3.5 < fastest <= 4.0 + 1e-6


def test_preflight_disarm_also_waits_for_the_wall_clock(vehicle):
    """At lockstep speeds simulated time races ahead of a ground station's wall-clock command retries."""
    wall = [100.0]
    vehicle.wall_clock = lambda: wall[0]
    vehicle.arm()
    fly_until(vehicle, lambda v: not v.armed, PREFLIGHT_DISARM_S + 2)
    assert vehicle.armed  # 12 s simulated, no wall time: the station's MISSION_START retry may still come
    wall[0] += PREFLIGHT_DISARM_S + 0.5
    fly_until(vehicle, lambda v: not v.armed, 1.0)
    assert not vehicle.armed
