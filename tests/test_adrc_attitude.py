"""The ADRC attitude loop on a plain rigid body (a test helper, not the package's simulator)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from adrc_offboard.adrc import AdrcParameterError
from adrc_offboard.adrc_attitude import AdrcAttitudeController, AdrcAttitudeGains
from uavcore.airframe import Airframe
from uavcore.rotation import euler_from_quat, quat_from_euler, quat_multiply, wrap_pi
from uavcore.state import AttitudeTarget, VehicleState

INERTIA = np.array([0.085, 0.083, 0.151])  # Table 2


class RigidBody:
    """Euler's equations + quaternion kinematics at 1 kHz, with an optional first-order torque lag."""

    def __init__(self, roll=0.0, pitch=0.0, yaw=0.0, lag: float = 0.0) -> None:
        self.q = quat_from_euler(roll, pitch, yaw)
        self.w = np.zeros(3)
        self.torque = np.zeros(3)
        self.lag = lag
        self.unwrapped_yaw = yaw

    def state(self) -> VehicleState:
        return VehicleState(quaternion=self.q.copy(), angular_velocity=self.w.copy())

    def advance(self, command: np.ndarray, seconds: float, disturbance_torque=(0.0, 0.0, 0.0)) -> None:
        h = 0.001
        for _ in range(round(seconds / h)):
            self.torque = command if self.lag == 0 else self.torque + (command - self.torque) * h / self.lag
            total = self.torque + np.asarray(disturbance_torque)
            self.w = self.w + h * (total - np.cross(self.w, INERTIA * self.w)) / INERTIA
            self.q = self.q + 0.5 * h * quat_multiply(self.q, np.array([0.0, *self.w]))
            self.q /= np.linalg.norm(self.q)
            self.unwrapped_yaw += h * self.w[2]  # level flight: yaw rate = body r

    @property
    def euler(self) -> tuple[float, float, float]:
        return euler_from_quat(self.q)


def fly(controller, body, target_euler, seconds, disturbance_torque=(0.0, 0.0, 0.0), record=None):
    target = AttitudeTarget(quaternion=quat_from_euler(*target_euler), thrust=0.5)
    dt = 0.004
    for _ in range(round(seconds / dt)):
        torque = controller.update(target, body.state(), dt)
        if record is not None:
            record.append((torque.copy(), body.euler, body.unwrapped_yaw))
        body.advance(torque, dt, disturbance_torque)


def attitude_error(body: RigidBody, target_euler) -> float:
    return max(abs(wrap_pi(a - b)) for a, b in zip(body.euler, target_euler, strict=True))


def test_reaches_a_combined_attitude_target() -> None:
    controller = AdrcAttitudeController(*INERTIA)
    body = RigidBody()
    target = (0.3, -0.2, 0.6)
    fly(controller, body, target, 6.0)
    assert attitude_error(body, target) < 1e-3


@pytest.mark.parametrize(("axis", "step"), [(0, 0.4), (1, -0.3), (2, 0.5)])
def test_a_single_axis_step_settles_without_overshoot(axis: int, step: float) -> None:
    controller = AdrcAttitudeController(*INERTIA)
    body = RigidBody()
    target = [0.0, 0.0, 0.0]
    target[axis] = step
    record: list = []
    fly(controller, body, target, 5.0, record=record)
    angles = np.array([r[1][axis] for r in record]) / step
    assert angles.max() < 1.02
    assert abs(angles[-1] - 1.0) < 1e-3


def test_yaw_takes_the_short_way_across_plus_minus_180_degrees() -> None:
    controller = AdrcAttitudeController(*INERTIA)
    start, goal = math.radians(179.0), math.radians(-179.0)
    body = RigidBody(yaw=start)
    record: list = []
    fly(controller, body, (0.0, 0.0, goal), 4.0, record=record)
    unwrapped = np.array([r[2] for r in record])
    # +2 degrees the short way; the long way would swing through 358 degrees the other way
    assert np.all(unwrapped > start - math.radians(0.5))
    assert np.all(unwrapped < start + math.radians(2.5))
    assert attitude_error(body, (0.0, 0.0, goal)) < math.radians(0.1)


def test_rejects_a_constant_disturbance_torque_and_estimates_it() -> None:
    controller = AdrcAttitudeController(*INERTIA)
    body = RigidBody()
    disturbance = (0.8, -0.5, 0.05)  # N m, like a gust's moment on the arms
    fly(controller, body, (0.0, 0.0, 0.0), 8.0, disturbance_torque=disturbance)
    assert attitude_error(body, (0.0, 0.0, 0.0)) < 1e-3
    estimates = controller.disturbance_estimates()
    for axis, torque, inertia in zip(("roll", "pitch", "yaw"), disturbance, INERTIA, strict=True):
        assert estimates[axis] == pytest.approx(torque / inertia, rel=0.02)  # z3 in rad/s^2, same sign


def test_actuator_lag_is_modelled_in_the_observer_input() -> None:
    # with the rotors' 20 ms lag, an observer fed the raw command sees a phantom disturbance during a step
    lag = 0.02
    peaks = {}
    for name, modelled_lag in (("aware", lag), ("unaware", 0.0)):
        controller = AdrcAttitudeController(*INERTIA, actuator_time_constant=modelled_lag)
        body = RigidBody(lag=lag)
        target = AttitudeTarget(quaternion=quat_from_euler(0.0, -0.3, 0.0), thrust=0.5)
        peak = 0.0
        for _ in range(500):
            body.advance(controller.update(target, body.state(), 0.004), 0.004)
            peak = max(peak, abs(controller.disturbance_estimates()["pitch"]))
        peaks[name] = peak
        assert abs(body.euler[1] + 0.3) < 1e-3
    assert peaks["aware"] < 0.2 * peaks["unaware"]


def test_torque_limits_are_respected_even_against_an_overwhelming_disturbance() -> None:
    gains = AdrcAttitudeGains.load()
    controller = AdrcAttitudeController(*INERTIA, gains=gains)
    limits = np.array([gains.roll["u_max"], gains.pitch["u_max"], gains.yaw["u_max"]])
    record: list = []
    fly(controller, RigidBody(), (0.6, -0.6, 3.0), 1.0, disturbance_torque=-1.5 * limits, record=record)
    torques = np.array([r[0] for r in record])
    assert np.all(np.abs(torques) <= limits + 1e-12)
    assert np.all(np.isclose(np.abs(torques[-10:]), limits))  # it does push with everything it has


def test_reset_forgets_the_observers_and_the_bookkeeping() -> None:
    controller = AdrcAttitudeController(*INERTIA)
    body = RigidBody()
    fly(controller, body, (0.0, 0.0, 0.0), 2.0, disturbance_torque=(0.5, 0.0, 0.0))
    assert abs(controller.disturbance_estimates()["roll"]) > 1.0
    controller.reset()
    fresh = AdrcAttitudeController(*INERTIA)
    state = RigidBody(roll=0.1).state()
    target = AttitudeTarget(quaternion=quat_from_euler(0.2, 0.0, 0.0), thrust=0.5)
    assert np.allclose(controller.update(target, state, 0.004), fresh.update(target, state, 0.004))


def test_for_airframe_takes_inertias_and_motor_lag_and_bad_values_are_refused() -> None:
    airframe = Airframe.table2()
    controller = AdrcAttitudeController.for_airframe(airframe)
    assert controller.actuator_time_constant == airframe.motor_time_constant == 0.02
    with pytest.raises(AdrcParameterError):
        AdrcAttitudeController(0.0, 0.083, 0.151)
    with pytest.raises(AdrcParameterError):
        AdrcAttitudeController(*INERTIA, rate_hz=-250.0)
    with pytest.raises(AdrcParameterError, match="unknown keys"):
        AdrcAttitudeGains.from_dict({"roll": {}, "pitch": {}, "yaw": {}, "rol": {}})
