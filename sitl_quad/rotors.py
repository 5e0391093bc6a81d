"""Rotor layout, the paper's mixing (eq. 3) and its inverse, the mixer.

Where each rotor is follows from the signs of eq. (3) read in body FRD axes (x forward, y right, z down;
positive roll = right side down, positive pitch = nose up, positive yaw = nose right):

    rotor 1 front-left   spins CCW seen from above      U2 = kl(O1^2 + O2^2 - O3^2 - O4^2): left lifts -> +roll
    rotor 2 rear-left    spins CW                        U3 = kl(O1^2 - O2^2 - O3^2 + O4^2): front lifts -> +pitch
    rotor 3 rear-right   spins CCW                       U4 = kf(O1^2 - O2^2 + O3^2 - O4^2): a CCW rotor's drag
    rotor 4 front-right  spins CW                             torque turns the body CW from above -> +yaw

Body torques are [L U2, L U3, L U4] (eq. 1). The paper applies the full arm L to roll and pitch (rotors L from
each axis, an X frame) and also multiplies the yaw term by L (eq. 1 writes L U4 / Iz although a rotor's drag
torque does not depend on the arm); we follow the paper, so kf here is effectively a drag-torque coefficient
of L * kf = 3.7e-7 N m s^2.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

from uavcore.airframe import P_ARM, P_KF, P_KL, P_OMEGA_MAX, P_OMEGA_MIN, Airframe, ModelParameterError
from uavcore.kernel_cache import cached_kernel


@cached_kernel
def rotor_wrench(omega: np.ndarray, params: np.ndarray) -> tuple[float, float, float, float]:
    """Collective thrust U1 (N, along body -z) and body torques (N m) of the rotor speeds, eq. (1) and (3)."""
    s1, s2, s3, s4 = omega[0] ** 2, omega[1] ** 2, omega[2] ** 2, omega[3] ** 2
    kl, kf, arm = params[P_KL], params[P_KF], params[P_ARM]
    thrust = kl * (s1 + s2 + s3 + s4)
    roll = arm * kl * (s1 + s2 - s3 - s4)
    pitch = arm * kl * (s1 - s2 - s3 + s4)
    yaw = arm * kf * (s1 - s2 + s3 - s4)
    return thrust, roll, pitch, yaw


@cached_kernel
def mix(thrust_n: float, tx: float, ty: float, tz: float, params: np.ndarray, omega: np.ndarray) -> bool:
    """Write into omega the rotor speeds (rad/s) for collective thrust (N) and body torque (N m): the
    inverse of eq. (3) with Mixer's saturation priorities. Returns whether the request had to be changed."""
    kl, kf, arm = params[P_KL], params[P_KF], params[P_ARM]
    s_min, s_max = params[P_OMEGA_MIN] ** 2, params[P_OMEGA_MAX] ** 2
    # Per-rotor squared speeds of each input, from solving eq. (3) for Omega_i^2.
    a = thrust_n / kl / 4.0
    b = tx / (arm * kl) / 4.0
    c = ty / (arm * kl) / 4.0
    d = tz / (arm * kf) / 4.0
    roll_pitch = np.array([b + c, b - c, -b - c, -b + c])
    yaw = (d, -d, d, -d)
    saturated = False

    span = roll_pitch.max() - roll_pitch.min()
    if span > s_max - s_min:
        roll_pitch *= (s_max - s_min) / span
        saturated = True
    lowest, highest = s_min - roll_pitch.min(), s_max - roll_pitch.max()
    collective = min(max(a, lowest), highest)
    if collective != a:
        saturated = True
    squared = collective + roll_pitch

    yaw_scale = 1.0
    for i in range(4):
        if yaw[i] > 0.0:
            yaw_scale = min(yaw_scale, (s_max - squared[i]) / yaw[i])
        elif yaw[i] < 0.0:
            yaw_scale = min(yaw_scale, (s_min - squared[i]) / yaw[i])
    yaw_scale = max(yaw_scale, 0.0)
    if yaw_scale < 1.0:
        saturated = True
    for i in range(4):
        omega[i] = math.sqrt(max(squared[i] + yaw_scale * yaw[i], 0.0))
    return saturated


class Mixer:
    """Collective thrust + body torque -> four rotor-speed commands, the inverse of eq. (3).

    When the request does not fit in [rotor_speed_min, rotor_speed_max], roll and pitch are kept first
    (scaled down together only if they alone exceed the range), then collective thrust is shifted as little as
    possible, and yaw gets whatever room is left (PX4's priority: attitude over altitude over heading).
    ``saturated`` tells whether the last command had to be changed; ``saturated_steps`` counts such calls.
    The law is the kernel ``mix`` (also called by the vehicle's compiled inner loop, which reports its calls
    through ``record``).
    """

    def __init__(self, airframe: Airframe) -> None:
        self.airframe = airframe
        self.params = airframe.as_array()
        self.saturated = False
        self.saturated_steps = 0
        self.calls = 0

    def rotor_commands(self, thrust_n: float, torque_body) -> np.ndarray:
        """Rotor speeds (rad/s) for collective thrust thrust_n (N) and body torque [roll, pitch, yaw] (N m)."""
        tx, ty, tz = (float(c) for c in torque_body)
        thrust_n = float(thrust_n)
        if not all(math.isfinite(v) for v in (thrust_n, tx, ty, tz)):
            raise ModelParameterError(f"mixer input must be finite, got thrust {thrust_n}, torque {torque_body}")
        omega = np.empty(4)
        self.record((mix(thrust_n, tx, ty, tz, self.params, omega),))
        return omega

    def record(self, saturated: Sequence[bool] | np.ndarray) -> None:
        """Count calls of the kernel ``mix`` made for this mixer, in call order, each flagged whether it
        saturated."""
        calls = len(saturated)
        if calls:
            self.saturated = bool(saturated[-1])
            self.calls += calls
            self.saturated_steps += int(np.count_nonzero(saturated))
