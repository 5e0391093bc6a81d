"""The built-in PX4-style position loop: position P -> velocity PID -> acceleration -> attitude + thrust.

As PX4's PositionControl (mc_pos_control): velocity setpoint = feed-forward + P * position error, limited
(horizontal norm, climb, descent); acceleration = feed-forward + P * velocity error + integral - D * measured
acceleration, limited (horizontal norm, up, down); then uavcore.rotation.acceleration_to_attitude turns it
into an AttitudeTarget (tilt limit, thrust normalised to the airframe's maximum). A NaN position component
means "no position control on that axis" (velocity control, e.g. a constant-rate descent); NaN velocity or
acceleration feed-forward counts as 0, a NaN yaw keeps the current heading. The velocity integrator is
clamped, frozen horizontally while the horizontal acceleration is limited and vertically while thrust is
saturated in the direction it would push (anti-windup). Gains use PX4's names and defaults (MPC_*), which
are in SI units.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

import numpy as np

from uavcore.airframe import Airframe, ModelParameterError
from uavcore.rotation import acceleration_to_attitude, heading
from uavcore.state import AttitudeTarget, TrajectorySetpoint, VehicleState


@dataclass(frozen=True)
class PidPositionGains:
    """PX4 MPC_* gains and limits (lower case)."""

    mpc_xy_p: float = 0.95  # 1/s
    mpc_z_p: float = 1.0
    mpc_xy_vel_p_acc: float = 1.8  # (m/s^2) / (m/s)
    mpc_xy_vel_i_acc: float = 0.4
    mpc_xy_vel_d_acc: float = 0.2
    mpc_z_vel_p_acc: float = 4.0
    mpc_z_vel_i_acc: float = 2.0
    mpc_z_vel_d_acc: float = 0.0
    mpc_xy_vel_max: float = 12.0  # m/s
    mpc_z_vel_max_up: float = 3.0
    mpc_z_vel_max_dn: float = 1.5
    mpc_acc_hor_max: float = 6.0  # m/s^2, horizontal acceleration setpoint (feed-forward + feedback)
    mpc_acc_up_max: float = 8.0  # m/s^2
    mpc_acc_down_max: float = 5.0  # m/s^2
    mpc_tiltmax_air: float = 35.0  # deg
    integrator_limit_xy: float = 4.0  # m/s^2
    integrator_limit_z: float = 4.0
    velocity_derivative_cutoff: float = 5.0  # Hz, low-pass on the measured acceleration of the D term

    def __post_init__(self) -> None:
        for f in dataclasses.fields(self):
            value = getattr(self, f.name)
            if not isinstance(value, int | float) or not math.isfinite(value) or value < 0:
                raise ModelParameterError(f"position gain {f.name} must be finite and >= 0, got {value!r}")
        if not 0 < self.mpc_tiltmax_air < 90:
            raise ModelParameterError("mpc_tiltmax_air must be in (0, 90) degrees")


def _finite_or(value: float, default: float) -> float:
    return value if math.isfinite(value) else default


class PidPositionController:
    """Cascade position -> velocity -> acceleration -> AttitudeTarget for one airframe."""

    def __init__(self, airframe: Airframe, gains: PidPositionGains | None = None) -> None:
        self.airframe = airframe
        self.gains = gains or PidPositionGains()
        self.reset()

    def reset_horizontal(self) -> None:
        """Forget the horizontal velocity integrator: with no horizontal position estimate (GPS lost) the vehicle
        descends level, as PX4's Descend, instead of leaning on into the wind it last fought."""
        self.integral[:2] = 0.0

    def reset(self) -> None:
        """Forget the velocity integrator and the derivative filter (on arming, after landing)."""
        self.integral = np.zeros(3)
        self._previous_velocity: np.ndarray | None = None
        self._acceleration = np.zeros(3)
        self.velocity_setpoint = np.zeros(3)
        self.acceleration_setpoint = np.zeros(3)

    def update(self, setpoint: TrajectorySetpoint, estimate: VehicleState, dt: float) -> AttitudeTarget:
        """Attitude and normalised thrust that steer the estimate toward the setpoint; dt s since last call."""
        if not dt > 0:
            raise ModelParameterError(f"position update needs dt > 0, got {dt}")
        g = self.gains
        position = estimate.position
        velocity = estimate.velocity
        kp = (g.mpc_xy_p, g.mpc_xy_p, g.mpc_z_p)
        vel_sp = [0.0, 0.0, 0.0]
        for i in range(3):
            feed_forward = _finite_or(float(setpoint.velocity[i]), 0.0)
            target = float(setpoint.position[i])
            vel_sp[i] = feed_forward + (kp[i] * (target - float(position[i])) if math.isfinite(target) else 0.0)
        horizontal = math.hypot(vel_sp[0], vel_sp[1])
        if horizontal > g.mpc_xy_vel_max:
            vel_sp[0] *= g.mpc_xy_vel_max / horizontal
            vel_sp[1] *= g.mpc_xy_vel_max / horizontal
        vel_sp[2] = min(max(vel_sp[2], -g.mpc_z_vel_max_up), g.mpc_z_vel_max_dn)

        if self._previous_velocity is not None:
            alpha = dt / (dt + 1.0 / (2.0 * math.pi * g.velocity_derivative_cutoff))
            self._acceleration += alpha * ((velocity - self._previous_velocity) / dt - self._acceleration)
        self._previous_velocity = np.array(velocity, dtype=float)

        vel_p = (g.mpc_xy_vel_p_acc, g.mpc_xy_vel_p_acc, g.mpc_z_vel_p_acc)
        vel_d = (g.mpc_xy_vel_d_acc, g.mpc_xy_vel_d_acc, g.mpc_z_vel_d_acc)
        errors = [vel_sp[i] - float(velocity[i]) for i in range(3)]
        acc_sp = [
            _finite_or(float(setpoint.acceleration[i]), 0.0)
            + vel_p[i] * errors[i]
            + self.integral[i]
            - vel_d[i] * self._acceleration[i]
            for i in range(3)
        ]
        horizontal = math.hypot(acc_sp[0], acc_sp[1])
        horizontal_limited = horizontal > g.mpc_acc_hor_max
        if horizontal_limited:
            acc_sp[0] *= g.mpc_acc_hor_max / horizontal
            acc_sp[1] *= g.mpc_acc_hor_max / horizontal
        acc_sp[2] = min(max(acc_sp[2], -g.mpc_acc_up_max), g.mpc_acc_down_max)
        af = self.airframe
        yaw = float(setpoint.yaw)
        if not math.isfinite(yaw):  # PX4: no yaw setpoint means keep the current heading
            yaw = heading(estimate.quaternion)
        yaw_rate = _finite_or(float(setpoint.yaw_rate), 0.0)  # fed forward in body axes, as PX4
        tilt_max = math.radians(g.mpc_tiltmax_air)
        target = acceleration_to_attitude(acc_sp, yaw, af.mass, af.g, af.max_thrust_n, tilt_max, yaw_rate)

        # integrate, except horizontally while the acceleration is limited and vertically while thrust is
        # saturated the way the error pushes (NED: up is -z)
        vel_i = (g.mpc_xy_vel_i_acc, g.mpc_xy_vel_i_acc, g.mpc_z_vel_i_acc)
        thrust_stuck = (target.thrust >= 1.0 and errors[2] < 0) or (target.thrust <= 0.0 and errors[2] > 0)
        for i in range(3):
            if (i < 2 and horizontal_limited) or (i == 2 and thrust_stuck):
                continue
            self.integral[i] += vel_i[i] * errors[i] * dt
        horizontal = math.hypot(self.integral[0], self.integral[1])
        if horizontal > g.integrator_limit_xy:
            self.integral[0:2] *= g.integrator_limit_xy / horizontal
        self.integral[2] = min(max(self.integral[2], -g.integrator_limit_z), g.integrator_limit_z)
        self.velocity_setpoint = np.array(vel_sp)
        self.acceleration_setpoint = np.array(acc_sp)
        return target
