"""Sensor noise: what the vehicle's estimator would report instead of the true state.

White Gaussian noise, fresh at every measurement: position and velocity per NED axis, attitude as a small
random rotation (body-frame rotation vector, std per axis) applied to the true quaternion, gyro per body axis.
Defaults are a good GNSS/vision-aided estimate (2 cm, 5 cm/s, 0.3 deg, 0.01 rad/s); ``SensorNoise.none()``
reports the truth.

Measurement delay (`delay_s`, default 0): the state estimate the outer loops see (the vehicle's estimate at
each outer tick: the built-in position loop, the navigator, the offboard controller's telemetry) is the
measurement taken delay_s earlier, rounded to whole outer-loop ticks (`MeasurementDelay`); the attitude loop's
own attitude and gyro measurements at 250 Hz are not delayed. Until delay_s has passed, the first measurement
is repeated.

The noise is applied by the kernel ``add_sensor_noise`` on the simulator's flat state layout
(sitl_quad.rigid_body), so the vehicle's compiled inner loop measures with the same code; the unit normals
come from one seeded stream, 12 per measurement in order, however they are drawn.
"""

from __future__ import annotations

import dataclasses
import math
from collections import deque
from dataclasses import dataclass

import numpy as np

from sitl_quad.normal_stream import NormalStream, Zeros
from uavcore.airframe import ModelParameterError
from uavcore.kernel_cache import cached_kernel
from uavcore.quaternion_kernels import quat_product
from uavcore.state import VehicleState

NOISE_PER_MEASUREMENT = 12  # position, velocity, attitude rotation vector, gyro: 3 each


@dataclass(frozen=True)
class SensorNoise:
    """Standard deviations of the measurement noise."""

    position_std_m: float = 0.02
    velocity_std_m_s: float = 0.05
    attitude_std_rad: float = 0.005
    gyro_std_rad_s: float = 0.01
    delay_s: float = 0.0  # the outer loops' estimate lags the truth by this, in whole outer ticks

    def __post_init__(self) -> None:
        for f in dataclasses.fields(self):
            value = getattr(self, f.name)
            if not isinstance(value, int | float) or not math.isfinite(value) or value < 0:
                raise ModelParameterError(f"sensor noise {f.name} must be finite and >= 0, got {value!r}")

    @classmethod
    def none(cls) -> SensorNoise:
        return cls(0.0, 0.0, 0.0, 0.0)


@cached_kernel
def add_sensor_noise(truth: np.ndarray, noise: np.ndarray, measured: np.ndarray) -> None:
    """Write into measured the flat state truth (rigid_body layout) with noise added. noise holds position
    [0:3], velocity [3:6], the attitude error as a body rotation vector [6:9] and gyro [9:12]; rotor speeds
    pass unchanged."""
    for i in range(6):
        measured[i] = truth[i] + noise[i]
    rx, ry, rz = noise[6], noise[7], noise[8]
    angle = math.sqrt(rx * rx + ry * ry + rz * rz)
    q = (truth[6], truth[7], truth[8], truth[9])
    if angle > 0.0:
        s = math.sin(0.5 * angle) / angle
        q = quat_product(q, (math.cos(0.5 * angle), rx * s, ry * s, rz * s))
    for i in range(4):
        measured[6 + i] = q[i]
    for i in range(3):
        measured[10 + i] = truth[10 + i] + noise[9 + i]
    for i in range(13, 17):
        measured[i] = truth[i]


class Sensors:
    """Adds SensorNoise to a true VehicleState; seeded, 12 normals per measurement (none if noise is off)."""

    def __init__(self, config: SensorNoise | None = None, seed: int | np.random.Generator = 0) -> None:
        self.config = config or SensorNoise.none()
        self.rng = seed if isinstance(seed, np.random.Generator) else np.random.default_rng(seed)
        c = self.config
        self._std = np.repeat([c.position_std_m, c.velocity_std_m_s, c.attitude_std_rad, c.gyro_std_rad_s], 3)
        self.active = bool(np.any(self._std > 0))
        self._normals = NormalStream(self.rng, NOISE_PER_MEASUREMENT)
        self._zeros = Zeros(NOISE_PER_MEASUREMENT)

    def reconfigured(self, config: SensorNoise) -> Sensors:
        """Sensors with a new configuration that go on with this one's random stream where it stands."""
        sensors = Sensors(config, self.rng)
        sensors._normals = self._normals
        return sensors

    def noise(self, measurements: int) -> np.ndarray:
        """The noise of the next `measurements` measurements, (measurements, 12) as add_sensor_noise takes it
        (zeros, and no draw, when the noise is off)."""
        if not self.active:
            return self._zeros.take(measurements)
        return self._normals.take(measurements) * self._std

    def measure(self, state: VehicleState) -> VehicleState:
        """A noisy copy of state (the input is not modified)."""
        truth = np.concatenate(
            [state.position, state.velocity, state.quaternion, state.angular_velocity, state.rotor_speeds]
        ).astype(np.float64, copy=False)
        return self.measure_flat(truth, state.t)

    def measure_flat(self, truth: np.ndarray, t: float) -> VehicleState:
        """A noisy copy of the flat state truth (rigid_body layout) at time t, as measure() gives."""
        measured = np.array(truth, dtype=np.float64)
        if self.active:
            add_sensor_noise(truth, self.noise(1)[0], measured)
        return VehicleState(
            t=t,
            position=measured[0:3],
            velocity=measured[3:6],
            quaternion=measured[6:10],
            angular_velocity=measured[10:13],
            rotor_speeds=measured[13:17],
        )


class MeasurementDelay:
    """A FIFO of `ticks` outer-loop measurements: `push(now)` returns the one taken `ticks` ticks earlier (the
    oldest one held until that many have been pushed); ticks 0 returns `now`."""

    def __init__(self, ticks: int) -> None:
        if ticks < 0:
            raise ModelParameterError(f"measurement delay must be >= 0 ticks, got {ticks}")
        self.ticks = ticks
        self._held: deque[VehicleState] = deque(maxlen=ticks + 1)

    @classmethod
    def for_config(cls, config: SensorNoise, outer_dt: float) -> MeasurementDelay:
        return cls(round(config.delay_s / outer_dt))

    def push(self, measured: VehicleState) -> VehicleState:
        if self.ticks == 0:
            return measured
        self._held.append(measured)
        return self._held[0]
