"""Geometric attitude tracking on SO(3) (Lee, Leok and McClamroch 2010): the vehicle's inner loop for MC_ATT_CTRL = 2.

T. Lee, M. Leok, N. H. McClamroch, "Geometric tracking control of a quadrotor UAV on SE(3)", 49th IEEE CDC,
2010 (equation numbers as in the paper and its arXiv version 1003.2005). The attitude half of the paper's
controller, as most quadrotor simulators ship it (RotorPy's SE3Control, ...), with R the body-to-world rotation
(NED world, FRD body, as in the paper, whose e3 points down too):

    e_R     = 1/2 (R_d^T R - R^T R_d)^vee                                     (10)
    e_Omega = Omega - R^T R_d Omega_d                                          (11)
    M       = -k_R e_R - k_Omega e_Omega + Omega x J Omega
              - J (hat(Omega) R^T R_d Omega_d - R^T R_d Omegadot_d)            (16)

Omega_d is the target's body-rate feed-forward (`AttitudeTarget.body_rates`, the outer loops' yaw-rate
feed-forward R_d^T e_z yaw_rate); Omegadot_d is taken as 0 (the outer loop sends no angular acceleration; the
navigator's turns change their rate slowly, 45 deg/s^2). No integral action: the law is stateless.

Gains (`GeometricAttitudeGains.for_bandwidth`): per body axis k_R = J_i w_i^2, k_Omega = 2 zeta J_i w_i, so each
axis linearised about the target is s^2 + 2 zeta w s + w^2 -- with w the ADRC attitude loop's omega_c (12 rad/s
roll/pitch, 4 yaw; adrc_offboard/gains/attitude_adrc.json) and zeta = 1 it flies "at the same attitude
bandwidth". Unlike PX4's cascade (sitl_quad.attitude_pid) there is no tilt-first prioritisation and no rate
limit: the paper's e_R weighs a yaw error like a tilt error. The torque is clipped per axis to what the Table 2
mixer can deliver around hover (4 N m roll/pitch, 0.16 N m yaw, the ADRC loop's u_max), so a large yaw error
cannot eat the roll/pitch authority in the mixer.

The law is the numba kernel `geometric_attitude_torque` on flat arrays (gains: `GeometricAttitudeGains.as_array`,
`G_*` layout), run by the compiled inner loop `geometric_inner_loop` (built on sitl_quad.inner_loop's `measure`
and `fly_attitude_step`, as the ADRC's loop in sitl_quad.attitude_loops); `GeometricAttitudeController` is its
Python face and a `CompiledAttitudeLoop`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from sitl_quad.inner_loop import fly_attitude_step, measure
from sitl_quad.rigid_body import STATE_SIZE
from uavcore.airframe import Airframe, ModelParameterError
from uavcore.kernel_cache import cached_kernel
from uavcore.quaternion_kernels import error_quaternion
from uavcore.state import AttitudeTarget, VehicleState

# The kernel's gains array: k_R [0:3] (N m / rad), k_Omega [3:6] (N m / (rad/s)), inertias [6:9] (kg m^2),
# torque limits [9:12] (N m), per body axis roll, pitch, yaw.
G_KR, G_KOMEGA, G_INERTIA, G_TORQUE_MAX = 0, 3, 6, 9
GAINS_SIZE = 12
TORQUE_MAX_ROLL_PITCH = 4.0  # N m, as the ADRC attitude loop's u_max: inside the Table 2 mixer's ~6 N m at hover
TORQUE_MAX_YAW = 0.16  # N m, ditto (~0.17 N m at hover)


@dataclass(frozen=True)
class GeometricAttitudeGains:
    """Per-axis (roll, pitch, yaw) gains of eq. (16) and the inertia its feed-forward terms use."""

    k_r: tuple[float, float, float]  # N m / rad
    k_omega: tuple[float, float, float]  # N m / (rad/s)
    inertia: tuple[float, float, float]  # kg m^2, the diagonal of J
    torque_max: tuple[float, float, float] = (TORQUE_MAX_ROLL_PITCH, TORQUE_MAX_ROLL_PITCH, TORQUE_MAX_YAW)

    def __post_init__(self) -> None:
        for name in ("k_r", "k_omega", "inertia", "torque_max"):
            values = getattr(self, name)
            if len(values) != 3 or not all(math.isfinite(v) and v > 0 for v in values):
                raise ModelParameterError(f"geometric attitude {name} needs 3 finite positive values, got {values!r}")

    @classmethod
    def for_bandwidth(
        cls,
        airframe: Airframe,
        omega_roll_pitch: float = 12.0,
        omega_yaw: float = 4.0,
        zeta: float = 1.0,
        torque_max: tuple[float, float, float] = (TORQUE_MAX_ROLL_PITCH, TORQUE_MAX_ROLL_PITCH, TORQUE_MAX_YAW),
    ) -> GeometricAttitudeGains:
        """k_R = J w^2, k_Omega = 2 zeta J w per axis (module docstring), for the airframe's inertias."""
        for name, value in (("omega_roll_pitch", omega_roll_pitch), ("omega_yaw", omega_yaw), ("zeta", zeta)):
            if not (math.isfinite(value) and value > 0):
                raise ModelParameterError(f"{name} must be finite and positive, got {value!r}")
        inertia = (airframe.ixx, airframe.iyy, airframe.izz)
        omegas = (omega_roll_pitch, omega_roll_pitch, omega_yaw)
        k_r = tuple(j * w * w for j, w in zip(inertia, omegas, strict=True))
        k_omega = tuple(2.0 * zeta * j * w for j, w in zip(inertia, omegas, strict=True))
        return cls(k_r, k_omega, inertia, torque_max)  # type: ignore[arg-type]

    def as_array(self) -> np.ndarray:
        return np.array([*self.k_r, *self.k_omega, *self.inertia, *self.torque_max], dtype=np.float64)


@cached_kernel
def relative_rotation(q: np.ndarray, qd: np.ndarray) -> np.ndarray:
    """R^T R_d as a 3x3 matrix: the matrix of q^-1 qd (the target's axes in the current body axes)."""
    ew, ex, ey, ez = error_quaternion((q[0], q[1], q[2], q[3]), (qd[0], qd[1], qd[2], qd[3]))
    n2 = ew * ew + ex * ex + ey * ey + ez * ez
    s = 2.0 / n2
    m = np.empty((3, 3))
    m[0, 0] = 1.0 - s * (ey * ey + ez * ez)
    m[0, 1] = s * (ex * ey - ew * ez)
    m[0, 2] = s * (ex * ez + ew * ey)
    m[1, 0] = s * (ex * ey + ew * ez)
    m[1, 1] = 1.0 - s * (ex * ex + ez * ez)
    m[1, 2] = s * (ey * ez - ew * ex)
    m[2, 0] = s * (ex * ez - ew * ey)
    m[2, 1] = s * (ey * ez + ew * ex)
    m[2, 2] = 1.0 - s * (ex * ex + ey * ey)
    return m


@cached_kernel
def attitude_error(q: np.ndarray, qd: np.ndarray) -> tuple[float, float, float]:
    """e_R of eq. (10), 1/2 (R_d^T R - R^T R_d)^vee, in body axes (rad for small errors; sin of the angle times
    the axis in general). With M = R^T R_d, R_d^T R - R^T R_d = M^T - M, and vee(S) = (S_32, S_13, S_21)."""
    m = relative_rotation(q, qd)
    return 0.5 * (m[1, 2] - m[2, 1]), 0.5 * (m[2, 0] - m[0, 2]), 0.5 * (m[0, 1] - m[1, 0])


@cached_kernel
def geometric_attitude_torque(
    gains: np.ndarray, q: np.ndarray, rates: np.ndarray, qd: np.ndarray, feedforward: np.ndarray, torque: np.ndarray
) -> None:
    """Eq. (16) with Omegadot_d = 0: write the body torque [roll, pitch, yaw] (N m) toward qd, from the measured
    attitude q and body rates, with the target's body rates feedforward (Omega_d), into torque (clipped per axis
    to gains' torque limits)."""
    m = relative_rotation(q, qd)  # R^T R_d
    e_r = (0.5 * (m[1, 2] - m[2, 1]), 0.5 * (m[2, 0] - m[0, 2]), 0.5 * (m[0, 1] - m[1, 0]))  # eq. (10)
    # R^T R_d Omega_d: the desired body rates seen in the current body axes
    wd = (
        m[0, 0] * feedforward[0] + m[0, 1] * feedforward[1] + m[0, 2] * feedforward[2],
        m[1, 0] * feedforward[0] + m[1, 1] * feedforward[1] + m[1, 2] * feedforward[2],
        m[2, 0] * feedforward[0] + m[2, 1] * feedforward[1] + m[2, 2] * feedforward[2],
    )
    jx, jy, jz = gains[G_INERTIA], gains[G_INERTIA + 1], gains[G_INERTIA + 2]
    p, r_, s = rates[0], rates[1], rates[2]
    # Omega x J Omega (gyroscopic term, diagonal J)
    gyro = (r_ * jz * s - s * jy * r_, s * jx * p - p * jz * s, p * jy * r_ - r_ * jx * p)
    # hat(Omega) R^T R_d Omega_d = Omega x wd
    cross = (r_ * wd[2] - s * wd[1], s * wd[0] - p * wd[2], p * wd[1] - r_ * wd[0])
    inertia = (jx, jy, jz)
    for i in range(3):
        e_omega = rates[i] - wd[i]  # eq. (11)
        u = -gains[G_KR + i] * e_r[i] - gains[G_KOMEGA + i] * e_omega + gyro[i] - inertia[i] * cross[i]  # eq. (16)
        limit = gains[G_TORQUE_MAX + i]
        torque[i] = min(max(u, -limit), limit)


@cached_kernel
def geometric_inner_loop(
    physics: tuple,
    sensor_noise: np.ndarray,
    law: tuple,
    attitude_dt: float,
    thrust_n: float,
    apply_torque: bool,
    attitude_steps: int,
    physics_steps: int,
    saturated: np.ndarray,
) -> tuple[int, bool]:
    """The inner loop (sitl_quad.inner_loop's docstring) with the geometric attitude law; law = (gains array,
    target quaternion, feed-forward body rates). attitude_dt is unused: the law has no state."""
    gains, qd, feedforward = law
    measured = np.empty(STATE_SIZE)
    torque = np.empty(3)
    on_ground = physics[0][2] >= 0.0
    for k in range(attitude_steps):
        measure(physics, sensor_noise, k, measured)
        geometric_attitude_torque(gains, measured[6:10], measured[10:13], qd, feedforward, torque)
        finite, landed = fly_attitude_step(physics, k, physics_steps, thrust_n, torque, apply_torque, saturated)
        if not finite:
            return k, on_ground
        on_ground = landed
    return attitude_steps, on_ground


_NO_FEEDFORWARD = np.zeros(3)


def _floats(values) -> np.ndarray:
    return np.ascontiguousarray(values, dtype=np.float64)


class GeometricAttitudeController:
    """Implements uavcore.control.AttitudeController with eq. (16) (module docstring); a `CompiledAttitudeLoop`
    whose outer tick is one `geometric_inner_loop` call."""

    inner_loop = staticmethod(geometric_inner_loop)

    def __init__(self, gains: GeometricAttitudeGains) -> None:
        self.gains = gains
        self.kernel_gains = gains.as_array()

    @classmethod
    def for_airframe(
        cls, airframe: Airframe, omega_roll_pitch: float = 12.0, omega_yaw: float = 4.0, zeta: float = 1.0
    ) -> GeometricAttitudeController:
        return cls(GeometricAttitudeGains.for_bandwidth(airframe, omega_roll_pitch, omega_yaw, zeta))

    def reset(self) -> None:
        """Nothing to forget: the law has no state."""

    def kernel_arguments(self, target: AttitudeTarget) -> tuple:
        """`geometric_inner_loop`'s law for this target: (gains, quaternion, feed-forward body rates)."""
        qd = _floats(target.quaternion)
        feedforward = _NO_FEEDFORWARD if target.body_rates is None else _floats(target.body_rates)
        if qd.shape != (4,) or feedforward.shape != (3,):  # the kernel reads them unchecked
            raise ModelParameterError(f"an attitude target needs a quaternion of 4 and body rates of 3, got {target}")
        return self.kernel_gains, qd, feedforward

    def update(self, target: AttitudeTarget, state: VehicleState, dt: float) -> np.ndarray:
        """Body torque [roll, pitch, yaw] (N m) toward target from the measured state (dt unused)."""
        gains, qd, feedforward = self.kernel_arguments(target)
        torque = np.empty(3)
        geometric_attitude_torque(
            gains, _floats(state.quaternion), _floats(state.angular_velocity), qd, feedforward, torque
        )
        return torque
