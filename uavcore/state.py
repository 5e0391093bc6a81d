"""Plain data passed between the vehicle's parts: true state, setpoints and attitude targets.

Frames: world NED (x north, y east, z down, metres, origin at home), body FRD (x forward, y right, z down).
Attitude is a unit quaternion (w, x, y, z) rotating body vectors into the world frame; Euler angles are
ZYX (yaw psi, pitch theta, roll phi) and only reported, never integrated. The paper writes z up; here
z_down = -z_up, so its eq. (2) altitude channel appears with the sign flipped.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np


def _zeros3() -> np.ndarray:
    return np.zeros(3)


@dataclass
class VehicleState:
    """The rigid body's state at simulated time t (seconds)."""

    t: float = 0.0
    position: np.ndarray = field(default_factory=_zeros3)  # NED, m
    velocity: np.ndarray = field(default_factory=_zeros3)  # NED, m/s
    quaternion: np.ndarray = field(default_factory=lambda: np.array([1.0, 0.0, 0.0, 0.0]))  # w, x, y, z
    angular_velocity: np.ndarray = field(default_factory=_zeros3)  # body FRD, rad/s (p, q, r)
    rotor_speeds: np.ndarray = field(default_factory=lambda: np.zeros(4))  # rad/s


@dataclass
class TrajectorySetpoint:
    """What the navigator asks the position loop to follow (POSITION_TARGET_LOCAL_NED)."""

    position: np.ndarray  # NED, m
    velocity: np.ndarray = field(default_factory=_zeros3)  # NED, m/s (feed-forward)
    acceleration: np.ndarray = field(default_factory=_zeros3)  # NED, m/s^2 (feed-forward)
    yaw: float = 0.0  # rad, from north, clockwise positive
    yaw_rate: float = 0.0  # rad/s


@dataclass
class AttitudeTarget:
    """What the position loop asks the attitude loop for (SET_ATTITUDE_TARGET)."""

    quaternion: np.ndarray  # w, x, y, z, body -> world
    thrust: float  # normalised collective thrust, 0..1 of the airframe's maximum
    body_rates: np.ndarray | None = None  # rad/s feed-forward, None when ignored
