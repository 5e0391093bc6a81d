"""PX4-style attitude controller: quaternion attitude P feeding a body-rate PID, output body torque in N m.

Structure as PX4's mc_att_control + mc_rate_control (AttitudeControl.cpp, RateControl.cpp):
1. Attitude: the tilt (thrust direction) error is corrected first; yaw is mixed in with weight
   ``yaw_weight`` (MC_YAW_WEIGHT), because a quadrotor's yaw authority is far weaker than its roll/pitch
   authority (here 0.17 N m against 6 N m at hover). The error quaternion qe = q^-1 qd gives the rate setpoint
   2 Im(qe) * P per axis, plus the target's body-rate feed-forward, limited per axis.
2. Rates: torque = P e + I int(e) - D d(rate)/dt. D acts on the measured rate (no kick on setpoint steps),
   low-pass filtered; the integrator is clamped and its gain fades for large errors (PX4's i_factor).
Gains are in SI units (N m per rad/s, etc.), unlike PX4's normalised outputs, and are tuned for Table 2:
rate loop crossover about 25 rad/s on roll/pitch (motor lag 0.02 s), attitude P 6.5 (PX4's default).
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

import numpy as np

from sitl_quad.airframe import ModelParameterError
from sitl_quad.rotation import quat_conjugate, quat_multiply, rotate
from sitl_quad.state import AttitudeTarget, VehicleState


@dataclass(frozen=True)
class PidAttitudeGains:
    """Gains with PX4's parameter names (lower case); torques in N m, rates in rad/s."""

    mc_roll_p: float = 6.5  # 1/s
    mc_pitch_p: float = 6.5
    mc_yaw_p: float = 2.0
    mc_yaw_weight: float = 0.4
    mc_rollrate_p: float = 2.0  # N m / (rad/s)
    mc_rollrate_i: float = 2.5  # N m / rad
    mc_rollrate_d: float = 0.02  # N m / (rad/s^2)
    mc_pitchrate_p: float = 2.0
    mc_pitchrate_i: float = 2.5
    mc_pitchrate_d: float = 0.02
    mc_yawrate_p: float = 1.0
    mc_yawrate_i: float = 0.3
    mc_yawrate_d: float = 0.0
    mc_rr_int_lim: float = 0.5  # N m, roll-rate integrator limit
    mc_pr_int_lim: float = 0.5
    mc_yr_int_lim: float = 0.1
    mc_rollrate_max: float = math.radians(220.0)  # rad/s
    mc_pitchrate_max: float = math.radians(220.0)
    mc_yawrate_max: float = math.radians(60.0)
    mc_dterm_cutoff: float = 30.0  # Hz, low-pass on the D term's rate derivative

    def __post_init__(self) -> None:
        for f in dataclasses.fields(self):
            value = getattr(self, f.name)
            if not isinstance(value, int | float) or not math.isfinite(value) or value < 0:
                raise ModelParameterError(f"attitude gain {f.name} must be finite and >= 0, got {value!r}")
        if self.mc_yaw_weight > 1:
            raise ModelParameterError("mc_yaw_weight must be in [0, 1]")


def _shortest_rotation(v1, v2) -> tuple[float, float, float, float]:
    """Unit quaternion turning unit vector v1 onto unit vector v2 by the shortest arc (PX4's Quatf(v1, v2))."""
    cx, cy, cz = v1[1] * v2[2] - v1[2] * v2[1], v1[2] * v2[0] - v1[0] * v2[2], v1[0] * v2[1] - v1[1] * v2[0]
    dot = v1[0] * v2[0] + v1[1] * v2[1] + v1[2] * v2[2]
    if math.sqrt(cx * cx + cy * cy + cz * cz) < 1e-6 and dot < 0:  # opposite: any perpendicular axis
        ax = [abs(c) for c in v1]
        k = ax.index(min(ax))
        e = [0.0, 0.0, 0.0]
        e[k] = 1.0
        cx, cy, cz = v1[1] * e[2] - v1[2] * e[1], v1[2] * e[0] - v1[0] * e[2], v1[0] * e[1] - v1[1] * e[0]
        w = 0.0
    else:
        w = dot + 1.0
    n = math.sqrt(w * w + cx * cx + cy * cy + cz * cz)
    return w / n, cx / n, cy / n, cz / n


class PidAttitudeController:
    """Implements sitl_quad.attitude_control.AttitudeController with PX4's cascade (see module docstring)."""

    def __init__(self, gains: PidAttitudeGains | None = None) -> None:
        self.gains = gains or PidAttitudeGains()
        self.reset()

    def reset(self) -> None:
        self._integral = [0.0, 0.0, 0.0]
        self._previous_rates: tuple[float, float, float] | None = None
        self._rate_derivative = [0.0, 0.0, 0.0]
        self.rate_setpoint = np.zeros(3)

    def attitude_rate_setpoint(self, target: AttitudeTarget, q) -> list[float]:
        """Body-rate setpoint (rad/s) from the attitude error, PX4's AttitudeControl::update.

        Quaternions travel as lists of Python floats: numpy's per-element cost would dominate at 250 Hz.
        """
        g = self.gains
        q = [float(c) for c in q]
        qd = target.quaternion.tolist() if isinstance(target.quaternion, np.ndarray) else list(target.quaternion)
        # reduced attitude: only turn the thrust axis, then add a weighted share of the yaw error
        down = (0.0, 0.0, 1.0)
        qd_red = _shortest_rotation(rotate(q, down).tolist(), rotate(qd, down).tolist())
        near_flip = abs(qd_red[1]) > 1 - 1e-5 or abs(qd_red[2]) > 1 - 1e-5  # thrust axis upside down: full
        qd_red = qd if near_flip else quat_multiply(qd_red, q).tolist()
        q_mix = quat_multiply(quat_conjugate(qd_red).tolist(), qd).tolist()
        if q_mix[0] < 0:
            q_mix = [-c for c in q_mix]
        mix_w = min(max(q_mix[0], -1.0), 1.0)
        mix_z = min(max(q_mix[3], -1.0), 1.0)
        weight = g.mc_yaw_weight
        yaw_share = (math.cos(weight * math.acos(mix_w)), 0.0, 0.0, math.sin(weight * math.asin(mix_z)))
        qe = quat_multiply(quat_conjugate(q).tolist(), quat_multiply(qd_red, yaw_share).tolist()).tolist()
        sign = 2.0 if qe[0] >= 0 else -2.0
        yaw_p = g.mc_yaw_p / weight if weight > 1e-4 else g.mc_yaw_p
        rates = [sign * qe[1] * g.mc_roll_p, sign * qe[2] * g.mc_pitch_p, sign * qe[3] * yaw_p]
        if target.body_rates is not None:
            rates = [r + float(f) for r, f in zip(rates, target.body_rates, strict=True)]
        limits = (g.mc_rollrate_max, g.mc_pitchrate_max, g.mc_yawrate_max)
        return [min(max(r, -lim), lim) for r, lim in zip(rates, limits, strict=True)]

    def update(self, target: AttitudeTarget, state: VehicleState, dt: float) -> np.ndarray:
        """Body torque [roll, pitch, yaw] (N m) toward target from the measured state, after dt seconds."""
        if not dt > 0:
            raise ModelParameterError(f"attitude update needs dt > 0, got {dt}")
        g = self.gains
        rate_sp = self.attitude_rate_setpoint(target, state.quaternion.tolist())
        rates = tuple(state.angular_velocity.tolist())
        # D term: low-passed derivative of the measured rate
        if self._previous_rates is not None:
            alpha = dt / (dt + 1.0 / (2.0 * math.pi * g.mc_dterm_cutoff)) if g.mc_dterm_cutoff > 0 else 1.0
            for i in range(3):
                raw = (rates[i] - self._previous_rates[i]) / dt
                self._rate_derivative[i] += alpha * (raw - self._rate_derivative[i])
        self._previous_rates = rates
        p_gains = (g.mc_rollrate_p, g.mc_pitchrate_p, g.mc_yawrate_p)
        i_gains = (g.mc_rollrate_i, g.mc_pitchrate_i, g.mc_yawrate_i)
        d_gains = (g.mc_rollrate_d, g.mc_pitchrate_d, g.mc_yawrate_d)
        limits = (g.mc_rr_int_lim, g.mc_pr_int_lim, g.mc_yr_int_lim)
        torque = [0.0, 0.0, 0.0]
        for i in range(3):
            error = rate_sp[i] - rates[i]
            torque[i] = p_gains[i] * error + self._integral[i] - d_gains[i] * self._rate_derivative[i]
            fade = max(0.0, 1.0 - (error / math.radians(400.0)) ** 2)  # PX4: less I for large errors
            integral = self._integral[i] + fade * i_gains[i] * error * dt
            self._integral[i] = min(max(integral, -limits[i]), limits[i])
        self.rate_setpoint = np.array(rate_sp)
        return np.array(torque)
