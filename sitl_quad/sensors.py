"""Sensor noise: what the vehicle's estimator would report instead of the true state.

White Gaussian noise, fresh at every measurement: position and velocity per NED axis, attitude as a small
random rotation (body-frame rotation vector, std per axis) applied to the true quaternion, gyro per body axis.
Defaults are a good GNSS/vision-aided estimate (2 cm, 5 cm/s, 0.3 deg, 0.01 rad/s); ``SensorNoise.none()``
reports the truth.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

import numpy as np

from sitl_quad.airframe import ModelParameterError
from sitl_quad.rotation import quat_multiply
from sitl_quad.state import VehicleState


@dataclass(frozen=True)
class SensorNoise:
    """Standard deviations of the measurement noise."""

    position_std_m: float = 0.02
    velocity_std_m_s: float = 0.05
    attitude_std_rad: float = 0.005
    gyro_std_rad_s: float = 0.01

    def __post_init__(self) -> None:
        for f in dataclasses.fields(self):
            value = getattr(self, f.name)
            if not isinstance(value, int | float) or not math.isfinite(value) or value < 0:
                raise ModelParameterError(f"sensor noise {f.name} must be finite and >= 0, got {value!r}")

    @classmethod
    def none(cls) -> SensorNoise:
        return cls(0.0, 0.0, 0.0, 0.0)


class Sensors:
    """Adds SensorNoise to a true VehicleState; seeded, one draw of 12 normals per measurement."""

    def __init__(self, config: SensorNoise | None = None, seed: int | np.random.Generator = 0) -> None:
        self.config = config or SensorNoise.none()
        self.rng = seed if isinstance(seed, np.random.Generator) else np.random.default_rng(seed)
        c = self.config
        self._std = np.repeat([c.position_std_m, c.velocity_std_m_s, c.attitude_std_rad, c.gyro_std_rad_s], 3)
        self.active = bool(np.any(self._std > 0))

    def measure(self, state: VehicleState) -> VehicleState:
        """A noisy copy of state (the input is not modified)."""
        if not self.active:
            return dataclasses.replace(
                state, position=state.position.copy(), velocity=state.velocity.copy(),
                quaternion=state.quaternion.copy(), angular_velocity=state.angular_velocity.copy(),
                rotor_speeds=state.rotor_speeds.copy(),
            )
        noise = (self.rng.standard_normal(12) * self._std).tolist()
        rx, ry, rz = noise[6:9]
        angle = math.sqrt(rx * rx + ry * ry + rz * rz)
        if angle > 0.0:
            s = math.sin(0.5 * angle) / angle
            quaternion = quat_multiply(state.quaternion.tolist(), (math.cos(0.5 * angle), rx * s, ry * s, rz * s))
        else:
            quaternion = state.quaternion.copy()
        return VehicleState(
            t=state.t,
            position=state.position + noise[0:3],
            velocity=state.velocity + noise[3:6],
            quaternion=quaternion,
            angular_velocity=state.angular_velocity + noise[9:12],
            rotor_speeds=state.rotor_speeds.copy(),
        )
