"""PX4's failure injection (MAV_CMD_INJECT_FAILURE, `failure <unit> <type> -i <instance>` in PX4's shell): which
failures are in force, and what a command asks. Pure data, no I/O; the vehicle applies the failures
(sitl_quad.vehicle) and sitl_quad.mavlink.failure_injection carries the command.

As PX4 (src/modules/commander/Commander.cpp, failure_detector/FailureInjector.cpp and the simulators'
handlers): the command is refused with MAV_RESULT_DENIED while SYS_FAILURE_EN is 0; a unit/type pair nobody
handles is MAV_RESULT_UNSUPPORTED; FAILURE_TYPE_OK restores. Supported here:
- SENSOR_GPS OFF / OK (instance 0 = all, or 1: the one receiver): no fix, no position estimate;
- SYSTEM_MOTOR OFF / OK (instance 0 = all motors, else the motor number 1..4): the ESC stops driving that rotor,
  as PX4's FailureInjector blocks the ESC (`_esc_blocked`);
- SYSTEM_BATTERY OFF / OK (instance 0 only, as PX4's BatterySimulator): the pack reads as empty
  (`_force_empty_battery`), so the battery failsafe sees the emergency level;
- SYSTEM_MAVLINK_SIGNAL OFF / OK (instance 0): the vehicle neither sends nor receives MAVLink, so the ground
  station sees the link lost and the vehicle's data-link-loss failsafe (NAV_DLL_ACT) may act.
A motor or receiver number this vehicle does not have is MAV_RESULT_DENIED (the command is supported, its
instance is not valid here).
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from enum import IntEnum

from sitl_quad.vehicle_types import CommandResult
from uavcore.state import TrajectorySetpoint, VehicleState

MOTORS = (1, 2, 3, 4)


class FailureUnit(IntEnum):
    """MAVLink FAILURE_UNIT (the ones this vehicle knows of; any other number is unsupported)."""

    SENSOR_GPS = 4
    SYSTEM_BATTERY = 100
    SYSTEM_MOTOR = 101
    SYSTEM_MAVLINK_SIGNAL = 105


class FailureType(IntEnum):
    """MAVLink FAILURE_TYPE."""

    OK = 0
    OFF = 1
    STUCK = 2
    GARBAGE = 3
    WRONG = 4
    SLOW = 5
    DELAYED = 6
    INTERMITTENT = 7


# the instances each unit has: 0 means "all", as in PX4's failure command
INSTANCES = {
    FailureUnit.SENSOR_GPS: (0, 1),
    FailureUnit.SYSTEM_BATTERY: (0,),
    FailureUnit.SYSTEM_MOTOR: (0, *MOTORS),
    FailureUnit.SYSTEM_MAVLINK_SIGNAL: (0,),
}
SUPPORTED_TYPES = (FailureType.OK, FailureType.OFF)


@dataclass(frozen=True)
class Failures:
    """The failures in force (none by default)."""

    gps_off: bool = False
    motors_off: frozenset[int] = frozenset()  # motor numbers 1..4
    battery_empty: bool = False
    mavlink_off: bool = False

    @property
    def any(self) -> bool:
        return self != Failures()


@dataclass(frozen=True)
class Injection:
    """The answer to one MAV_CMD_INJECT_FAILURE: its result, the failures from now on, and what to say."""

    result: CommandResult
    failures: Failures
    text: str = ""


def inject(failures: Failures, enabled: bool, unit: float, kind: float, instance: float) -> Injection:
    """MAV_CMD_INJECT_FAILURE(param1 unit, param2 type, param3 instance) with SYS_FAILURE_EN = enabled."""
    if not enabled:
        return Injection(CommandResult.DENIED, failures, "Failure injection disabled (SYS_FAILURE_EN 0)")
    try:
        failure_unit, failure_type = FailureUnit(int(unit)), FailureType(int(kind))
    except (ValueError, OverflowError):  # NaN, or a number MAVLink (or this vehicle) has no unit or type for
        return Injection(CommandResult.UNSUPPORTED, failures)
    if failure_type not in SUPPORTED_TYPES:
        return Injection(CommandResult.UNSUPPORTED, failures)
    number = int(instance) if instance == instance else 0  # NaN: unset, i.e. 0 = all
    if number not in INSTANCES[failure_unit]:
        return Injection(CommandResult.DENIED, failures, f"Failure injection: no {failure_unit.name} {number}")
    off = failure_type == FailureType.OFF
    word = "off" if off else "ok"
    if failure_unit == FailureUnit.SENSOR_GPS:
        changed = dataclasses.replace(failures, gps_off=off)
        text = f"Failure injection: GPS {word}"
    elif failure_unit == FailureUnit.SYSTEM_BATTERY:
        changed = dataclasses.replace(failures, battery_empty=off)
        text = f"Failure injection: battery {'empty' if off else word}"
    elif failure_unit == FailureUnit.SYSTEM_MOTOR:
        motors = frozenset(MOTORS) if number == 0 else frozenset({number})
        now_off = failures.motors_off | motors if off else failures.motors_off - motors
        changed = dataclasses.replace(failures, motors_off=now_off)
        text = f"Failure injection: motor {'all' if number == 0 else number} {word}"
    else:
        changed = dataclasses.replace(failures, mavlink_off=off)
        text = f"Failure injection: MAVLink signal {word}"
    return Injection(CommandResult.ACCEPTED, changed, text)


def estimate_without_gps(measured: VehicleState, held_north_east: tuple[float, float]) -> VehicleState:
    """The state estimate with the GPS off: the altitude and attitude still measured (barometer, IMU), the horizontal
    position held where the last fix put it and the horizontal velocity unknown (0), as an estimator with no
    horizontal aiding leaves them. A position loop flying it holds the vehicle level: it drifts with its momentum and
    the wind while it descends, as PX4's Descend."""
    position = measured.position.copy()
    position[:2] = held_north_east
    velocity = measured.velocity.copy()
    velocity[:2] = 0.0
    return dataclasses.replace(measured, position=position, velocity=velocity)


def without_horizontal_control(setpoint: TrajectorySetpoint, estimate: VehicleState) -> TrajectorySetpoint:
    """A setpoint with no horizontal part: held where the estimate is, no velocity or acceleration asked. With the
    position estimate gone the navigator's horizontal reference means nothing (it would chase a frozen estimate to
    full tilt); the vehicle keeps level and controls only its height and yaw, as PX4's Descend."""
    position = setpoint.position.copy()
    position[:2] = estimate.position[:2]
    velocity, acceleration = setpoint.velocity.copy(), setpoint.acceleration.copy()
    velocity[:2] = 0.0
    acceleration[:2] = 0.0
    return dataclasses.replace(setpoint, position=position, velocity=velocity, acceleration=acceleration)


def rotor_health(failures: Failures) -> tuple[float, float, float, float]:
    """Per rotor 1.0 (driven) or 0.0 (its ESC blocked): what the physics multiplies the rotor's command by."""
    return tuple(0.0 if motor in failures.motors_off else 1.0 for motor in MOTORS)  # type: ignore[return-value]
