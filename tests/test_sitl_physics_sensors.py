"""Sensor noise: the configured standard deviations, unit quaternions, truth when off, seeded."""

from __future__ import annotations

import math

import numpy as np
import pytest

from sitl_quad.sensors import SensorNoise, Sensors
from uavcore.airframe import ModelParameterError
from uavcore.rotation import quat_conjugate, quat_from_euler, quat_multiply
from uavcore.state import VehicleState

TRUTH = VehicleState(
    t=1.0,
    position=np.array([1.0, 2.0, -3.0]),
    velocity=np.array([4.0, -1.0, 0.5]),
    quaternion=quat_from_euler(0.1, -0.2, 2.5),
    angular_velocity=np.array([0.3, 0.0, -0.1]),
    rotor_speeds=np.full(4, 330.0),
)


def test_measurements_have_the_configured_noise():
    noise = SensorNoise(position_std_m=0.1, velocity_std_m_s=0.2, attitude_std_rad=0.01, gyro_std_rad_s=0.05)
    sensors = Sensors(noise, seed=3)
    samples = [sensors.measure(TRUTH) for _ in range(4000)]
    position = np.array([s.position for s in samples]) - TRUTH.position
    velocity = np.array([s.velocity for s in samples]) - TRUTH.velocity
    gyro = np.array([s.angular_velocity for s in samples]) - TRUTH.angular_velocity
    np.testing.assert_allclose(position.std(axis=0), 0.1, rtol=0.06)
    np.testing.assert_allclose(velocity.std(axis=0), 0.2, rtol=0.06)
    np.testing.assert_allclose(gyro.std(axis=0), 0.05, rtol=0.06)
    # attitude error: the small rotation between truth and measurement, per body axis
    errors = []
    for s in samples:
        assert np.linalg.norm(s.quaternion) == pytest.approx(1.0)
        e = quat_multiply(quat_conjugate(TRUTH.quaternion), s.quaternion)
        errors.append(2.0 * np.sign(e[0]) * e[1:])
    np.testing.assert_allclose(np.array(errors).std(axis=0), 0.01, rtol=0.06)
    assert all(s.t == TRUTH.t for s in samples)


def test_no_noise_returns_an_independent_copy_of_the_truth():
    measured = Sensors(SensorNoise.none()).measure(TRUTH)
    np.testing.assert_array_equal(measured.position, TRUTH.position)
    measured.position[0] = 99.0
    assert TRUTH.position[0] == 1.0


def test_sensor_noise_is_seeded_and_validated():
    a = Sensors(SensorNoise(), seed=8).measure(TRUTH)
    b = Sensors(SensorNoise(), seed=8).measure(TRUTH)
    np.testing.assert_array_equal(a.position, b.position)
    with pytest.raises(ModelParameterError):
        SensorNoise(position_std_m=-1.0)
    with pytest.raises(ModelParameterError):
        SensorNoise(gyro_std_rad_s=math.inf)
