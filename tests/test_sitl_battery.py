"""The flight battery (sitl_quad.battery) and what the vehicle does with it, in simulated time (no sockets).

The protocol side (BATTERY_STATUS, STATUSTEXT, MAV_CMD_BATTERY_RESET over UDP) is tests/test_sitl_battery_protocol.py.
"""

from __future__ import annotations

import dataclasses
import itertools
import math

import pytest
from test_sitl_vehicle import HOME, fly_until, item

from sitl_quad.battery import (
    Battery,
    BatteryConfig,
    BatteryWarning,
    electrical_power,
    pack_current,
    rotor_mechanical_power,
)
from sitl_quad.config import LowBatteryAction, VehicleConfig
from sitl_quad.disturbances import DisturbanceConfig
from sitl_quad.failsafe import battery_failsafe
from sitl_quad.params import ParameterError, ParameterTable
from sitl_quad.sensors import SensorNoise
from sitl_quad.vehicle import CommandResult, Vehicle
from sitl_quad.vehicle_params import VEHICLE_PARAMETERS
from uavcore.airframe import Airframe
from uavcore.mission import MavCmd
from uavcore.modes import FlightMode

PACK = BatteryConfig()


# ----- the model alone
def test_rotor_power_is_drag_torque_times_speed():
    airframe = Airframe.table2()
    omega = airframe.hover_rotor_speed
    shaft = rotor_mechanical_power([omega] * 4, airframe.kf)
    assert shaft == pytest.approx(4 * (airframe.kf * omega**2) * omega, rel=1e-12)  # sum Q_i Omega_i
    assert 100 < shaft < 125  # ~112 W of shaft power for the 1.3 kg Table 2 vehicle
    assert electrical_power(shaft, PACK, armed=True) == pytest.approx(shaft / PACK.efficiency + PACK.avionics_w)
    assert electrical_power(0.0, PACK, armed=False) == 0.0  # disarmed: nothing drawn


def test_open_circuit_voltage_rises_with_charge_between_empty_and_charged():
    socs = [i / 1000 for i in range(1001)]
    volts = [PACK.cell_ocv(s) for s in socs]
    assert all(b > a for a, b in itertools.pairwise(volts))
    assert volts[0] == pytest.approx(PACK.v_empty) and volts[-1] == pytest.approx(PACK.v_charged)
    assert PACK.cell_ocv(-0.5) == volts[0] and PACK.cell_ocv(1.5) == volts[-1]
    assert 3.7 < PACK.cell_ocv(0.5) < 3.9  # a LiPo's plateau


def test_terminal_voltage_sags_with_current_and_delivers_the_power_asked():
    voltages = []
    for power in (0.0, 50.0, 150.0, 400.0):
        battery = Battery(PACK, state_of_charge=0.6)
        battery.draw(power, 0.0)
        assert battery.voltage_v == pytest.approx(battery.open_circuit_v - battery.current_a * battery.resistance_ohm)
        assert battery.power_w == pytest.approx(power, rel=1e-9)
        voltages.append(battery.voltage_v)
    assert voltages == sorted(voltages, reverse=True) and voltages[0] > voltages[-1]


def test_beyond_the_packs_maximum_power_the_voltage_collapses_to_half():
    ocv, resistance = 16.0, 0.02
    most = ocv**2 / (4 * resistance)
    assert pack_current(10 * most, ocv, resistance) == pytest.approx(ocv / (2 * resistance))
    assert pack_current(100.0, ocv, 0.0) == pytest.approx(100.0 / ocv)


def test_state_of_charge_falls_by_the_coulombs_drawn():
    battery = Battery(PACK, state_of_charge=0.9)
    current, dt, steps = 12.5, 0.02, 5000  # 100 s at 12.5 A
    for _ in range(steps):
        battery.discharge(current, dt)
    drawn_mah = current * dt * steps / 3.6
    assert battery.consumed_mah == pytest.approx(drawn_mah, rel=1e-9)
    assert battery.state_of_charge == pytest.approx(0.9 - drawn_mah / PACK.capacity_mah, rel=1e-9)
    battery.discharge(1e6, 1.0)  # far more than is left: empty, not negative
    assert battery.state_of_charge == 0.0


def test_warning_levels_follow_the_thresholds():
    assert [PACK.warning(s) for s in (0.5, 0.15, 0.149, 0.07, 0.069, 0.05, 0.049)] == [
        BatteryWarning.NONE,
        BatteryWarning.NONE,
        BatteryWarning.LOW,
        BatteryWarning.LOW,
        BatteryWarning.CRITICAL,
        BatteryWarning.CRITICAL,
        BatteryWarning.EMERGENCY,
    ]


@pytest.mark.parametrize(
    ("action", "critical", "emergency"),
    [
        (LowBatteryAction.WARNING, None, None),
        (LowBatteryAction.RETURN, FlightMode.AUTO_RTL, FlightMode.AUTO_RTL),
        (LowBatteryAction.LAND, FlightMode.AUTO_LAND, FlightMode.AUTO_LAND),
        (LowBatteryAction.RETURN_OR_LAND, FlightMode.AUTO_RTL, FlightMode.AUTO_LAND),
    ],
)
def test_com_low_bat_act_picks_px4s_mode_at_critical_and_emergency(action, critical, emergency):
    assert battery_failsafe(BatteryWarning.NONE, action) is None
    assert battery_failsafe(BatteryWarning.LOW, action).mode is None
    assert battery_failsafe(BatteryWarning.CRITICAL, action).mode == critical
    assert battery_failsafe(BatteryWarning.EMERGENCY, action).mode == emergency


def test_pack_parameters_are_validated():
    table = ParameterTable(VEHICLE_PARAMETERS, VehicleConfig())
    with pytest.raises(ParameterError, match="BAT1_V_EMPTY"):
        table.set("BAT1_V_EMPTY", 4.3)  # above BAT1_V_CHARGED
    with pytest.raises(ParameterError):
        table.set("COM_LOW_BAT_ACT", 4)
    with pytest.raises(ValueError):
        Battery(PACK, state_of_charge=1.2)


# ----- the vehicle
def still_vehicle(**params: float) -> Vehicle:
    """The Table 2 vehicle without D terms or sensor noise, parameters set by PX4 name."""
    config = VehicleConfig(disturbance=DisturbanceConfig.none(), sensor_noise=SensorNoise.none())
    table = ParameterTable(VEHICLE_PARAMETERS, config)
    for name, value in params.items():
        table.set(name, value)
    return Vehicle(config, home=HOME, seed=1)


def test_hovering_vehicle_draws_the_rotors_power_from_the_pack():
    vehicle = still_vehicle()
    vehicle.arm()
    vehicle.takeoff(10.0)
    fly_until(vehicle, lambda v: False, 20.0)
    airframe, pack = vehicle.config.airframe, vehicle.config.battery
    hover = electrical_power(rotor_mechanical_power([airframe.hover_rotor_speed] * 4, airframe.kf), pack, armed=True)
    assert vehicle.battery.power_w == pytest.approx(hover, rel=0.01)
    assert 9.0 < vehicle.battery.current_a < 11.5  # ~2.5C from a 4S 4000 mAh pack
    assert vehicle.battery.consumed_mah > 0 and vehicle.battery.state_of_charge < 1.0


def test_hover_endurance_of_the_default_pack():
    """Time to empty scales with capacity (coulomb counting at the same power): a 400 mAh pack empties in a tenth
    of the default 4000 mAh pack's time, which must be the ~20-25 min of quadrotors of this mass."""
    vehicle = still_vehicle(BAT1_CAPACITY=400.0)
    vehicle.arm()
    vehicle.takeoff(10.0)
    armed_at = vehicle.t
    fly_until(vehicle, lambda v: v.battery.state_of_charge <= 0.0, 300.0)
    full_pack_min = (vehicle.t - armed_at) * 10 / 60
    assert 21.0 < full_pack_min < 25.0


def test_disarmed_on_the_ground_the_pack_holds_its_charge():
    vehicle = still_vehicle()
    fly_until(vehicle, lambda v: False, 60.0)
    assert vehicle.battery.state_of_charge == 1.0 and vehicle.battery.current_a == 0.0
    assert vehicle.battery.voltage_v == pytest.approx(4 * PACK.v_charged)


def test_arming_is_refused_below_the_critical_level_or_com_arm_bat_min():
    vehicle = still_vehicle()
    vehicle.battery.reset(0.06)
    assert vehicle.arm() == CommandResult.DENIED
    assert any("Arming denied: battery 6%" in e.text for e in vehicle.events)
    vehicle.battery.reset(0.10)  # low, not critical: PX4 arms and warns
    assert vehicle.arm() == CommandResult.ACCEPTED
    fly_until(vehicle, lambda v: False, 0.1)
    assert vehicle.battery_guard.announced == BatteryWarning.LOW
    vehicle.disarm()
    vehicle.config.failsafe = dataclasses.replace(vehicle.config.failsafe, arm_battery_min=0.5)
    assert vehicle.arm() == CommandResult.DENIED  # 10 % < COM_ARM_BAT_MIN 50 %


def test_battery_swap_only_landed_and_disarmed():
    vehicle = still_vehicle()
    vehicle.battery.reset(0.5)
    vehicle.arm()
    assert vehicle.replace_battery(1.0) == CommandResult.DENIED  # armed on the ground
    vehicle.takeoff(5.0)
    fly_until(vehicle, lambda v: v.in_air, 10.0)
    assert vehicle.replace_battery(1.0) == CommandResult.TEMPORARILY_REJECTED  # flying
    assert vehicle.set_mode(FlightMode.AUTO_LAND) == CommandResult.ACCEPTED
    fly_until(vehicle, lambda v: not v.armed, 60.0)
    assert not vehicle.armed and vehicle.battery.state_of_charge < 0.5
    assert vehicle.replace_battery(1.0) == CommandResult.ACCEPTED
    assert vehicle.battery.state_of_charge == 1.0 and vehicle.battery.consumed_mah == 0.0


def test_return_at_critical_then_land_at_emergency():
    """COM_LOW_BAT_ACT 3 on a small pack: the mission flies out, critical turns it home, emergency lands it where
    it is; each level is announced once, in order."""
    vehicle = still_vehicle(
        BAT1_CAPACITY=1000.0, BAT_LOW_THR=0.45, BAT_CRIT_THR=0.25, BAT_EMERGEN_THR=0.1, COM_LOW_BAT_ACT=3
    )
    vehicle.battery.reset(0.5)
    vehicle.set_mission(
        [item(0, MavCmd.NAV_TAKEOFF, 0, 0, alt=10.0), item(1, MavCmd.NAV_WAYPOINT, 3000.0, 0.0, alt=10.0)]
    )
    assert vehicle.arm() == CommandResult.ACCEPTED
    assert vehicle.start_mission() == CommandResult.ACCEPTED
    events = fly_until(vehicle, lambda v: not v.armed, 900.0)
    texts = [e.text for e in events if e.kind == "text" and "battery level" in e.text]
    assert texts == [
        "Low battery level! Return advised",
        "Critical battery level! Executing RTL",
        "Emergency battery level! Landing immediately",
    ]
    modes = [e.text for e in events if e.kind == "mode"]
    # the failsafes' Return then Land, and at the disarm back to the user's Mission (as PX4)
    assert modes[-3:] == [FlightMode.AUTO_RTL.label, FlightMode.AUTO_LAND.label, FlightMode.AUTO_MISSION.label]
    north = vehicle.truth.position[0]
    assert 0.0 < north < 1000.0 and math.isclose(vehicle.truth.position[2], 0.0, abs_tol=0.1)  # on the way home
    assert vehicle.battery.state_of_charge < 0.1


def test_battery_parameters_apply_to_the_pack_in_use():
    vehicle = still_vehicle()
    vehicle.battery.reset(0.4)
    table = ParameterTable(VEHICLE_PARAMETERS, vehicle.config)
    table.set("BAT_LOW_THR", 0.45)
    vehicle.apply_config("battery")
    assert vehicle.battery.state_of_charge == 0.4 and vehicle.battery.warning == BatteryWarning.LOW
