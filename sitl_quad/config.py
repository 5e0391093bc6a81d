"""Everything configurable about the vehicle, as one tree of dataclasses (parameters are data, not code).

Each section is an immutable dataclass; the parameter table (sitl_quad.vehicle_params) replaces a section
when a PARAM_SET arrives and the vehicle rebuilds what depends on it.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from enum import IntEnum

from sitl_quad.attitude_pid import PidAttitudeGains
from sitl_quad.battery import BatteryConfig
from sitl_quad.disturbances import DisturbanceConfig
from sitl_quad.navigator import NavigatorConfig
from sitl_quad.position_control import PidPositionGains
from sitl_quad.sensors import SensorNoise
from sitl_quad.wind import WindConfig
from uavcore.airframe import Airframe


class FailsafeAction(IntEnum):
    """What the vehicle does when the offboard stream is lost (OFFB_LOSS_ACT)."""

    HOLD = 0
    LAND = 1
    RETURN = 2


class GeofenceAction(IntEnum):
    """What the vehicle does when it breaches its geofence (GF_ACTION, PX4's numbers and names)."""

    NONE = 0
    WARNING = 1  # a critical STATUSTEXT only
    HOLD = 2  # hold (AUTO.LOITER) where it is
    RETURN = 3  # return to launch (AUTO.RTL)
    TERMINATE = 4  # flight termination: not simulated (PX4 also keeps it behind a circuit breaker)
    LAND = 5  # land where it is (AUTO.LAND)


class DataLinkLossAction(IntEnum):
    """What the vehicle does when no ground station has been heard for COM_DL_LOSS_T (NAV_DLL_ACT, PX4's numbers;
    5 terminate and 6 lockdown are not simulated)."""

    DISABLED = 0
    HOLD = 1
    RETURN = 2
    LAND = 3


class LowBatteryAction(IntEnum):
    """What the vehicle does at the battery's critical and emergency levels (COM_LOW_BAT_ACT, PX4's numbers)."""

    WARNING = 0  # STATUSTEXT warnings only
    RETURN = 1  # return (AUTO.RTL) at critical and at emergency (PX4 keeps it, no longer lists it)
    LAND = 2  # land where it is (AUTO.LAND) at critical
    RETURN_OR_LAND = 3  # return at critical, land where it is at emergency


class AttitudeControllerKind(IntEnum):
    """Which inner loop flies the attitude (MC_ATT_CTRL)."""

    PID = 0
    ADRC = 1
    GEOMETRIC = 2  # Lee, Leok and McClamroch 2010's geometric law on SO(3) (sitl_quad.attitude_geometric)


@dataclass(frozen=True)
class FailsafeConfig:
    # OFFB_LOSS_T, simulated seconds: PX4's COM_OF_LOSS_T default (commander's offboardCheck: no setpoint for
    # that long and the offboard signal is lost). At 0.5 s a MAVSDK example's 20 Hz stream, stalled 0.51 s by a
    # loaded machine, failed over where PX4 would have flown on.
    offboard_loss_timeout_s: float = 1.0
    offboard_loss_action: int = FailsafeAction.HOLD  # OFFB_LOSS_ACT
    geofence_action: int = GeofenceAction.HOLD  # GF_ACTION
    geofence_max_horizontal_m: float = 0.0  # GF_MAX_HOR_DIST: horizontal distance from home, m (0: no limit)
    geofence_max_vertical_m: float = 0.0  # GF_MAX_VER_DIST: height above home, m (0: no limit)
    low_battery_action: int = LowBatteryAction.WARNING  # COM_LOW_BAT_ACT (PX4's default: warn only)
    arm_battery_min: float = -1.0  # COM_ARM_BAT_MIN: no arming below this charge; negative: below BAT_CRIT_THR
    data_link_loss_action: int = DataLinkLossAction.DISABLED  # NAV_DLL_ACT (PX4's default: disabled)
    data_link_loss_timeout_s: float = 10.0  # COM_DL_LOSS_T, s on the wall clock (ground stations beat on it)
    failure_injection_enabled: int = 0  # SYS_FAILURE_EN: MAV_CMD_INJECT_FAILURE refused while 0

    def __post_init__(self) -> None:
        if self.geofence_action == GeofenceAction.TERMINATE:
            raise ValueError("GF_ACTION 4 (flight termination) is not simulated: use 0, 1, 2, 3 or 5")


@dataclass(frozen=True)
class ControlConfig:
    attitude_controller: int = AttitudeControllerKind.PID  # MC_ATT_CTRL


@dataclass(frozen=True)
class SimulationConfig:
    """How the simulation runs, not what it simulates (SIM_SPEEDUP, ArduPilot SITL's name)."""

    # simulated seconds per wall second at most (sitl_quad.server): 0 = as fast as lockstep goes (paced: --speed)
    speedup: float = 0.0


@dataclass
class VehicleConfig:
    """`airframe` is the vehicle's true airframe: the physics flies it. `design_airframe` is the one its controllers
    are designed for (the mixer, the built-in position loop, the normalised-thrust scale, the ADRC attitude loop's
    b0 and motor lag, and bench.control.flight.make_controller's outer loops); None (the default) = the true one.
    A robustness study (bench/robustness.py) perturbs `airframe` and keeps the nominal one here."""

    airframe: Airframe = field(default_factory=Airframe.table2)
    wind: WindConfig = field(default_factory=WindConfig)
    disturbance: DisturbanceConfig = field(default_factory=DisturbanceConfig)
    sensor_noise: SensorNoise = field(default_factory=SensorNoise)
    navigator: NavigatorConfig = field(default_factory=NavigatorConfig)
    attitude_pid: PidAttitudeGains = field(default_factory=PidAttitudeGains)
    position_pid: PidPositionGains = field(default_factory=PidPositionGains)
    failsafe: FailsafeConfig = field(default_factory=FailsafeConfig)
    battery: BatteryConfig = field(default_factory=BatteryConfig)
    control: ControlConfig = field(default_factory=ControlConfig)
    simulation: SimulationConfig = field(default_factory=SimulationConfig)
    design_airframe: Airframe | None = None

    @property
    def controller_airframe(self) -> Airframe:
        """The airframe the controllers are designed for: design_airframe, or the true one when it is None."""
        return self.design_airframe if self.design_airframe is not None else self.airframe
