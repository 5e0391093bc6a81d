"""Failsafes: the offboard setpoint stream and its loss (OFFB_LOSS_T, OFFB_LOSS_ACT); the geofence (GF_ACTION);
the battery (BAT_LOW_THR, BAT_CRIT_THR, BAT_EMERGEN_THR, COM_LOW_BAT_ACT); the data link (NAV_DLL_ACT,
COM_DL_LOSS_T); the position estimate lost with the GPS (an injected failure, sitl_quad.failure_injection).

Offboard setpoints (attitude + thrust from the offboard controller; body rates + thrust; position, velocity,
acceleration and yaw targets, see sitl_quad.offboard_setpoints) fly the vehicle only in OFFBOARD and only while
fresh: no new setpoint of any kind for `offboard_loss_timeout_s` of simulated time and the vehicle leaves
OFFBOARD for the mode OFFB_LOSS_ACT names, as PX4's commander does. The latest setpoint decides what is flown.
Ages are counted in integer physics steps, so a lockstep flight decides the loss at the same tick whatever the
wall clock did.

The geofence (uavcore.geofence, uploaded as a MISSION_TYPE_FENCE list) is checked every tick while flying;
a breach switches to the mode GF_ACTION names and says so in a STATUSTEXT.

The battery (sitl_quad.battery) is checked every tick while armed. Each warning level its charge falls to is
announced once per flight, in PX4's words, and at the critical and emergency levels COM_LOW_BAT_ACT picks the
mode, as PX4's failsafe framework does (Failsafe::fromBatteryWarningActParam): 0 warns only; 1 returns at both;
2 lands at both; 3 returns at critical and lands at emergency.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from sitl_quad.battery import BatteryWarning
from sitl_quad.config import DataLinkLossAction, FailsafeAction, FailsafeConfig, GeofenceAction, LowBatteryAction
from sitl_quad.offboard_setpoints import PositionTarget, RatesTarget, SetpointKind
from uavcore.geodesy import LocalFrame
from uavcore.geofence import Geofence, NorthEast, PlanarFence, Zone
from uavcore.modes import FlightMode
from uavcore.state import AttitudeTarget

OFFBOARD_LOSS_MODES = {
    FailsafeAction.HOLD: FlightMode.AUTO_LOITER,
    FailsafeAction.LAND: FlightMode.AUTO_LAND,
    FailsafeAction.RETURN: FlightMode.AUTO_RTL,
}


@dataclass
class OffboardStream:
    """The latest offboard setpoint: its kind and the one of that kind."""

    target: AttitudeTarget | None = None  # the latest attitude + thrust (SET_ATTITUDE_TARGET)
    position_target: PositionTarget | None = None  # the latest SET_POSITION_TARGET_*
    rates_target: RatesTarget | None = None  # the latest body rates + thrust
    kind: SetpointKind | None = None  # the kind of the latest setpoint: what OFFBOARD flies
    received_step: int = -(10**12)  # the physics step it arrived at
    answered_ms: int = -1  # the state time_boot_ms the latest attitude target answers (lockstep)
    count: int = 0

    def receive(self, target: AttitudeTarget, answered_ms: int, step_index: int) -> None:
        """An attitude + thrust target (the offboard controller's, answering state `answered_ms`)."""
        self.target = target
        self.answered_ms = answered_ms
        self._arrived(SetpointKind.ATTITUDE, step_index)

    def receive_position(self, target: PositionTarget, step_index: int) -> None:
        self.position_target = target
        self._arrived(SetpointKind.TRAJECTORY, step_index)

    def receive_rates(self, target: RatesTarget, step_index: int) -> None:
        self.rates_target = target
        self._arrived(SetpointKind.RATES, step_index)

    def _arrived(self, kind: SetpointKind, step_index: int) -> None:
        self.kind = kind
        self.received_step = step_index
        self.count += 1

    def age_s(self, step_index: int, dt: float) -> float:
        """Simulated seconds since the last target, at physics step `step_index` of `dt` seconds."""
        return (step_index - self.received_step) * dt

    def fresh(self, step_index: int, dt: float, failsafe: FailsafeConfig) -> bool:
        return self.age_s(step_index, dt) <= failsafe.offboard_loss_timeout_s + 1e-9


def offboard_loss_mode(failsafe: FailsafeConfig) -> FlightMode:
    """The mode OFFB_LOSS_ACT switches to when the stream is lost."""
    return OFFBOARD_LOSS_MODES[FailsafeAction(failsafe.offboard_loss_action)]


GEOFENCE_MODES = {
    GeofenceAction.HOLD: FlightMode.AUTO_LOITER,
    GeofenceAction.RETURN: FlightMode.AUTO_RTL,
    GeofenceAction.LAND: FlightMode.AUTO_LAND,
}


MAX_DISTANCE, MAX_ALTITUDE = "max distance", "max altitude"  # GF_MAX_HOR_DIST, GF_MAX_VER_DIST


@dataclass(frozen=True)
class HomeDistanceLimit:
    """GF_MAX_HOR_DIST or GF_MAX_VER_DIST, broken."""

    kind: str  # for the breach text, as a zone's kind (short: a STATUSTEXT holds 50 characters)
    limit_m: float

    @property
    def px4_text(self) -> str:
        """PX4's critical STATUSTEXT (Geofence::isCloserThanMaxDistToHome, isBelowMaxAltitude)."""
        what = "distance from home" if self.kind == MAX_DISTANCE else "altitude above home"
        return f"Maximum {what} reached ({self.limit_m:.5f})"


def home_limits_on(failsafe: FailsafeConfig) -> bool:
    return failsafe.geofence_max_horizontal_m > 0 or failsafe.geofence_max_vertical_m > 0


def home_distance_breach(
    north: float, east: float, height: float, failsafe: FailsafeConfig
) -> HomeDistanceLimit | None:
    """The limit a place (NED metres from home, its height above home) breaks, as PX4 checks them: farther from
    home horizontally than GF_MAX_HOR_DIST, higher above home than GF_MAX_VER_DIST; a limit of 0 is off."""
    max_horizontal, max_vertical = failsafe.geofence_max_horizontal_m, failsafe.geofence_max_vertical_m
    if max_horizontal > 0 and math.hypot(north, east) > max_horizontal:
        return HomeDistanceLimit(MAX_DISTANCE, max_horizontal)
    if max_vertical > 0 and height > max_vertical:
        return HomeDistanceLimit(MAX_ALTITUDE, max_vertical)
    return None


class GeofenceGuard:
    """The vehicle's geofence in its own NED frame, and whether the vehicle is breaching it.

    As PX4's geofence, the action (GF_ACTION) is taken once, when a breach begins; the vehicle may then be flown
    back inside (or further out: the ground station's business) without the action repeating every tick.
    """

    def __init__(self) -> None:
        self.fence = Geofence()
        self.plane = PlanarFence(())
        self.breached = False

    @property
    def present(self) -> bool:
        return not self.fence.empty

    def set_fence(self, fence: Geofence, frame: LocalFrame, position: NorthEast | None = None) -> list[str]:
        """Load a fence as PX4's Geofence::_updateFence does: a zone that bars home, the origin of `frame`
        (checkHomeRequirementsForGeofence), or bars `position`, the flying vehicle's place while GF_ACTION acts
        (checkCurrentPositionRequirementsForGeofence), is discarded and the rest kept. PX4's critical
        texts for the discarded zones, one each, are returned."""
        plane, barring_home = fence.in_plane(frame).split_barring((0.0, 0.0))
        texts = ["Geofence invalid, doesn't contain Home position"] * len(barring_home)
        if position is not None:
            plane, barring_vehicle = plane.split_barring(position)
            texts += ["Geofence invalid, doesn't contain current vehicle position"] * len(barring_vehicle)
        self.fence = Geofence(tuple(zone.zone for zone in plane.zones), fence.return_point)
        self.plane = plane
        self.breached = False
        return texts

    def violation(self, north: float, east: float) -> Zone | None:
        return self.plane.violation((north, east)) if self.present else None

    def new_breach(
        self, north: float, east: float, height: float, failsafe: FailsafeConfig
    ) -> Zone | HomeDistanceLimit | None:
        """What the vehicle at (north, east, height above home) has just broken, a zone of the fence or a limit
        of GF_MAX_HOR_DIST / GF_MAX_VER_DIST, else None (also while a breach goes on)."""
        breach: Zone | HomeDistanceLimit | None = self.violation(north, east)
        if breach is None:
            breach = home_distance_breach(north, east, height, failsafe)
        began = breach is not None and not self.breached
        self.breached = breach is not None
        return breach if began else None


def geofence_action_mode(action: GeofenceAction) -> FlightMode | None:
    """The mode GF_ACTION switches to on a breach (None: warn only, or nothing)."""
    return GEOFENCE_MODES.get(action)


# MAV_SEVERITY of the battery texts: PX4 logs low and critical as critical, emergency as emergency.
SEVERITY_EMERGENCY, SEVERITY_CRITICAL = 0, 2


@dataclass(frozen=True)
class BatteryFailsafe:
    """What a battery warning level does: the mode to switch to (None: warn only) and the text that says so."""

    mode: FlightMode | None
    text: str
    severity: int


def battery_failsafe(level: BatteryWarning, action: LowBatteryAction) -> BatteryFailsafe | None:
    """The reaction to the charge falling to `level` under COM_LOW_BAT_ACT = action (None for NONE)."""
    if level == BatteryWarning.LOW:
        return BatteryFailsafe(None, "Low battery level! Return advised", SEVERITY_CRITICAL)
    if level == BatteryWarning.CRITICAL:
        if action in (LowBatteryAction.RETURN, LowBatteryAction.RETURN_OR_LAND):
            return BatteryFailsafe(FlightMode.AUTO_RTL, "Critical battery level! Executing RTL", SEVERITY_CRITICAL)
        if action == LowBatteryAction.LAND:
            return BatteryFailsafe(
                FlightMode.AUTO_LAND, "Critical battery level! Landing immediately", SEVERITY_CRITICAL
            )
        return BatteryFailsafe(None, "Critical battery level! Landing advised", SEVERITY_CRITICAL)
    if level == BatteryWarning.EMERGENCY:
        if action == LowBatteryAction.RETURN:
            return BatteryFailsafe(FlightMode.AUTO_RTL, "Emergency battery level! Executing RTL", SEVERITY_EMERGENCY)
        if action in (LowBatteryAction.LAND, LowBatteryAction.RETURN_OR_LAND):
            return BatteryFailsafe(
                FlightMode.AUTO_LAND, "Emergency battery level! Landing immediately", SEVERITY_EMERGENCY
            )
        return BatteryFailsafe(None, "Emergency battery level! Please land", SEVERITY_EMERGENCY)
    return None


class BatteryGuard:
    """The battery warning levels already announced this flight: each is acted on once, when the charge first falls
    to it (a later, more severe level acts again), so the operator may take over after a battery failsafe."""

    def __init__(self) -> None:
        self.announced = BatteryWarning.NONE

    def reset(self) -> None:
        """A new flight (arming) or a new pack."""
        self.announced = BatteryWarning.NONE

    def new_level(self, level: BatteryWarning) -> BatteryWarning | None:
        """`level` if it is more severe than any announced since the reset, else None."""
        if level <= self.announced:
            return None
        self.announced = level
        return level


DATA_LINK_LOSS_MODES = {
    DataLinkLossAction.HOLD: FlightMode.AUTO_LOITER,
    DataLinkLossAction.RETURN: FlightMode.AUTO_RTL,
    DataLinkLossAction.LAND: FlightMode.AUTO_LAND,
}


def data_link_loss_mode(action: DataLinkLossAction) -> FlightMode | None:
    """The mode NAV_DLL_ACT switches to when no ground station is heard for COM_DL_LOSS_T (None: disabled)."""
    return DATA_LINK_LOSS_MODES.get(action)


# Modes that need a horizontal position estimate: without GPS, PX4's failsafe leaves them for Descend (reported as
# AUTO.LAND), as its position-loss failsafe does when only the altitude is still known. OFFBOARD is one here: this
# vehicle's offboard controller flies the navigator's position reference from the position estimate (PX4 likewise
# requires a position for offboard position and velocity setpoints).
POSITION_MODES = frozenset(
    {
        FlightMode.OFFBOARD,
        FlightMode.POSCTL,
        FlightMode.ORBIT,
        FlightMode.AUTO_TAKEOFF,
        FlightMode.AUTO_LOITER,
        FlightMode.AUTO_MISSION,
        FlightMode.AUTO_RTL,
    }
)
