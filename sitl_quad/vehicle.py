"""The autopilot without its radio: modes, arming, failsafes and the loop that ties physics to control.

`Vehicle.tick()` advances one outer-loop period (50 Hz by default): the navigator's reference, the outer
loop's attitude target (built-in PID cascade, or the offboard controller's SET_ATTITUDE_TARGET while in
OFFBOARD and fresh), then the attitude loop at 250 Hz, each attitude step driving 1 kHz RK4 physics steps.
Nothing here knows MAVLink: commands return a `CommandResult` whose numbers equal MAV_RESULT's, and what
the outside world should hear about is queued as `VehicleEvent`s.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from enum import IntEnum

import numpy as np

from sitl_quad.attitude_pid import PidAttitudeController
from sitl_quad.config import AttitudeControllerKind, FailsafeAction, VehicleConfig
from sitl_quad.navigator import Navigator
from sitl_quad.rotors import Mixer
from sitl_quad.simulator import Simulator
from uavcore.airframe import ModelParameterError
from uavcore.control import AttitudeController
from uavcore.geodesy import LocalFrame
from uavcore.mission import MissionItem
from uavcore.modes import FlightMode
from uavcore.rotation import euler_from_quat
from uavcore.state import AttitudeTarget, TrajectorySetpoint, VehicleState

ATTITUDE_RATE_HZ = 250
PHYSICS_RATE_HZ = 1000
IDLE_THROTTLE = 0.05  # armed on the ground: rotors spin at idle, as PX4 does
TOUCHDOWN_CONFIRM_S = 1.0  # on the ground this long while landing -> landed, disarm
SPOOLUP_S = 1.0  # from a takeoff or mission command on the ground to the climb (PX4's COM_SPOOLUP_TIME)
PREFLIGHT_DISARM_S = 10.0  # armed on the ground without taking off this long -> disarm (COM_DISARM_PRFLT)
FORCE_DISARM_MAGIC = 21196  # COMPONENT_ARM_DISARM param2 that disarms even in the air

# Builds an attitude loop for a configuration at a loop rate (Hz); see sitl_quad.attitude_loops.
AttitudeLoopFactory = Callable[[VehicleConfig, float], AttitudeController]


def builtin_pid_loop(config: VehicleConfig, rate_hz: float) -> AttitudeController:
    return PidAttitudeController(config.attitude_pid)


class CommandResult(IntEnum):
    """Same numbers as MAV_RESULT."""

    ACCEPTED = 0
    TEMPORARILY_REJECTED = 1
    DENIED = 2
    UNSUPPORTED = 3
    FAILED = 4


class LandedState(IntEnum):
    """Same numbers as MAV_LANDED_STATE."""

    UNDEFINED = 0
    ON_GROUND = 1
    IN_AIR = 2
    TAKEOFF = 3
    LANDING = 4


@dataclass
class VehicleEvent:
    kind: str  # "text" | "mission_current" | "item_reached" | "mission_complete" | "mode" | "armed"
    text: str = ""
    severity: int = 6  # MAV_SEVERITY for "text": 6 info, 4 warning, 3 error
    seq: int = -1


@dataclass
class OffboardStream:
    """The latest SET_ATTITUDE_TARGET from the offboard controller."""

    target: AttitudeTarget | None = None
    received_step: int = -(10**12)  # the physics step it arrived at
    answered_ms: int = -1  # the state time_boot_ms it answers (lockstep)
    count: int = 0


@dataclass
class TickRecord:
    """What one outer tick did, for logs and benchmarks."""

    t: float
    truth: VehicleState
    estimate: VehicleState
    setpoint: TrajectorySetpoint
    target: AttitudeTarget
    source: str  # "offboard" | "builtin" | "idle" | "off"
    disturbance: dict = field(default_factory=dict)


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
        self.attitude_loops = dict(attitude_loops or {AttitudeControllerKind.PID: builtin_pid_loop})
        self.home = home
        self.frame = LocalFrame(*home)
        self.seed = seed
        self.outer_dt = 1.0 / outer_rate_hz
        self.attitude_steps = max(1, round(ATTITUDE_RATE_HZ / outer_rate_hz))
        self.attitude_dt = self.outer_dt / self.attitude_steps
        self.physics_steps = max(1, round(self.attitude_dt * PHYSICS_RATE_HZ))
        self.sim = self._make_simulator()
        self.mixer = Mixer(config.airframe)
        self.attitude = self._make_attitude_controller()
        self.position = self._make_position_controller()
        self.navigator = Navigator(self.frame, config.navigator)
        self.mission: list[MissionItem] = []
        self.armed = False
        self.mode = FlightMode.AUTO_LOITER
        self.landed_state = LandedState.ON_GROUND
        self.offboard = OffboardStream()
        self.events: list[VehicleEvent] = []
        self.estimate = self.sim.measure()
        self.setpoint = self._hold_here()
        self.target = AttitudeTarget(quaternion=np.array([1.0, 0, 0, 0]), thrust=0.0)
        self.source = "off"
        self.saturated_ticks = 0
        self.flight_time_s = 0.0  # armed time, drains the battery model
        self._ground_since: float | None = None
        self._armed_at = 0.0
        self._armed_at_wall = 0.0
        # Wall clock for the pre-flight disarm timer (the server passes time.monotonic): a ground station's
        # command retries run on the wall clock, so at lockstep speeds 10 s of simulated time can pass between
        # its ARM and a MISSION_START that had to be resent. None: simulated time only (tests, benchmarks).
        self.wall_clock = None
        self._was_airborne = False
        self._pending_start: tuple | None = None  # (time, mode, first_seq, altitude) of a takeoff spooling up

    # ----- construction from config (also after parameter changes)
    def _make_simulator(self) -> Simulator:
        c = self.config
        return Simulator(
            airframe=c.airframe,
            wind=c.wind,
            disturbance=c.disturbance,
            sensor_noise=c.sensor_noise,
            seed=self.seed,
            dt=1.0 / PHYSICS_RATE_HZ,
        )

    def _make_attitude_controller(self) -> AttitudeController:
        kind = AttitudeControllerKind(self.config.control.attitude_controller)
        factory = self.attitude_loops.get(kind)
        if factory is None:
            raise ModelParameterError(
                f"MC_ATT_CTRL={int(kind)} ({kind.name}): this vehicle was built without that loop"
            )
        return factory(self.config, 1.0 / self.attitude_dt)

    def _make_position_controller(self):
        from sitl_quad.position_control import PidPositionController

        return PidPositionController(self.config.airframe, self.config.position_pid)

    def apply_config(self, changed: str) -> None:
        """Rebuild what depends on a config section after a parameter change."""
        if changed in ("wind", "disturbance", "sensor_noise", "airframe"):
            self.sim.reconfigure(
                airframe=self.config.airframe,
                wind=self.config.wind,
                disturbance=self.config.disturbance,
                sensor_noise=self.config.sensor_noise,
            )
        if changed == "airframe":
            self.mixer = Mixer(self.config.airframe)
        if changed in ("airframe", "attitude_pid", "control"):
            self.attitude = self._make_attitude_controller()
        if changed in ("airframe", "position_pid"):
            self.position = self._make_position_controller()
        if changed == "navigator":
            self.navigator.config = self.config.navigator

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
    def in_air(self) -> bool:
        return self.landed_state in (LandedState.IN_AIR, LandedState.TAKEOFF, LandedState.LANDING)

    @property
    def offboard_age_s(self) -> float:
        """Simulated seconds since the last offboard setpoint (exact: counted in integer physics steps)."""
        return (self.sim.step_index - self.offboard.received_step) * self.sim.dt

    def offboard_fresh(self) -> bool:
        return self.offboard_age_s <= self.config.failsafe.offboard_loss_timeout_s + 1e-9

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
        self.armed = True
        self._armed_at = self.t
        self._armed_at_wall = self.wall_clock() if self.wall_clock is not None else 0.0
        self._was_airborne = False
        self.attitude.reset()
        self.position.reset()
        self.landed_state = LandedState.ON_GROUND
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

    def _disarm(self, reason: str) -> None:
        self.armed = False
        self.landed_state = LandedState.ON_GROUND
        self.sim.set_rotor_commands(np.zeros(4))
        self._emit("armed", reason)

    def set_mode(self, mode: FlightMode) -> CommandResult:
        if mode == FlightMode.OFFBOARD and not self.offboard_fresh():
            self._emit("text", "Offboard denied: no attitude setpoint stream", 4)
            return CommandResult.TEMPORARILY_REJECTED
        if mode == FlightMode.AUTO_MISSION and not self.mission:
            self._emit("text", "Mission denied: no mission", 4)
            return CommandResult.DENIED
        self._enter(mode)
        return CommandResult.ACCEPTED

    def takeoff(self, altitude: float | None = None) -> CommandResult:
        if not self.armed:
            self._emit("text", "Takeoff denied: disarmed", 4)
            return CommandResult.DENIED
        self._enter(FlightMode.AUTO_TAKEOFF, altitude=altitude)
        return CommandResult.ACCEPTED

    def start_mission(self, first_seq: int | None = None) -> CommandResult:
        if not self.mission:
            self._emit("text", "Mission start denied: no mission", 4)
            return CommandResult.DENIED
        if first_seq is not None and not 0 <= first_seq < len(self.mission):
            return CommandResult.DENIED
        self._enter(FlightMode.AUTO_MISSION, first_seq=first_seq)
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

        NaN keeps the current value of a coordinate; yaw NaN keeps the heading toward the travel."""
        if not self.armed or not self.in_air:
            self._emit("text", "Reposition denied: not flying", 4)
            return CommandResult.DENIED
        here = self.estimate.position
        north, east, down = (float(c) for c in here)
        if math.isfinite(lat) and math.isfinite(lon):
            if not (-90 <= lat <= 90 and -180 <= lon <= 180):
                return CommandResult.DENIED
            north, east, _ = (float(c) for c in self.frame.to_ned(lat, lon, 0.0))
        if math.isfinite(alt_amsl):
            down = -(alt_amsl - self.home[2])
            if down > 0:
                return CommandResult.DENIED  # below home: into the water
        self._enter(FlightMode.AUTO_LOITER)
        self.navigator.hold(
            self.clock, self.estimate, position=(north, east, down), yaw=yaw if math.isfinite(yaw) else None
        )
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

    def set_offboard_target(self, target: AttitudeTarget, answered_ms: int) -> None:
        self.offboard.target = target
        self.offboard.received_step = self.sim.step_index
        self.offboard.answered_ms = answered_ms
        self.offboard.count += 1

    def _enter(self, mode: FlightMode, first_seq: int | None = None, altitude: float | None = None) -> None:
        """Switch mode and tell the navigator what to fly (only when armed; a disarmed mode waits)."""
        changed = mode != self.mode
        self.mode = mode
        if changed:
            self._emit("mode", mode.label)
        if not self.armed or mode == FlightMode.OFFBOARD:
            return  # OFFBOARD: the navigator keeps flying whatever it flies; only the outer loop changes hands
        self._pending_start = None
        if self.sim.on_ground and not self._was_airborne and mode in (FlightMode.AUTO_MISSION, FlightMode.AUTO_TAKEOFF):
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
        self.attitude.reset()
        self.position.reset()
        self.estimate = self.sim.measure()
        if first_seq is None and self.navigator.mission_state != "complete":
            first_seq = self.navigator.current_seq
        self.navigator = Navigator(self.frame, self.config.navigator)
        self.navigator.set_mission(self.mission)
        self.navigator.hold(self.clock, self.estimate)
        self._pending_start = (self.clock + SPOOLUP_S, mode, first_seq, altitude)

    def _start_activity(self, mode: FlightMode, first_seq: int | None = None, altitude: float | None = None) -> None:
        t, est = self.clock, self.estimate
        if mode == FlightMode.AUTO_MISSION:
            if self.navigator.mission_state == "complete" and first_seq is None:
                first_seq = 0  # re-arming after a finished mission flies it again, from the start
            self.navigator.start_mission(t, est, first_seq)
        elif mode == FlightMode.AUTO_TAKEOFF:
            self.navigator.start_takeoff(t, est, altitude or self.config.navigator.takeoff_altitude)
        elif mode == FlightMode.AUTO_RTL:
            self.navigator.start_rtl(t, est)
        elif mode == FlightMode.AUTO_LAND:
            self.navigator.start_land(t, est)
        elif mode in (FlightMode.AUTO_LOITER, FlightMode.POSCTL, FlightMode.AUTO_READY):
            self.navigator.hold(t, est)

    def _start_pending_takeoff(self) -> None:
        """Called each tick: begin the climb once the motors have spooled up (if still armed and wanted)."""
        if self._pending_start is None or self.clock + 1e-9 < self._pending_start[0]:
            return
        _, mode, first_seq, altitude = self._pending_start
        self._pending_start = None
        if self.armed:
            self._start_activity(mode, first_seq, altitude)

    # ----- the loop
    def tick(self) -> TickRecord:
        """Advance one outer-loop period of simulated time.

        The estimate and the reference are taken at the start of the tick and are what the tick's state
        messages carry, so the offboard controller sees them consistent (same instant), one tick old.
        """
        self.estimate = est = self.sim.measure()
        self._start_pending_takeoff()
        if self.armed:
            self.setpoint = self.navigator.update(self.clock, est)
            self._drain_navigator()
        else:
            self.setpoint = self._hold_here()
        self._check_offboard_loss()
        target, source = self._outer_loop(est)
        self.target, self.source = target, source
        saturated = False
        thrust_n = target.thrust * self.config.airframe.max_thrust_n
        if source == "off":  # rotors commanded to 0 all tick: the physics steps in one batch, same result
            self.sim.set_rotor_commands(np.zeros(4))
            self.sim.step(self.attitude_steps * self.physics_steps)
        elif isinstance(self.attitude, PidAttitudeController):
            # the steps of the loop below in one compiled call ("idle": the PID runs, its torque unused)
            saturated = self.sim.run_pid_attitude_steps(
                self.attitude,
                self.mixer,
                target,
                thrust_n,
                self.attitude_steps,
                self.physics_steps,
                self.attitude_dt,
                apply_torque=source != "idle",
            )
        else:
            for _ in range(self.attitude_steps):
                measured = self.sim.measure()
                torque = self.attitude.update(target, measured, self.attitude_dt)
                if source == "idle":
                    torque = np.zeros(3)
                self.sim.set_rotor_commands(self.mixer.rotor_commands(thrust_n, torque))
                saturated = saturated or self.mixer.saturated
                self.sim.step(self.physics_steps)
        self.saturated_ticks += int(saturated)
        if self.armed:
            self.flight_time_s += self.outer_dt
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

    def _outer_loop(self, est: VehicleState) -> tuple[AttitudeTarget, str]:
        if not self.armed:
            return AttitudeTarget(quaternion=np.array([1.0, 0, 0, 0]), thrust=0.0), "off"
        climbing = self.navigator.activity in ("takeoff", "mission", "rtl") and not self.navigator.is_landing
        if self.sim.on_ground and not self._was_airborne and not climbing:  # motors idle until a climb starts
            level = AttitudeTarget(quaternion=self._level_quaternion(est), thrust=IDLE_THROTTLE)
            return level, "idle"
        if self.mode == FlightMode.OFFBOARD and self.offboard.target is not None:
            return self.offboard.target, "offboard"
        return self.position.update(self.setpoint, est, self.outer_dt), "builtin"

    @staticmethod
    def _level_quaternion(est: VehicleState) -> np.ndarray:
        _, _, yaw = euler_from_quat(est.quaternion)
        return np.array([math.cos(yaw / 2), 0.0, 0.0, math.sin(yaw / 2)])

    def _check_offboard_loss(self) -> None:
        if self.mode != FlightMode.OFFBOARD or self.offboard_fresh():
            return
        action = self.config.failsafe.offboard_loss_action
        next_mode = {
            FailsafeAction.HOLD: FlightMode.AUTO_LOITER,
            FailsafeAction.LAND: FlightMode.AUTO_LAND,
            FailsafeAction.RETURN: FlightMode.AUTO_RTL,
        }[FailsafeAction(action)]
        self._emit("text", f"Failsafe: offboard setpoints lost, {next_mode.label}", 3)
        self._enter(next_mode)

    def _drain_navigator(self) -> None:
        for event in self.navigator.pop_events():
            if event.kind == "current":
                self._emit("mission_current", seq=event.seq)
            elif event.kind == "reached":
                self._emit("item_reached", seq=event.seq)
            elif event.kind == "complete":
                self._emit("mission_complete", "Mission finished", seq=event.seq)

    def _touching_ground(self) -> bool:
        """Land detector: in contact, or hovering within a few cm of the ground without vertical motion.

        Contact alone flickers when a controller presses with about the vehicle's weight (as an ESO that
        learned the ground reaction does), so a near-ground, near-still state also counts.
        """
        truth = self.sim.state
        return self.sim.on_ground or (-truth.position[2] < 0.05 and abs(truth.velocity[2]) < 0.3)

    def _preflight_timed_out(self) -> bool:
        """Armed on the ground without a takeoff for PREFLIGHT_DISARM_S, in simulated and in wall time."""
        if self.t - self._armed_at <= PREFLIGHT_DISARM_S:
            return False
        return self.wall_clock is None or self.wall_clock() - self._armed_at_wall > PREFLIGHT_DISARM_S

    def _update_landed_state(self) -> None:
        if not self.armed:
            self.landed_state = LandedState.ON_GROUND
            return
        on_ground = self._touching_ground()
        if not on_ground:
            altitude = -self.sim.state.position[2]
            self._was_airborne = self._was_airborne or altitude > 0.5
        if self.navigator.is_landing or (self._was_airborne and on_ground):
            self.landed_state = LandedState.LANDING
            if on_ground:
                self._ground_since = self.clock if self._ground_since is None else self._ground_since
                if self.clock - self._ground_since >= TOUCHDOWN_CONFIRM_S - 1e-9:
                    self._ground_since = None
                    self._emit("text", "Landing detected", 6)
                    self._disarm("Disarmed after landing")
            else:
                self._ground_since = None
        elif on_ground and not self._was_airborne:
            climbing = self.navigator.activity in ("takeoff", "mission", "rtl")
            # while the motors spool up the vehicle is still on the ground (an offboard controller resets then)
            self.landed_state = LandedState.TAKEOFF if climbing else LandedState.ON_GROUND
            spooling = self._pending_start is not None
            if not climbing and not spooling and self._preflight_timed_out():
                self._disarm("Disarmed: no takeoff")
        elif self.navigator.activity == "takeoff":
            self.landed_state = LandedState.TAKEOFF
        else:
            self.landed_state = LandedState.IN_AIR
