"""The simulated quadrotor: rigid body + rotors + wind + disturbances + sensor noise, stepped at fixed dt.

Pure computation, no I/O. One seed fixes everything random: it is split into independent streams for the
wind, the disturbance terms and the sensors, so e.g. changing the sensor noise does not change the wind.
Results do not depend on how the steps are batched (step(4) twice equals step(1) eight times).
``run_attitude_steps`` runs the vehicle's 250 Hz loop in one compiled call (an inner loop as sitl_quad.inner_loop
describes: ``run_pid_attitude_steps`` with the PID attitude controller), with the same results as stepping it
from Python.
"""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np

from sitl_quad.attitude_pid import PidAttitudeController
from sitl_quad.disturbances import DisturbanceConfig, GaussianDisturbance
from sitl_quad.inner_loop import disturbance_samples_due, pid_inner_loop
from sitl_quad.rigid_body import INFO_SIZE, STATE_SIZE, advance, physics_params
from sitl_quad.rotors import Mixer
from sitl_quad.sensors import SensorNoise, Sensors
from sitl_quad.wind import WindConfig, WindModel
from uavcore.airframe import Airframe, ModelParameterError
from uavcore.rotation import quat_from_euler
from uavcore.state import AttitudeTarget, VehicleState

# (physics, sensor_noise, law, attitude_dt, thrust_n, apply_torque, attitude_steps, physics_steps, saturated)
# -> (attitude steps completed, on the ground): see sitl_quad.inner_loop
InnerLoop = Callable[..., tuple[int, bool]]


class Simulator:
    """Fixed-step (RK4, default 1 kHz) simulation of one quadrotor.

    ``state`` returns a fresh VehicleState (copies; changing it does not change the simulation).
    ``last_disturbance`` reports what acted on the body during the last step (the truth an observer should
    estimate): ``wind_ned`` (m/s), ``d_accel_ned`` (D_x, D_y, D_z, m/s^2), ``d_angular`` (D_phi, D_theta,
    D_psi, rad/s^2) and ``external_accel_ned``: drag + D terms, i.e. the acceleration not explained by rotor
    thrust and gravity (ground reaction excluded), evaluated at the end of the last step; likewise for the
    rotation (rad/s^2 about the body axes, at the end of the last step): ``external_angular_accel``, eq. 1's
    gyroscopic coupling + D_angular, and ``rotor_angular_accel``, the rotors' delivered torque / inertia (their sum
    is the body's angular acceleration).
    """

    def __init__(
        self,
        airframe: Airframe | None = None,
        wind: WindConfig | None = None,
        disturbance: DisturbanceConfig | None = None,
        sensor_noise: SensorNoise | None = None,
        seed: int = 0,
        dt: float = 0.001,
        position=(0.0, 0.0, 0.0),
        yaw: float = 0.0,
        rotor_speed=0.0,
    ) -> None:
        if not (isinstance(dt, int | float) and math.isfinite(dt) and 0 < dt <= 0.1):
            raise ModelParameterError(f"dt must be in (0, 0.1] s, got {dt!r}")
        self.airframe = airframe or Airframe.table2()
        self.wind_config = wind or WindConfig()
        self.disturbance_config = disturbance or DisturbanceConfig.none()
        self.sensor_noise = sensor_noise or SensorNoise.none()
        self.dt = float(dt)
        self.seed = seed
        self.rotor_health: tuple[float, ...] = (1.0, 1.0, 1.0, 1.0)  # sitl_quad.failure_injection
        self._params = physics_params(self.airframe, self.rotor_health)
        self._state = np.zeros(STATE_SIZE)
        self._omega_cmd = np.zeros(4)
        self._info = np.zeros(INFO_SIZE)
        self.reset(position=position, yaw=yaw, rotor_speed=rotor_speed)

    def reset(self, position=(0.0, 0.0, 0.0), yaw: float = 0.0, rotor_speed=0.0, seed: int | None = None) -> None:
        """Back to time 0 at rest at position (NED) with the given yaw and rotor speeds (one number or four,
        rad/s; also the initial commands).

        The random streams restart from the seed (the constructor's unless given), so a reset simulator
        repeats its first run.
        """
        position = np.asarray(position, dtype=float)
        if position.shape != (3,) or not np.all(np.isfinite(position)) or not math.isfinite(yaw):
            raise ModelParameterError(f"reset needs a finite NED position of 3 numbers and a yaw, got {position}")
        if seed is not None:
            self.seed = seed
        self._step_index = 0
        self.restart_disturbances()
        self._state[:] = 0.0
        self._state[0:3] = position
        self._state[6:10] = quat_from_euler(0.0, 0.0, yaw)
        speeds = np.asarray(rotor_speed, dtype=float)
        self.set_rotor_commands(np.full(4, float(speeds)) if speeds.ndim == 0 else speeds)
        self._state[13:17] = self._omega_cmd
        self._info[:] = 0.0
        self._on_ground = bool(self._state[2] >= 0.0)
        if self._on_ground:
            self._state[2] = 0.0

    def reconfigure(
        self,
        airframe: Airframe | None = None,
        wind: WindConfig | None = None,
        disturbance: DisturbanceConfig | None = None,
        sensor_noise: SensorNoise | None = None,
    ) -> None:
        """Swap configuration sections mid-run (a parameter change), keeping the state, the time and the
        random streams; a section given as None is left as it is. The turbulence state carries over, and the
        held disturbance sample stays until the next sample time of the new configuration."""
        if airframe is not None:
            self.airframe = airframe
            self._params = physics_params(airframe, self.rotor_health)
            self.set_rotor_commands(self._omega_cmd)
        if wind is not None:
            turbulence = self.wind.turbulence
            self.wind_config = wind
            self.wind = WindModel(wind, self.wind.rng)
            if self.wind.turbulent and np.any(turbulence):
                self.wind.turbulence[:] = turbulence
        if disturbance is not None:
            self.disturbance_config = disturbance
            self.disturbance = GaussianDisturbance(disturbance, self.disturbance.rng)
            self._steps_per_sample = max(1, round(disturbance.sample_time_s / self.dt))
        if sensor_noise is not None:
            self.sensor_noise = sensor_noise
            self.sensors = self.sensors.reconfigured(sensor_noise)

    def restart_disturbances(self) -> None:
        """Restart wind, turbulence, D-term and sensor-noise streams from the seed, with their clock at zero now.

        The vehicle calls this at takeoff, so a flight's disturbances (including a gust at gust_start_s) are
        the same for a given seed however long the vehicle sat on the ground before: that is what makes a
        lockstep flight repeatable when the ground station's commands arrive at arbitrary ticks.
        """
        wind_rng, disturbance_rng, sensor_rng = (
            np.random.default_rng(s) for s in np.random.SeedSequence(self.seed).spawn(3)
        )
        self.wind = WindModel(self.wind_config, wind_rng)
        self.disturbance = GaussianDisturbance(self.disturbance_config, disturbance_rng)
        self.sensors = Sensors(self.sensor_noise, sensor_rng)
        self._steps_per_sample = max(1, round(self.disturbance_config.sample_time_s / self.dt))
        self._disturbance_now = np.zeros(6)
        self._epoch = self._step_index

    @property
    def step_index(self) -> int:
        """Steps of dt since the start: simulated time as an exact integer."""
        return self._step_index

    @property
    def disturbance_time(self) -> float:
        """Seconds on the disturbances' clock (since the last restart_disturbances)."""
        return (self._step_index - self._epoch) * self.dt

    def set_state(self, state: VehicleState) -> None:
        """Overwrite the body's state (not the time, the commands or the random streams); for tests and
        scenario set-up. The quaternion is normalised."""
        values = np.concatenate(
            [state.position, state.velocity, state.quaternion, state.angular_velocity, state.rotor_speeds]
        ).astype(float)
        if values.shape != (STATE_SIZE,) or not np.all(np.isfinite(values)) or not np.any(values[6:10]):
            raise ModelParameterError("set_state needs finite 3-vectors, a non-zero quaternion and 4 rotor speeds")
        values[6:10] /= np.linalg.norm(values[6:10])
        self._state[:] = values
        self._on_ground = bool(values[2] >= 0.0)

    def set_rotor_health(self, health: tuple[float, float, float, float]) -> None:
        """Per rotor 1.0 (its ESC drives it) or 0.0 (blocked: an injected motor failure, the rotor spins down)."""
        self.rotor_health = tuple(float(h) for h in health)
        self._params = physics_params(self.airframe, self.rotor_health)

    def set_rotor_commands(self, omega_cmd) -> None:
        """Four rotor-speed commands (rad/s), clipped to the airframe's limits, held until changed."""
        omega = np.asarray(omega_cmd, dtype=float)
        if omega.shape != (4,) or not math.isfinite(float(omega.sum())):
            raise ModelParameterError(f"rotor commands must be 4 finite numbers, got {omega_cmd!r}")
        lo, hi = self.airframe.rotor_speed_min, self.airframe.rotor_speed_max
        self._omega_cmd[:] = [min(max(v, lo), hi) for v in omega.tolist()]

    def step(self, n: int = 1) -> None:
        """Advance n steps of dt."""
        if not isinstance(n, int | np.integer) or n < 0:
            raise ModelParameterError(f"step count must be a non-negative integer, got {n!r}")
        if n == 0:
            return
        first = self._step_index - self._epoch  # the disturbances' own clock
        period = self._steps_per_sample
        samples = disturbance_samples_due(first, n, period)
        self._on_ground = bool(
            advance(
                self._state,
                self._omega_cmd,
                self._params,
                self.wind.params,
                self.wind.turbulence,
                self.wind.noise(n),
                self._disturbance_now,
                self.disturbance.draw(samples),
                period,
                first,
                self.dt,
                n,
                self._info,
            )
        )
        self._step_index += n

    def run_pid_attitude_steps(
        self,
        controller: PidAttitudeController,
        mixer: Mixer,
        target: AttitudeTarget,
        thrust_n: float,
        attitude_steps: int,
        physics_steps: int,
        attitude_dt: float,
        apply_torque: bool = True,
    ) -> bool:
        """`run_attitude_steps` with the vehicle's PID (sitl_quad.inner_loop.pid_inner_loop)."""
        law = (controller.kernel_gains, controller.kernel_state, *controller.target_arrays(target))
        return self.run_attitude_steps(
            pid_inner_loop, law, mixer, thrust_n, attitude_steps, physics_steps, attitude_dt, apply_torque
        )

    def run_attitude_steps(
        self,
        inner_loop: InnerLoop,
        law: tuple,
        mixer: Mixer,
        thrust_n: float,
        attitude_steps: int,
        physics_steps: int,
        attitude_dt: float,
        apply_torque: bool = True,
    ) -> bool:
        """The attitude loop in one compiled call (an inner loop as sitl_quad.inner_loop describes, law its
        attitude law's arguments): attitude_steps times measure(), the controller's update(target, measured,
        attitude_dt), mixer.rotor_commands(thrust_n, torque) (zero torque unless apply_torque),
        set_rotor_commands and step(physics_steps). Same results as those calls, the same random streams; the
        controller's state and the mixer's counters advance as they would.
        Returns whether the mixer saturated at any of the steps.

        Raises ModelParameterError for a non-finite mixer input, after the steps before it (the sensor-noise,
        wind and disturbance streams have then advanced by all the steps).
        """
        counts_valid = all(isinstance(c, int | np.integer) for c in (attitude_steps, physics_steps))
        if not (counts_valid and attitude_steps >= 0 and physics_steps >= 1 and attitude_dt > 0):
            raise ModelParameterError(
                "attitude loop needs attitude_steps >= 0, physics_steps >= 1, dt > 0; "
                f"got {attitude_steps}, {physics_steps}, {attitude_dt}"
            )
        n = attitude_steps * physics_steps
        first = self._step_index - self._epoch  # the disturbances' own clock
        period = self._steps_per_sample
        physics = (
            self._state,
            self._omega_cmd,
            self._params,
            self.wind.params,
            self.wind.turbulence,
            self.wind.noise(n),
            self._disturbance_now,
            self.disturbance.draw(disturbance_samples_due(first, n, period)),
            int(period),
            int(first),
            self.dt,
            self._info,
            mixer.params,
        )
        saturated = np.zeros(attitude_steps, dtype=np.bool_)
        completed, on_ground = inner_loop(
            physics,
            self.sensors.noise(attitude_steps),
            law,
            float(attitude_dt),
            float(thrust_n),
            bool(apply_torque),
            int(attitude_steps),
            int(physics_steps),
            saturated,
        )
        self._step_index += completed * physics_steps
        if completed > 0:
            self._on_ground = bool(on_ground)
        mixer.record(saturated[:completed])
        if completed < attitude_steps:
            raise ModelParameterError(
                f"mixer input must be finite, got thrust {thrust_n} and the attitude "
                f"controller's torque at attitude step {completed}"
            )
        return bool(saturated.any())

    @property
    def t(self) -> float:
        """Simulated time, s (an exact multiple of dt)."""
        return self._step_index * self.dt

    @property
    def on_ground(self) -> bool:
        return self._on_ground

    @property
    def rotor_commands(self) -> np.ndarray:
        return self._omega_cmd.copy()

    @property
    def rotor_speeds(self) -> list[float]:
        """The four rotor speeds now (rad/s), as plain floats: what the battery model reads every tick."""
        return self._state[13:17].tolist()

    @property
    def state(self) -> VehicleState:
        s = self._state
        return VehicleState(
            t=self.t,
            position=s[0:3].copy(),
            velocity=s[3:6].copy(),
            quaternion=s[6:10].copy(),
            angular_velocity=s[10:13].copy(),
            rotor_speeds=s[13:17].copy(),
        )

    def measure(self) -> VehicleState:
        """The state as the sensors see it (SensorNoise added; the truth when there is none)."""
        return self.sensors.measure_flat(self._state, self.t)

    @property
    def last_disturbance(self) -> dict[str, np.ndarray]:
        info = self._info
        return {
            "wind_ned": info[0:3].copy(),
            "d_accel_ned": info[3:6].copy(),
            "d_angular": info[6:9].copy(),
            "external_accel_ned": info[9:12].copy(),
            "external_angular_accel": info[12:15].copy(),
            "rotor_angular_accel": info[15:18].copy(),
        }
