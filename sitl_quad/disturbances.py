"""The paper's external disturbance terms D_x, D_y, D_z, D_phi, D_theta, D_psi (eq. 1-2).

Section VI models "the total noise" as zero-mean white Gaussian noise sampled every 0.5 s with variance 15,
held between samples. Here each channel has its own variance; a sample is drawn every ``sample_time_s`` and
held (zero-order hold). Units: D_x, D_y, D_z are accelerations in world NED (m/s^2; D_z is positive down,
the paper's z is up), D_phi, D_theta, D_psi are angular accelerations (rad/s^2) added to the body rates' time
derivatives (the paper adds them to the Euler angles' second derivatives; the two agree near level flight).

Defaults are deliberately milder than the paper: variance 15 m^2/s^4 means a random push of about 0.4 g held
for half a second, which no real quadrotor meets in the air. The default 0.05 m^2/s^4 (std 0.22 m/s^2) and
0.05 rad^2/s^4 (std 0.22 rad/s^2, a fifth of the yaw authority at hover) are the size of unmodelled
aerodynamics and vibration; use ``DisturbanceConfig.paper()`` to reproduce Section VI.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

import numpy as np

from sitl_quad.normal_stream import NormalStream, Zeros
from uavcore.airframe import ModelParameterError

CHANNELS = ("x", "y", "z", "roll", "pitch", "yaw")


@dataclass(frozen=True)
class DisturbanceConfig:
    """Variance per channel ((m/s^2)^2 for x, y, z; (rad/s^2)^2 for roll, pitch, yaw) and the hold time."""

    variance_x: float = 0.05
    variance_y: float = 0.05
    variance_z: float = 0.05
    variance_roll: float = 0.05
    variance_pitch: float = 0.05
    variance_yaw: float = 0.05
    sample_time_s: float = 0.5

    def __post_init__(self) -> None:
        for f in dataclasses.fields(self):
            value = getattr(self, f.name)
            if not isinstance(value, int | float) or not math.isfinite(value) or value < 0:
                raise ModelParameterError(f"disturbance parameter {f.name} must be finite and >= 0, got {value!r}")
        if self.sample_time_s <= 0:
            raise ModelParameterError(f"sample_time_s must be positive, got {self.sample_time_s}")

    @classmethod
    def paper(cls) -> DisturbanceConfig:
        """Section VI: variance 15 on every channel, sampled every 0.5 s."""
        return cls(15.0, 15.0, 15.0, 15.0, 15.0, 15.0, 0.5)

    @classmethod
    def none(cls) -> DisturbanceConfig:
        return cls(0.0, 0.0, 0.0, 0.0, 0.0, 0.0)

    def std(self) -> np.ndarray:
        return np.sqrt([getattr(self, f"variance_{c}") for c in CHANNELS])


class GaussianDisturbance:
    """Zero-order-held Gaussian samples; sample k holds over [k T, (k + 1) T), drawn in order from the seed."""

    def __init__(self, config: DisturbanceConfig | None = None, seed: int | np.random.Generator = 0) -> None:
        self.config = config or DisturbanceConfig()
        self.rng = seed if isinstance(seed, np.random.Generator) else np.random.default_rng(seed)
        self._std = self.config.std()
        self.active = bool(np.any(self._std > 0))
        self._index = -1
        self._current = np.zeros(6)
        self._normals = NormalStream(self.rng, 6)
        self._zeros = Zeros(6)

    def draw(self, count: int) -> np.ndarray:
        """The next `count` samples, (count, 6) [D_x, D_y, D_z, D_phi, D_theta, D_psi]."""
        if not self.active:
            return self._zeros.take(count)
        return self._normals.take(count) * self._std

    def value(self, t: float) -> np.ndarray:
        """The disturbance held at time t (t must not go backwards past a sample)."""
        index = math.floor(t / self.config.sample_time_s + 1e-9)
        if index < self._index:
            raise ModelParameterError(f"disturbance time went backwards to {t}")
        if index > self._index:
            self._current = self.draw(index - self._index)[-1]
            self._index = index
        return self._current.copy()
