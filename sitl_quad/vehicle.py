"""The autopilot without its radio: one simulated quadrotor as its users see it.

`Vehicle` is a facade over the parts it composes, each in its own module:
- sitl_quad.flight_loop: physics, mixer, position and attitude loops at their rates (`FlightLoop`);
- sitl_quad.navigator: the mission and the reference the position loop follows;
- sitl_quad.arming: armed or not, spool-up, the land detector and its automatic disarms (`ArmingState`);
- sitl_quad.flight_modes: what each flight mode asks of the navigator;
- sitl_quad.failsafe: the offboard setpoint stream and its loss (`OffboardStream`), the geofence (`GeofenceGuard`),
  the battery's warnings and actions (`BatteryGuard`);
- sitl_quad.battery: the flight battery, drawn every tick by the rotors' power (`Battery`);
- sitl_quad.failure_injection: the failures MAV_CMD_INJECT_FAILURE put in force (`Failures`);
- sitl_quad.offboard_setpoints: what position/velocity and body-rate setpoints ask of the loops;
- sitl_quad.orbit: DO_ORBIT's circle;
- sitl_quad.vehicle_types: command results, events, tick records.

`Vehicle.tick()` advances one outer-loop period (50 Hz by default): the navigator's reference, the outer
loop's attitude target (built-in PID cascade toward the navigator's reference or an offboard position target,
or the offboard controller's SET_ATTITUDE_TARGET while in OFFBOARD and fresh), then the attitude loop at
250 Hz, each attitude step driving 1 kHz RK4 physics steps.
Nothing here knows MAVLink: commands return a `CommandResult` whose numbers equal MAV_RESULT's, and what
the outside world should hear about is queued as `VehicleEvent`s.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable, Mapping

import numpy as np

from sitl_quad.arming import (
    AIRBORNE_ALTITUDE_M,
    CLIMBING_ACTIVITIES,
    FORCE_DISARM_MAGIC,
    PREFLIGHT_DISARM_S,
    SPOOLUP_S,
    ArmingState,
    AutoDisarm,
    LandedState,
    PendingClimb,
    touching_ground,
)
from sitl_quad.battery import Battery, electrical_power, rotor_mechanical_power
from sitl_quad.config import (
    AttitudeControllerKind,
    DataLinkLossAction,
    GeofenceAction,
    LowBatteryAction,
    VehicleConfig,
)
from sitl_quad.failsafe import (
    POSITION_MODES,
    SEVERITY_CRITICAL,
    BatteryGuard,
    GeofenceGuard,
    HomeDistanceLimit,
    OffboardStream,
    battery_failsafe,
    data_link_loss_mode,
    geofence_action_mode,
    home_limits_on,
    offboard_loss_mode,
)
from sitl_quad.failure_injection import (
    Failures,
    estimate_without_gps,
    inject,
    rotor_health,
    without_horizontal_control,
)
from sitl_quad.flight_loop import AttitudeLoopFactory, FlightLoop, builtin_pid_loop, motors_off_target
from sitl_quad.flight_modes import (
    ARMING_PREVENTED_MODES,
    CLIMB_MODES,
    flight_navigator,
    kept_after_disarm,
    reposition_target,
    resume_seq,
    start_activity,
)
from sitl_quad.navigator import Navigator
from sitl_quad.offboard_setpoints import OffboardTracker, PositionTarget, RatesTarget, SetpointKind, wants_takeoff
from sitl_quad.orbit import orbit_from_command
from sitl_quad.position_control import PidPositionController
from sitl_quad.rotors import Mixer
from sitl_quad.sensors import MeasurementDelay
from sitl_quad.simulator import Simulator
from sitl_quad.vehicle_types import CommandResult, TickRecord, VehicleEvent
from uavcore.control import AttitudeController
from uavcore.geodesy import LocalFrame
from uavcore.geofence import Geofence
from uavcore.mission import MissionItem
from uavcore.modes import FlightMode
from uavcore.rotation import euler_from_quat
from uavcore.state import AttitudeTarget, TrajectorySetpoint, VehicleState

# The vehicle's vocabulary, importable from here as before the split.
__all__ = [
    "FORCE_DISARM_MAGIC",
    "PREFLIGHT_DISARM_S",
    "AttitudeLoopFactory",
    "CommandResult",
    "LandedState",
    "TickRecord",
    "Vehicle",
    "VehicleEvent",
    "builtin_pid_loop",
]


class Vehicle:
    """One simulated quadrotor with its onboard autopilot functions."""

    def __init__(
        self,
        config: VehicleConfig,
        home: tuple[float, float, float],
        seed: int = 0,
        outer_rate_hz: float = 50.0,
        attitude_loops: Mapping[AttitudeControllerKind, AttitudeLoopFactory] | None = None,
    ) -> None:
        """attitude_loops: the inner loops MC_ATT_CTRL may select (`sitl_quad.attitude_loops.attitude_loops()`
        gives all); without it the vehicle flies only its built-in PID."""
        self.config = config
        self.home = home
        self.frame = LocalFrame(*home)
        self.seed = seed
        self.loop = FlightLoop(config, seed, outer_rate_hz, attitude_loops)
        self.measurement_delay = MeasurementDelay.for_config(config.sensor_noise, self.loop.outer_dt)
        self.navigator = Navigator(self.frame, config.navigator)
        self.mission: list[MissionItem] = []
        self.arming = ArmingState()
        self.mode = FlightMode.AUTO_LOITER
        self.mode_after_disarm = FlightMode.AUTO_LOITER  # the user's last mode that allows arming
        self.offboard = OffboardStream()
        # The physics step a setpoint read now belongs to: a paced server that fell behind the wall clock names a
        # later one than the current step (sitl_quad.pacing); None: the current step (lockstep, tests)
        self.arrival_step: Callable[[], int] | None = None
        self.offboard_tracker = OffboardTracker()
        self.geofence = GeofenceGuard()
        self.fence_items: list[MissionItem] = []  # the MISSION_TYPE_FENCE list, as uploaded
        self.rally_points: list[MissionItem] = []  # the MISSION_TYPE_RALLY list, as uploaded
        # DO_REPOSITION received while taking off: flown once the climb is done, as PX4 does
        self._reposition_after_takeoff: tuple[float, float, float, float] | None = None
        self.events: list[VehicleEvent] = []
        self.estimate = self.sim.measure()
        self.setpoint = self._hold_here()
        self.target = motors_off_target()
        self.source = "off"
        self.saturated_ticks = 0
        self.battery = Battery(config.battery)
        self.battery_guard = BatteryGuard()
        self.failures = Failures()  # injected by MAV_CMD_INJECT_FAILURE (sitl_quad.failure_injection)
        self._failures_reported = Failures()  # the ones the failsafes have already acted on this flight
        self._last_fix: tuple[float, float] | None = None  # GPS off: where the last fix put the vehicle (north, east)

    # ----- the parts, by the names the vehicle's users know them
    @property
    def sim(self) -> Simulator:
        return self.loop.sim

    @property
    def mixer(self) -> Mixer:
        return self.loop.mixer

    @property
    def attitude(self) -> AttitudeController:
        return self.loop.attitude

    @attitude.setter
    def attitude(self, controller: AttitudeController) -> None:
        self.loop.attitude = controller

    @property
    def position(self) -> PidPositionController:
        return self.loop.position

    @property
    def outer_dt(self) -> float:
        return self.loop.outer_dt

    @property
    def armed(self) -> bool:
        return self.arming.armed

    @property
    def landed_state(self) -> LandedState:
        return self.arming.landed_state

    @property
    def in_air(self) -> bool:
        return self.arming.in_air

    @property
    def wall_clock(self) -> Callable[[], float] | None:
        """See ArmingState.wall_clock (the server sets time.monotonic)."""
        return self.arming.wall_clock

    @wall_clock.setter
    def wall_clock(self, clock: Callable[[], float] | None) -> None:
        self.arming.wall_clock = clock

    def apply_config(self, changed: str) -> None:
        """Rebuild what depends on a config section after a parameter change."""
        self.loop.apply_config(changed)
        if changed == "sensor_noise":
            self.measurement_delay = MeasurementDelay.for_config(self.config.sensor_noise, self.outer_dt)
        if changed == "navigator":
            self.navigator.config = self.config.navigator
        if changed == "battery":  # the same pack, its charge kept, seen with the new parameters
            self.battery.config = self.config.battery

    # ----- state readers
    @property
    def t(self) -> float:
        return self.sim.t

    @property
    def clock(self) -> float:
        """The flight's own clock for the navigator and landing: seconds since the last takeoff preparation.

        Relative to the flight and computed from integer steps, so a lockstep flight rounds identically
        whatever the absolute time it started at.
        """
        return self.sim.disturbance_time

    @property
    def time_boot_ms(self) -> int:
        return round(self.sim.t * 1000)

    @property
    def truth(self) -> VehicleState:
        return self.sim.state

    @property
    def offboard_age_s(self) -> float:
        """Simulated seconds since the last offboard setpoint (exact: counted in integer physics steps)."""
        return self.offboard.age_s(self.sim.step_index, self.sim.dt)

    def offboard_fresh(self) -> bool:
        return self.offboard.fresh(self.sim.step_index, self.sim.dt, self.config.failsafe)

    def _emit(self, kind: str, text: str = "", severity: int = 6, seq: int = -1) -> None:
        self.events.append(VehicleEvent(kind=kind, text=text, severity=severity, seq=seq))

    def _hold_here(self) -> TrajectorySetpoint:
        _, _, yaw = euler_from_quat(self.estimate.quaternion)
        return TrajectorySetpoint(position=self.estimate.position.copy(), yaw=yaw)

    # ----- commands (each returns a CommandResult)
    def arm(self) -> CommandResult:
        if self.armed:
            self._emit("text", "Arming denied: already armed", 4)
            return CommandResult.TEMPORARILY_REJECTED
        if not self.sim.on_ground:
            self._emit("text", "Arming denied: not on the ground", 4)
            return CommandResult.DENIED
        if self.mode in ARMING_PREVENTED_MODES:
            self._emit("text", f"Arming denied: not possible in {self.mode.label}", 4)
            return CommandResult.DENIED
        if self._geofence_enforced() and self.geofence.violation(*self._north_east()) is not None:
            self._emit("text", "Arming denied: vehicle outside geofence", 4)
            return CommandResult.DENIED
        if self.failures.gps_off:
            self._emit("text", "Arming denied: no GPS fix", 4)
            return CommandResult.DENIED
        minimum = self._arming_battery_minimum()
        if self.battery.reported_charge < minimum:
            charge = self.battery.reported_charge
            self._emit("text", f"Arming denied: battery {charge:.0%}, below {minimum:.0%}", 4)
            return CommandResult.DENIED
        self.arming.arm(self.t)
        self.battery_guard.reset()
        self._failures_reported = Failures()
        self.loop.reset_controllers()
        self._emit("armed", "Armed")
        self._enter(self.mode)
        return CommandResult.ACCEPTED

    def disarm(self, force: bool = False) -> CommandResult:
        if not self.armed:
            return CommandResult.ACCEPTED
        if self.in_air and not self.sim.on_ground and not force:
            self._emit("text", "Disarming denied: in the air", 4)
            return CommandResult.DENIED
        self._disarm("Disarmed")
        return CommandResult.ACCEPTED

    def _arming_battery_minimum(self) -> float:
        """PX4's battery arming check: COM_ARM_BAT_MIN, or BAT_CRIT_THR while that is negative."""
        minimum = self.config.failsafe.arm_battery_min
        return minimum if minimum >= 0 else self.config.battery.critical_threshold

    def replace_battery(self, state_of_charge: float) -> CommandResult:
        """MAV_CMD_BATTERY_RESET: a fresh pack at state_of_charge (0..1), as a depot crew swaps it; only on the
        ground and disarmed."""
        if self.in_air or not self.sim.on_ground:
            self._emit("text", "Battery swap denied: flying", 4)
            return CommandResult.TEMPORARILY_REJECTED
        if self.armed:
            self._emit("text", "Battery swap denied: armed", 4)
            return CommandResult.DENIED
        self.battery.reset(state_of_charge)
        self.battery_guard.reset()
        self._emit("text", f"Battery replaced: {state_of_charge:.0%}", 6)
        return CommandResult.ACCEPTED

    def _disarm(self, reason: str) -> None:
        self.arming.disarm()
        self.sim.set_rotor_commands(np.zeros(4))
        self._emit("armed", reason)
        if self.mode != self.mode_after_disarm:
            self._enter(self.mode_after_disarm)

    def _choose(self, mode: FlightMode, first_seq: int | None = None, altitude: float | None = None) -> None:
        """Enter a mode a command asked for (a failsafe's mode is entered, never chosen)."""
        if kept_after_disarm(mode):
            self.mode_after_disarm = mode
        self._enter(mode, first_seq, altitude)

    def set_mode(self, mode: FlightMode) -> CommandResult:
        if self.failures.gps_off and mode in POSITION_MODES:
            self._emit("text", f"{mode.label} denied: no position estimate (GPS)", 4)
            return CommandResult.DENIED
        if mode == FlightMode.OFFBOARD and not self.offboard_fresh():
            self._emit("text", "Offboard denied: no setpoint stream", 4)
            return CommandResult.TEMPORARILY_REJECTED
        if mode == FlightMode.AUTO_MISSION and not self.mission:
            self._emit("text", "Mission denied: no mission", 4)
            return CommandResult.DENIED
        if mode == FlightMode.AUTO_MISSION and not self._mission_inside_fence():
            return CommandResult.DENIED
        if mode == FlightMode.ORBIT:  # an orbit around here with the defaults, as PX4 enters it by mode
            return self.orbit(math.nan, math.nan, math.nan, math.nan, math.nan, math.nan)
        self._choose(mode)
        return CommandResult.ACCEPTED

    def takeoff(self, altitude: float | None = None) -> CommandResult:
        if not self.armed:
            self._emit("text", "Takeoff denied: disarmed", 4)
            return CommandResult.DENIED
        self._choose(FlightMode.AUTO_TAKEOFF, altitude=altitude)
        return CommandResult.ACCEPTED

    def start_mission(self, first_seq: int | None = None) -> CommandResult:
        if not self.mission:
            self._emit("text", "Mission start denied: no mission", 4)
            return CommandResult.DENIED
        if first_seq is not None and not 0 <= first_seq < len(self.mission):
            return CommandResult.DENIED
        if not self._mission_inside_fence():
            return CommandResult.DENIED
        self._choose(FlightMode.AUTO_MISSION, first_seq=first_seq)
        return CommandResult.ACCEPTED

    def set_mission(self, items: list[MissionItem]) -> None:
        self.mission = list(items)
        self.navigator.set_mission(self.mission)
        if self.armed and self.mode == FlightMode.AUTO_MISSION:
            self.navigator.start_mission(self.clock, self.estimate, 0)
        self._emit("mission_current", seq=self.navigator.current_seq)

    def change_speed(self, speed_m_s: float) -> CommandResult:
        """DO_CHANGE_SPEED as a command: the cruise speed of the legs planned from now on."""
        if not (math.isfinite(speed_m_s) and 0 < speed_m_s <= self.config.position_pid.mpc_xy_vel_max):
            return CommandResult.DENIED
        self.config.navigator = dataclasses.replace(self.config.navigator, cruise_speed=speed_m_s)
        self.navigator.config = self.config.navigator
        return CommandResult.ACCEPTED

    def reposition(self, lat: float, lon: float, alt_amsl: float, yaw: float) -> CommandResult:
        """DO_REPOSITION (QGC's "go to location", MAVSDK's goto_location): hold at a place, as PX4 does.

        NaN keeps the current value of a coordinate; yaw NaN keeps the heading toward the travel. During a
        takeoff (spool-up included) the place is flown to once the climb is done.

        Armed on the ground, the vehicle takes off toward the place, as PX4 does: its commander switches to
        AUTO_LOITER whatever the landed state, and its position controller takes off toward a loiter setpoint
        above a landed vehicle. MAVSDK's goto_location first switches to hold (Action::goto_location sets
        FlightMode::Hold, then sends DO_REPOSITION): one second after takeoff() that hold lands during the
        motors' spool-up, or on the first ticks of the climb while the vehicle still touches the ground, and
        cancels the takeoff, so the reposition finds the vehicle armed on the ground."""
        # a takeoff, or a climb _take_off_toward started in AUTO_LOITER
        taking_off = self.mode in (FlightMode.AUTO_TAKEOFF, FlightMode.AUTO_LOITER) and (
            self.arming.pending_climb is not None or self.navigator.activity == "takeoff"
        )
        # on the ground and not flown yet: the landed state says TAKEOFF from the climb's first tick, before
        # the vehicle leaves the ground, and a hold then idles the rotors there
        grounded = self.sim.on_ground and not self.arming.was_airborne
        if not self.armed:
            self._emit("text", "Reposition denied: disarmed", 4)
            return CommandResult.DENIED
        place = reposition_target(self.frame, self.home[2], self.estimate, lat, lon, alt_amsl)
        if place is None:
            return CommandResult.DENIED
        if grounded and not taking_off:
            self._take_off_toward(place)
        if taking_off or grounded:
            self._reposition_after_takeoff = (lat, lon, alt_amsl, yaw)
            return CommandResult.ACCEPTED
        self._choose(FlightMode.AUTO_LOITER)
        self.navigator.hold(self.clock, self.estimate, position=place, yaw=yaw if math.isfinite(yaw) else None)
        return CommandResult.ACCEPTED

    def orbit(
        self, radius: float, speed: float, yaw_behaviour: float, lat: float, lon: float, alt_amsl: float
    ) -> CommandResult:
        """DO_ORBIT (MAVSDK's do_orbit, QGC's orbit): circle a centre, as PX4's orbit mode (POSCTL.ORBIT).

        radius: m, its sign the direction (positive clockwise); speed: tangential m/s; yaw_behaviour:
        ORBIT_YAW_BEHAVIOUR; lat/lon: the centre; alt_amsl: the altitude. NaN: the orbit under way's value, else a
        default (the centre and altitude: the vehicle's own)."""
        if not self.armed or not self.in_air:
            self._emit("text", "Orbit denied: not flying", 4)
            return CommandResult.DENIED
        here = tuple(float(c) for c in self.estimate.position)
        center = None
        if math.isfinite(lat) and math.isfinite(lon):
            place = reposition_target(self.frame, self.home[2], self.estimate, lat, lon, math.nan)
            if place is None:
                return CommandResult.DENIED
            center = place[:2]
        down = -(alt_amsl - self.home[2]) if math.isfinite(alt_amsl) else None
        if down is not None and down > 0:
            return CommandResult.DENIED  # below home
        current = self.navigator.orbit if self.mode == FlightMode.ORBIT else None
        limits = self.config
        try:
            orbit = orbit_from_command(
                current,
                here,
                radius,
                speed,
                yaw_behaviour,
                center,
                down,
                limits.navigator.max_acceleration,
                limits.position_pid.mpc_xy_vel_max,
            )
        except ValueError as exc:
            self._emit("text", f"Orbit denied: {exc}", 4)
            return CommandResult.DENIED
        self._choose(FlightMode.ORBIT)
        self.navigator.start_orbit(self.clock, self.estimate, orbit)
        return CommandResult.ACCEPTED

    def set_current_item(self, seq: int) -> bool:
        if not 0 <= seq < len(self.mission):
            return False
        if self.armed and self.mode == FlightMode.AUTO_MISSION:
            self.navigator.start_mission(self.clock, self.estimate, seq)
        else:
            self.navigator.set_current(self.clock, self.estimate, seq)
        self._emit("mission_current", seq=seq)
        return True

    def _arrival_step(self) -> int:
        return self.sim.step_index if self.arrival_step is None else max(self.sim.step_index, self.arrival_step())

    def set_offboard_target(self, target: AttitudeTarget, answered_ms: int) -> None:
        self.offboard.receive(target, answered_ms, self._arrival_step())

    def set_offboard_position_target(self, target: PositionTarget) -> None:
        """SET_POSITION_TARGET_*, already in the local NED frame (sitl_quad.offboard_setpoints)."""
        self.offboard.receive_position(target, self._arrival_step())

    def set_offboard_rates_target(self, target: RatesTarget) -> None:
        """SET_ATTITUDE_TARGET with body rates and thrust, the attitude ignored."""
        self.offboard.receive_rates(target, self._arrival_step())

    # ----- injected failures and the data link (sitl_quad.failure_injection)
    def inject_failure(self, unit: float, kind: float, instance: float) -> CommandResult:
        """MAV_CMD_INJECT_FAILURE, refused unless SYS_FAILURE_EN: GPS, motor, battery or MAVLink signal off / ok."""
        enabled = bool(self.config.failsafe.failure_injection_enabled)
        answer = inject(self.failures, enabled, unit, kind, instance)
        if answer.text:
            self._emit("text", answer.text, 4 if answer.result == CommandResult.ACCEPTED else 3)
        if self.failures.gps_off != answer.failures.gps_off:
            self._last_fix = self._north_east() if answer.failures.gps_off else None
        self.failures = answer.failures
        self.sim.set_rotor_health(rotor_health(self.failures))
        self.battery.reads_empty = self.failures.battery_empty
        if not self.failures.gps_off:  # a position is known again: a later loss acts again
            self._failures_reported = dataclasses.replace(self._failures_reported, gps_off=False)
        return answer.result

    def data_link_lost(self, silent_s: float) -> None:
        """No ground station heard for silent_s >= COM_DL_LOSS_T (the server measures it): NAV_DLL_ACT, once per
        loss (the server calls again only after a ground station was heard), while flying."""
        next_mode = data_link_loss_mode(DataLinkLossAction(self.config.failsafe.data_link_loss_action))
        if next_mode is None or not (self.armed and self.in_air):
            return
        if self.failures.gps_off and next_mode in POSITION_MODES:
            next_mode = FlightMode.AUTO_LAND
        self._emit("text", f"Failsafe: no ground station for {silent_s:.0f} s, {next_mode.label}", 2)
        if next_mode != self.mode and self.mode != FlightMode.AUTO_LAND:
            self._enter(next_mode)

    def _check_failures(self) -> None:
        """What PX4's failsafes and failure detector make of an injected failure, once per flight: without GPS no
        position estimate, so a mode that needs one descends (Land); a blocked motor is reported (PX4's
        COM_ACT_FAIL_ACT defaults to warning only: the vehicle flies on as the physics lets it)."""
        if not (self.armed and self.in_air):
            return
        failures, reported = self.failures, self._failures_reported
        if failures.gps_off and not reported.gps_off:
            descend = self.mode in POSITION_MODES
            then = f": {FlightMode.AUTO_LAND.label}" if descend else ""
            self._emit("text", f"Failsafe: GPS lost, no position{then}", 2)
            self.loop.position.reset_horizontal()
            if descend:
                self._enter(FlightMode.AUTO_LAND)
        for motor in sorted(failures.motors_off - reported.motors_off):
            self._emit("text", f"Failsafe: motor {motor} failure", 2)
        self._failures_reported = dataclasses.replace(
            reported, gps_off=failures.gps_off or reported.gps_off, motors_off=failures.motors_off | reported.motors_off
        )

    # ----- geofence and rally points (the other two lists of the mission protocol)
    def set_fence(self, items: list[MissionItem]) -> None:
        """Store a MISSION_TYPE_FENCE list; raises uavcore.geofence.FenceError (nothing changed) if it does not
        describe zones. The list is kept as sent (a download hands it back whole) and its zones are loaded as
        PX4 loads them: one barring home, or the flying vehicle, is discarded with PX4's critical text."""
        fence = Geofence.from_items(items)
        self.fence_items = list(items)
        flying = self.armed and self.in_air and self.config.failsafe.geofence_action != GeofenceAction.NONE
        for text in self.geofence.set_fence(fence, self.frame, self._north_east() if flying else None):
            self._emit("text", text, SEVERITY_CRITICAL)

    def set_rally_points(self, items: list[MissionItem]) -> None:
        """Store a MISSION_TYPE_RALLY list: a return (RTL) then goes to the closest of home and these."""
        self.rally_points = list(items)
        self.navigator.set_rally_points(self.rally_points)

    def _north_east(self) -> tuple[float, float]:
        return float(self.estimate.position[0]), float(self.estimate.position[1])

    def _geofence_enforced(self) -> bool:
        failsafe = self.config.failsafe
        fenced = self.geofence.present or home_limits_on(failsafe)
        return fenced and failsafe.geofence_action != GeofenceAction.NONE

    def _mission_inside_fence(self) -> bool:
        """PX4's mission feasibility check: every place the mission names is where the vehicle may be."""
        if not self._geofence_enforced():
            return True
        for item in self.mission:
            if item.has_position:
                north, east, _ = self.frame.to_ned(item.lat, item.lon, self.frame.alt0)
                if self.geofence.violation(float(north), float(east)) is not None:
                    self._emit("text", f"Mission denied: item {item.seq} outside geofence", 4)
                    return False
        return True

    # ----- mode changes
    def _enter(self, mode: FlightMode, first_seq: int | None = None, altitude: float | None = None) -> None:
        """Switch mode and tell the navigator what to fly (only when armed; a disarmed mode waits)."""
        changed = mode != self.mode
        self.mode = mode
        self._reposition_after_takeoff = None
        if changed:
            self._emit("mode", mode.label)
        if not self.armed:
            return
        if mode == FlightMode.OFFBOARD:
            self._enter_offboard()
            return
        self.arming.pending_climb = None
        if self.sim.on_ground and not self.arming.was_airborne and mode in CLIMB_MODES:
            self._prepare_takeoff(mode, first_seq, altitude)
            return
        self._start_activity(mode, first_seq, altitude)

    def _prepare_takeoff(self, mode: FlightMode, first_seq: int | None, altitude: float | None) -> None:
        """A flight starts here: disturbances from the seed, fresh loops and navigator, motors spooling up.

        Everything a flight depends on restarts at this tick, and the climb begins a fixed SPOOLUP_S later
        with the rotors settled at idle, so a lockstep flight is the same whenever the command arrived
        (see Simulator.restart_disturbances). PX4 likewise waits COM_SPOOLUP_TIME before taking off.
        """
        self.sim.restart_disturbances()
        self.loop.reset_controllers()
        self.estimate = self.sim.measure()
        first_seq = resume_seq(self.navigator, first_seq)
        self.navigator = flight_navigator(
            self.frame, self.config.navigator, self.mission, self.rally_points, self.clock, self.estimate
        )
        self.arming.schedule_climb(PendingClimb(self.clock + SPOOLUP_S, mode, first_seq, altitude))

    def _enter_offboard(self) -> None:
        """OFFBOARD takes the outer loop. With the offboard controller's attitude targets during a flight the
        navigator keeps flying its reference (the controller follows it); position targets or body rates, or a
        start from the ground, leave the navigator nothing to fly. From the ground the motors first spool up, and
        the vehicle leaves the ground when the setpoints ask for it (`_offboard_lifts_off`)."""
        self.offboard_tracker.reset()
        from_ground = (
            self.sim.on_ground
            and not self.arming.was_airborne
            and self.arming.pending_climb is None
            and self.navigator.activity not in CLIMBING_ACTIVITIES
        )
        if from_ground:
            self._prepare_takeoff(FlightMode.OFFBOARD, None, None)
        if from_ground or self.offboard.kind != SetpointKind.ATTITUDE:
            self.navigator.release(self.clock)

    def _offboard_lifts_off(self, est: VehicleState) -> bool:
        """Whether OFFBOARD setpoints fly an armed vehicle still on the ground: once the motors have spooled up,
        attitude and rate setpoints at once (their thrust decides), position targets when they ask to climb."""
        if self.mode != FlightMode.OFFBOARD or not self.arming.spooled_up:
            return False
        if self.offboard.kind == SetpointKind.TRAJECTORY:
            return wants_takeoff(self.offboard.position_target, est)
        return True

    def _start_activity(self, mode: FlightMode, first_seq: int | None = None, altitude: float | None = None) -> None:
        start_activity(self.navigator, mode, self.clock, self.estimate, first_seq, altitude, self.config.navigator)

    def _start_pending_takeoff(self) -> None:
        """Called each tick: begin the climb once the motors have spooled up (if still armed and wanted)."""
        climb = self.arming.due_climb(self.clock)
        if climb is not None and self.armed:
            self._start_activity(climb.mode, climb.first_seq, climb.altitude)

    def _take_off_toward(self, place: tuple[float, float, float]) -> None:
        """In AUTO_LOITER, spool up and climb to the place's height (MIS_TAKEOFF_ALT if it is not above home);
        the reposition that asked is kept for once the climb is done (_reposition_once_climbed)."""
        self._choose(FlightMode.AUTO_LOITER)
        height = -place[2]
        self._prepare_takeoff(FlightMode.AUTO_TAKEOFF, None, height if height > AIRBORNE_ALTITUDE_M else None)

    def _reposition_once_climbed(self) -> None:
        """Fly to a place asked for during the takeoff, once the climb is done."""
        request = self._reposition_after_takeoff
        climbing = self.arming.pending_climb is not None or self.navigator.activity == "takeoff"
        if request is not None and not climbing:
            self._reposition_after_takeoff = None
            self.reposition(*request)

    def _check_geofence(self) -> None:
        """GF_ACTION when the flying vehicle leaves where its geofence lets it be (sitl_quad.failsafe)."""
        if not (self.armed and self.in_air and self._geofence_enforced()):
            return
        height = -float(self.estimate.position[2])
        breach = self.geofence.new_breach(*self._north_east(), height, self.config.failsafe)
        if breach is None:
            return
        action = GeofenceAction(self.config.failsafe.geofence_action)
        next_mode = geofence_action_mode(action)
        then = next_mode.label if next_mode is not None else "warning only"
        if isinstance(breach, HomeDistanceLimit):
            self._emit("text", breach.px4_text, SEVERITY_CRITICAL)
        self._emit("text", f"Geofence breached ({breach.kind}): {then}", SEVERITY_CRITICAL)
        # a hold is taken here even in AUTO_LOITER: flying to a place beyond the fence (a reposition) is a loiter
        # too, and PX4's navigator then sets its loiter point where the breach is (Navigator::geofence_breach_check)
        if next_mode is not None and (next_mode != self.mode or next_mode == FlightMode.AUTO_LOITER):
            self._enter(next_mode)

    def _check_battery(self) -> None:
        """Each battery warning level once per flight, and COM_LOW_BAT_ACT's mode at critical and emergency
        (sitl_quad.failsafe). A landing is never turned into a return."""
        if not self.armed:
            return
        level = self.battery_guard.new_level(self.battery.warning)
        if level is None:
            return
        reaction = battery_failsafe(level, LowBatteryAction(self.config.failsafe.low_battery_action))
        if reaction is None:
            return
        self._emit("text", reaction.text, reaction.severity)
        mode = reaction.mode
        if mode is not None and self.in_air and mode != self.mode and self.mode != FlightMode.AUTO_LAND:
            self._enter(mode)

    def _draw_battery(self) -> None:
        """The tick's electrical load on the pack, from the rotor speeds now (sitl_quad.battery)."""
        shaft_w = rotor_mechanical_power(self.sim.rotor_speeds, self.config.airframe.kf)
        self.battery.draw(electrical_power(shaft_w, self.config.battery, self.armed), self.outer_dt)

    def _check_offboard_loss(self) -> None:
        """OFFB_LOSS_ACT once the offboard stream is older than OFFB_LOSS_T (sitl_quad.failsafe)."""
        if self.mode != FlightMode.OFFBOARD or self.offboard_fresh():
            return
        next_mode = offboard_loss_mode(self.config.failsafe)
        self._emit("offboard_lost")  # the server reports the stream's ages (wall clock and simulated)
        self._emit("text", f"Failsafe: offboard setpoints lost, {next_mode.label}", 3)
        self._enter(next_mode)

    # ----- the loop
    def tick(self) -> TickRecord:
        """Advance one outer-loop period of simulated time.

        The estimate and the reference are taken at the start of the tick and are what the tick's state
        messages carry, so the offboard controller sees them consistent (same instant), one tick old.
        """
        est = self.measurement_delay.push(self.sim.measure())
        if self._last_fix is not None:
            est = estimate_without_gps(est, self._last_fix)
        self.estimate = est
        self._start_pending_takeoff()
        kind = self.offboard.kind if self.mode == FlightMode.OFFBOARD and self.offboard_fresh() else None
        if self.armed and kind in (SetpointKind.TRAJECTORY, SetpointKind.RATES):
            if self.navigator.activity != "idle":  # the stream switched kind: it sets the reference now
                self.navigator.release(self.clock)
            self.setpoint = (
                self.offboard_tracker.trajectory_setpoint(self.offboard.position_target, est, self.outer_dt)
                if kind == SetpointKind.TRAJECTORY
                else self._hold_here()
            )
        elif self.armed:
            self.setpoint = self.navigator.update(self.clock, est)
            self._drain_navigator()
            self._reposition_once_climbed()
        else:
            self.setpoint = self._hold_here()
        if self._last_fix is not None:  # no GPS: level, height and yaw only (PX4's Descend)
            self.setpoint = without_horizontal_control(self.setpoint, est)
        self._check_offboard_loss()
        self._check_failures()
        self._check_geofence()
        self._check_battery()
        offboard = self._offboard_attitude(est) if self.mode == FlightMode.OFFBOARD else None
        idling = (
            self.armed and self.arming.idling(self.sim.on_ground, self.navigator) and not self._offboard_lifts_off(est)
        )
        target, source = self.loop.outer_target(est, self.setpoint, offboard, armed=self.armed, idling=idling)
        self.target, self.source = target, source
        saturated = self.loop.fly(target, source)
        self.saturated_ticks += int(saturated)
        self._draw_battery()
        self._update_landed_state()
        return TickRecord(
            t=self.t,
            truth=self.sim.state,
            estimate=est,
            setpoint=self.setpoint,
            target=target,
            source=source,
            disturbance=dict(self.sim.last_disturbance),
        )

    def _offboard_attitude(self, est: VehicleState) -> AttitudeTarget | None:
        """The attitude target OFFBOARD sends straight to the attitude loop: the offboard controller's, or one
        integrated from body rates; None for position targets (the position loop flies those)."""
        if self.offboard.kind == SetpointKind.RATES:
            return self.offboard_tracker.rates_target(self.offboard.rates_target, est, self.outer_dt)
        if self.offboard.kind == SetpointKind.TRAJECTORY:
            return None
        return self.offboard.target

    def _drain_navigator(self) -> None:
        for event in self.navigator.pop_events():
            if event.kind == "current":
                self._emit("mission_current", seq=event.seq)
            elif event.kind == "reached":
                self._emit("item_reached", seq=event.seq)
            elif event.kind == "complete":
                self._emit("mission_complete", "Mission finished", seq=event.seq)
            elif event.kind == "payload":
                self._emit("payload_item", seq=event.seq)

    def _update_landed_state(self) -> None:
        truth = self.sim.state
        touching = touching_ground(self.sim.on_ground, truth)
        verdict = self.arming.update(touching, -truth.position[2], self.clock, self.t, self.navigator)
        if verdict == AutoDisarm.LANDED:
            self._emit("text", "Landing detected", 6)
            self._disarm("Disarmed after landing")
        elif verdict == AutoDisarm.NO_TAKEOFF:
            self._disarm("Disarmed: no takeoff")
