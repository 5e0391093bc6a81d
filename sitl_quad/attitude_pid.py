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

The law is a numba kernel on flat float arrays (gains: ``PidAttitudeGains.as_array``, controller state: the
``S_*`` layout below), so the vehicle's compiled inner loop (sitl_quad.inner_loop) runs the very same code;
``PidAttitudeController`` is its Python face.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

import numpy as np

from uavcore.airframe import ModelParameterError
from uavcore.kernel_cache import cached_kernel
from uavcore.quaternion_kernels import Quat, Vec3, quat_inverse, quat_product, rotate_vector
from uavcore.state import AttitudeTarget, VehicleState


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

    def as_array(self) -> np.ndarray:
        """The gains as float64 in declaration order, for the kernels (read through the G_* indices)."""
        return np.array([getattr(self, f.name) for f in dataclasses.fields(self)], dtype=np.float64)


# Index of each gain in PidAttitudeGains.as_array().
_INDEX = {f.name: i for i, f in enumerate(dataclasses.fields(PidAttitudeGains))}
G_ROLL_P = _INDEX["mc_roll_p"]
G_PITCH_P = _INDEX["mc_pitch_p"]
G_YAW_P = _INDEX["mc_yaw_p"]
G_YAW_WEIGHT = _INDEX["mc_yaw_weight"]
G_ROLLRATE_P = _INDEX["mc_rollrate_p"]
G_ROLLRATE_I = _INDEX["mc_rollrate_i"]
G_ROLLRATE_D = _INDEX["mc_rollrate_d"]
G_PITCHRATE_P = _INDEX["mc_pitchrate_p"]
G_PITCHRATE_I = _INDEX["mc_pitchrate_i"]
G_PITCHRATE_D = _INDEX["mc_pitchrate_d"]
G_YAWRATE_P = _INDEX["mc_yawrate_p"]
G_YAWRATE_I = _INDEX["mc_yawrate_i"]
G_YAWRATE_D = _INDEX["mc_yawrate_d"]
G_RR_INT_LIM = _INDEX["mc_rr_int_lim"]
G_PR_INT_LIM = _INDEX["mc_pr_int_lim"]
G_YR_INT_LIM = _INDEX["mc_yr_int_lim"]
G_ROLLRATE_MAX = _INDEX["mc_rollrate_max"]
G_PITCHRATE_MAX = _INDEX["mc_pitchrate_max"]
G_YAWRATE_MAX = _INDEX["mc_yawrate_max"]
G_DTERM_CUTOFF = _INDEX["mc_dterm_cutoff"]

# The controller's state, one flat float array: rate integrators [0:3] (N m), the previous measured rates
# [3:6] and a flag [6] telling they are set (the D term needs two measurements), the low-passed rate
# derivative [7:10], the last rate setpoint [10:13] (not fed back: there to inspect the attitude stage).
S_INTEGRAL = 0
S_PREVIOUS_RATES = 3
S_HAS_PREVIOUS = 6
S_RATE_DERIVATIVE = 7
S_RATE_SETPOINT = 10
PID_STATE_SIZE = 13

I_FADE_RATE = math.radians(400.0)  # rad/s of rate error at which PX4's integrator gain has faded to zero


@cached_kernel
def shortest_rotation(v1: Vec3, v2: Vec3) -> Quat:
    """Unit quaternion turning unit vector v1 onto unit vector v2 by the shortest arc (PX4's Quatf(v1, v2))."""
    cx, cy, cz = v1[1] * v2[2] - v1[2] * v2[1], v1[2] * v2[0] - v1[0] * v2[2], v1[0] * v2[1] - v1[1] * v2[0]
    dot = v1[0] * v2[0] + v1[1] * v2[1] + v1[2] * v2[2]
    if math.sqrt(cx * cx + cy * cy + cz * cz) < 1e-6 and dot < 0:  # opposite: any perpendicular axis
        # cross v1 with the unit axis along which v1 is smallest (the first such axis on a tie)
        a0, a1, a2 = abs(v1[0]), abs(v1[1]), abs(v1[2])
        e0, e1, e2 = 0.0, 0.0, 0.0
        if a0 <= a1 and a0 <= a2:
            e0 = 1.0
        elif a1 <= a2:
            e1 = 1.0
        else:
            e2 = 1.0
        cx, cy, cz = v1[1] * e2 - v1[2] * e1, v1[2] * e0 - v1[0] * e2, v1[0] * e1 - v1[1] * e0
        w = 0.0
    else:
        w = dot + 1.0
    n = math.sqrt(w * w + cx * cx + cy * cy + cz * cz)
    return w / n, cx / n, cy / n, cz / n


@cached_kernel
def attitude_rate_setpoint_kernel(gains: np.ndarray, q: np.ndarray, qd: np.ndarray, feedforward: np.ndarray) -> Vec3:
    """Body-rate setpoint (rad/s) from attitude q toward qd plus the feed-forward body rates, PX4's
    AttitudeControl::update."""
    q_now = (q[0], q[1], q[2], q[3])
    q_goal = (qd[0], qd[1], qd[2], qd[3])
    # reduced attitude: only turn the thrust axis, then add a weighted share of the yaw error
    down = (0.0, 0.0, 1.0)
    qd_red = shortest_rotation(rotate_vector(q_now, down), rotate_vector(q_goal, down))
    near_flip = abs(qd_red[1]) > 1 - 1e-5 or abs(qd_red[2]) > 1 - 1e-5  # thrust axis upside down: full
    qd_red = q_goal if near_flip else quat_product(qd_red, q_now)
    q_mix = quat_product(quat_inverse(qd_red), q_goal)
    if q_mix[0] < 0:
        q_mix = (-q_mix[0], -q_mix[1], -q_mix[2], -q_mix[3])
    mix_w = min(max(q_mix[0], -1.0), 1.0)
    mix_z = min(max(q_mix[3], -1.0), 1.0)
    weight = gains[G_YAW_WEIGHT]
    yaw_share = (math.cos(weight * math.acos(mix_w)), 0.0, 0.0, math.sin(weight * math.asin(mix_z)))
    qe = quat_product(quat_inverse(q_now), quat_product(qd_red, yaw_share))
    sign = 2.0 if qe[0] >= 0 else -2.0
    yaw_p = gains[G_YAW_P] / weight if weight > 1e-4 else gains[G_YAW_P]
    roll = sign * qe[1] * gains[G_ROLL_P] + feedforward[0]
    pitch = sign * qe[2] * gains[G_PITCH_P] + feedforward[1]
    yaw = sign * qe[3] * yaw_p + feedforward[2]
    roll_max, pitch_max, yaw_max = gains[G_ROLLRATE_MAX], gains[G_PITCHRATE_MAX], gains[G_YAWRATE_MAX]
    return (
        min(max(roll, -roll_max), roll_max),
        min(max(pitch, -pitch_max), pitch_max),
        min(max(yaw, -yaw_max), yaw_max),
    )


@cached_kernel
def pid_attitude_torque(
    gains: np.ndarray,
    pid_state: np.ndarray,
    q: np.ndarray,
    rates: np.ndarray,
    qd: np.ndarray,
    feedforward: np.ndarray,
    dt: float,
    torque: np.ndarray,
) -> None:
    """One step of the cascade: writes the body torque [roll, pitch, yaw] (N m) toward qd from the measured
    attitude q and body rates into torque, and advances pid_state (S_* layout) by dt seconds."""
    rate_sp = attitude_rate_setpoint_kernel(gains, q, qd, feedforward)
    # D term: low-passed derivative of the measured rate
    if pid_state[S_HAS_PREVIOUS] != 0.0:
        cutoff = gains[G_DTERM_CUTOFF]
        alpha = dt / (dt + 1.0 / (2.0 * math.pi * cutoff)) if cutoff > 0 else 1.0
        for i in range(3):
            raw = (rates[i] - pid_state[S_PREVIOUS_RATES + i]) / dt
            pid_state[S_RATE_DERIVATIVE + i] += alpha * (raw - pid_state[S_RATE_DERIVATIVE + i])
    for i in range(3):
        pid_state[S_PREVIOUS_RATES + i] = rates[i]
    pid_state[S_HAS_PREVIOUS] = 1.0
    p_gains = (gains[G_ROLLRATE_P], gains[G_PITCHRATE_P], gains[G_YAWRATE_P])
    i_gains = (gains[G_ROLLRATE_I], gains[G_PITCHRATE_I], gains[G_YAWRATE_I])
    d_gains = (gains[G_ROLLRATE_D], gains[G_PITCHRATE_D], gains[G_YAWRATE_D])
    limits = (gains[G_RR_INT_LIM], gains[G_PR_INT_LIM], gains[G_YR_INT_LIM])
    for i in range(3):
        error = rate_sp[i] - rates[i]
        integral = pid_state[S_INTEGRAL + i]
        torque[i] = p_gains[i] * error + integral - d_gains[i] * pid_state[S_RATE_DERIVATIVE + i]
        fade = max(0.0, 1.0 - (error / I_FADE_RATE) ** 2)  # PX4: less I for large errors
        integral += fade * i_gains[i] * error * dt
        pid_state[S_INTEGRAL + i] = min(max(integral, -limits[i]), limits[i])
        pid_state[S_RATE_SETPOINT + i] = rate_sp[i]


_NO_FEEDFORWARD = np.zeros(3)


def _floats(values) -> np.ndarray:
    return np.ascontiguousarray(values, dtype=np.float64)


class PidAttitudeController:
    """Implements uavcore.control.AttitudeController with PX4's cascade (see module docstring).

    ``kernel_gains`` and ``kernel_state`` are the arrays the kernels read and advance; the compiled inner
    loop works on them directly, so both paths share one controller state.
    """

    def __init__(self, gains: PidAttitudeGains | None = None) -> None:
        self.gains = gains or PidAttitudeGains()
        self.kernel_gains = self.gains.as_array()
        self.kernel_state = np.zeros(PID_STATE_SIZE)

    def reset(self) -> None:
        self.kernel_state[:] = 0.0

    @staticmethod
    def target_arrays(target: AttitudeTarget) -> tuple[np.ndarray, np.ndarray]:
        """The target's quaternion and feed-forward body rates (zeros when it has none) as kernel inputs."""
        qd = _floats(target.quaternion)
        feedforward = _NO_FEEDFORWARD if target.body_rates is None else _floats(target.body_rates)
        if qd.shape != (4,) or feedforward.shape != (3,):  # the kernels index without bounds checks
            raise ModelParameterError(
                f"attitude target needs 4 quaternion components and 3 body rates, got "
                f"{target.quaternion!r}, {target.body_rates!r}"
            )
        return qd, feedforward

    def update(self, target: AttitudeTarget, state: VehicleState, dt: float) -> np.ndarray:
        """Body torque [roll, pitch, yaw] (N m) toward target from the measured state, after dt seconds."""
        if not dt > 0:
            raise ModelParameterError(f"attitude update needs dt > 0, got {dt}")
        qd, feedforward = self.target_arrays(target)
        torque = np.empty(3)
        pid_attitude_torque(
            self.kernel_gains,
            self.kernel_state,
            _floats(state.quaternion),
            _floats(state.angular_velocity),
            qd,
            feedforward,
            float(dt),
            torque,
        )
        return torque
