"""The tick's control path: the outer loop's attitude target, the 250 Hz attitude loop, the 1 kHz physics.

`FlightLoop` owns the simulated body (Simulator), the mixer and the two loops of the cascade: the built-in
PX4-style position loop and the attitude loop MC_ATT_CTRL selects among the injected factories. Each outer tick
(50 Hz by default) the vehicle asks it for the tick's attitude target (`outer_target`) and then to fly that target for
one outer period (`fly`): `attitude_steps` attitude updates, each holding its rotor commands for `physics_steps`
RK4 steps. An attitude loop that can fly those steps in one compiled call does: the PID
(Simulator.run_pid_attitude_steps) and any injected loop that brings its own compiled inner loop
(`CompiledAttitudeLoop`, e.g. sitl_quad.attitude_loops' ADRC); any other is stepped from Python. Modes, arming and
failsafes are the vehicle's business, not this module's.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from typing import Protocol, runtime_checkable

import numpy as np

from sitl_quad.attitude_pid import PidAttitudeController
from sitl_quad.config import AttitudeControllerKind, VehicleConfig
from sitl_quad.position_control import PidPositionController
from sitl_quad.rotors import Mixer
from sitl_quad.simulator import InnerLoop, Simulator
from uavcore.airframe import ModelParameterError
from uavcore.control import AttitudeController
from uavcore.rotation import euler_from_quat
from uavcore.state import AttitudeTarget, TrajectorySetpoint, VehicleState

ATTITUDE_RATE_HZ = 250
PHYSICS_RATE_HZ = 1000
IDLE_THROTTLE = 0.05  # armed on the ground: rotors spin at idle, as PX4 does

# Builds an attitude loop for a configuration at a loop rate (Hz); see sitl_quad.attitude_loops.
AttitudeLoopFactory = Callable[[VehicleConfig, float], AttitudeController]


@runtime_checkable
class CompiledAttitudeLoop(Protocol):
    """An attitude loop that flies one outer period in one compiled call: `inner_loop`, with the signature
    sitl_quad.inner_loop describes, run by Simulator.run_attitude_steps on `kernel_arguments(target)` (its law's
    arguments: its gains and state, the target), with the same results as its update() stepped from Python."""

    inner_loop: InnerLoop

    def kernel_arguments(self, target: AttitudeTarget) -> tuple:
        """The inner loop's `law` argument for this target."""
        ...


def builtin_pid_loop(config: VehicleConfig, rate_hz: float) -> AttitudeController:
    return PidAttitudeController(config.attitude_pid)


def motors_off_target() -> AttitudeTarget:
    """Level and zero thrust: what a disarmed vehicle "flies"."""
    return AttitudeTarget(quaternion=np.array([1.0, 0, 0, 0]), thrust=0.0)


def level_quaternion(est: VehicleState) -> np.ndarray:
    """Level attitude at the estimate's heading."""
    _, _, yaw = euler_from_quat(est.quaternion)
    return np.array([math.cos(yaw / 2), 0.0, 0.0, math.sin(yaw / 2)])


class FlightLoop:
    """Physics, mixer, position loop and attitude loop at their rates; see the module docstring."""

    def __init__(
        self,
        config: VehicleConfig,
        seed: int,
        outer_rate_hz: float,
        attitude_loops: Mapping[AttitudeControllerKind, AttitudeLoopFactory] | None,
    ) -> None:
        self.config = config  # the vehicle's own (shared) config tree, sections replaced by parameter changes
        self.attitude_loops = dict(attitude_loops or {AttitudeControllerKind.PID: builtin_pid_loop})
        self.seed = seed
        self.outer_dt = 1.0 / outer_rate_hz
        self.attitude_steps = max(1, round(ATTITUDE_RATE_HZ / outer_rate_hz))
        self.attitude_dt = self.outer_dt / self.attitude_steps
        self.physics_steps = max(1, round(self.attitude_dt * PHYSICS_RATE_HZ))
        self.sim = self._make_simulator()
        self.mixer = Mixer(config.controller_airframe)  # the autopilot's mixer knows the design model
        self.attitude = self._make_attitude_controller()
        self.position = self._make_position_controller()

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

    def _make_position_controller(self) -> PidPositionController:
        return PidPositionController(self.config.controller_airframe, self.config.position_pid)

    def apply_config(self, changed: str) -> None:
        """Rebuild the parts that depend on config section `changed`."""
        if changed in ("wind", "disturbance", "sensor_noise", "airframe"):
            self.sim.reconfigure(
                airframe=self.config.airframe,
                wind=self.config.wind,
                disturbance=self.config.disturbance,
                sensor_noise=self.config.sensor_noise,
            )
        if changed == "airframe":
            self.mixer = Mixer(self.config.controller_airframe)
        if changed in ("airframe", "attitude_pid", "control"):
            self.attitude = self._make_attitude_controller()
        if changed in ("airframe", "position_pid"):
            self.position = self._make_position_controller()

    def reset_controllers(self) -> None:
        self.attitude.reset()
        self.position.reset()

    # ----- one outer tick
    def outer_target(
        self,
        est: VehicleState,
        setpoint: TrajectorySetpoint,
        offboard_target: AttitudeTarget | None,
        *,
        armed: bool,
        idling: bool,
    ) -> tuple[AttitudeTarget, str]:
        """The tick's attitude target and who set it: "off" (disarmed), "idle" (armed on the ground before
        the climb: level at idle throttle), "offboard" (the offboard controller's target, None when not in
        OFFBOARD) or "builtin" (the position loop toward the setpoint)."""
        if not armed:
            return motors_off_target(), "off"
        if idling:
            return AttitudeTarget(quaternion=level_quaternion(est), thrust=IDLE_THROTTLE), "idle"
        if offboard_target is not None:
            return offboard_target, "offboard"
        return self.position.update(setpoint, est, self.outer_dt), "builtin"

    def fly(self, target: AttitudeTarget, source: str) -> bool:
        """One outer period of attitude loop and physics toward `target`; whether the mixer saturated."""
        saturated = False
        thrust_n = target.thrust * self.config.controller_airframe.max_thrust_n
        # a compiled loop flies the steps of the Python loop below in one call ("idle": the law runs, its torque
        # is not applied)
        steps = (thrust_n, self.attitude_steps, self.physics_steps, self.attitude_dt, source != "idle")
        if source == "off":  # rotors commanded to 0 all tick: the physics steps in one batch, same result
            self.sim.set_rotor_commands(np.zeros(4))
            self.sim.step(self.attitude_steps * self.physics_steps)
        elif isinstance(self.attitude, PidAttitudeController):
            saturated = self.sim.run_pid_attitude_steps(self.attitude, self.mixer, target, *steps)
        elif isinstance(self.attitude, CompiledAttitudeLoop):
            law = self.attitude.kernel_arguments(target)
            saturated = self.sim.run_attitude_steps(self.attitude.inner_loop, law, self.mixer, *steps)
        else:
            for _ in range(self.attitude_steps):
                measured = self.sim.measure()
                torque = self.attitude.update(target, measured, self.attitude_dt)
                if source == "idle":
                    torque = np.zeros(3)
                self.sim.set_rotor_commands(self.mixer.rotor_commands(thrust_n, torque))
                saturated = saturated or self.mixer.saturated
                self.sim.step(self.physics_steps)
        return saturated
