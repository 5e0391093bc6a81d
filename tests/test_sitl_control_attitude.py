"""The PX4-style PID attitude loop on the simulated body: steps in roll, pitch and yaw, and integral action."""

from __future__ import annotations

import math

import numpy as np
import pytest

from sitl_quad.attitude_pid import PidAttitudeController, PidAttitudeGains, attitude_rate_setpoint_kernel
from sitl_quad.rotors import Mixer
from sitl_quad.simulator import Simulator
from uavcore.airframe import Airframe, ModelParameterError
from uavcore.control import AttitudeController
from uavcore.rotation import euler_from_quat, quat_from_euler, quat_multiply
from uavcore.state import AttitudeTarget

AIRFRAME = Airframe.table2()


def hold_attitude(target: AttitudeTarget, seconds: float, torque_offset=(0.0, 0.0, 0.0)):
    """Run the 250 Hz attitude loop + mixer on a body high in the air; returns (times, euler angles)."""
    sim = Simulator(AIRFRAME, position=(0.0, 0.0, -500.0), rotor_speed=AIRFRAME.hover_rotor_speed)
    controller: AttitudeController = PidAttitudeController()
    mixer = Mixer(AIRFRAME)
    times, angles = [], []
    for _ in range(round(seconds * 250)):
        torque = controller.update(target, sim.measure(), 0.004) + torque_offset
        sim.set_rotor_commands(mixer.rotor_commands(target.thrust * AIRFRAME.max_thrust_n, torque))
        sim.step(4)
        times.append(sim.t)
        angles.append(euler_from_quat(sim.state.quaternion))
    return np.array(times), np.degrees(np.array(angles))


@pytest.mark.parametrize("axis", [0, 1])
def test_roll_and_pitch_steps_settle_fast_without_large_overshoot(axis):
    euler = [0.0, 0.0, 0.0]
    euler[axis] = math.radians(20.0)
    target = AttitudeTarget(quaternion=quat_from_euler(*euler), thrust=AIRFRAME.hover_thrust)
    times, angles = hold_attitude(target, 1.5)
    response = angles[:, axis]
    assert response.max() < 20.0 * 1.15  # overshoot under 15 %
    rise = times[np.argmax(response > 18.0)]
    assert rise < 0.5
    assert np.all(np.abs(response[times > 0.8] - 20.0) < 0.5)
    assert np.all(np.abs(angles[:, 1 - axis]) < 1.0)


def test_yaw_step_settles_and_tilt_stays_level():
    target = AttitudeTarget(quaternion=quat_from_euler(0.0, 0.0, math.radians(90.0)), thrust=AIRFRAME.hover_thrust)
    times, angles = hold_attitude(target, 6.0)
    assert np.all(np.abs(angles[times > 4.0, 2] - 90.0) < 2.0)
    assert angles[:, 2].max() < 100.0
    assert np.all(np.abs(angles[:, :2]) < 1.0)


def test_integrator_removes_a_constant_torque_disturbance():
    target = AttitudeTarget(quaternion=np.array([1.0, 0.0, 0.0, 0.0]), thrust=AIRFRAME.hover_thrust)
    times, angles = hold_attitude(target, 6.0, torque_offset=np.array([0.3, -0.2, 0.0]))
    assert np.abs(angles[times < 1.0, 0]).max() > 0.3  # the disturbance did push
    assert np.all(np.abs(angles[times > 4.0, :2]) < 0.1)


def rate_setpoint(target_quaternion, q, feedforward=(0.0, 0.0, 0.0)) -> tuple[float, float, float]:
    """The attitude stage's body-rate setpoint (rad/s) with the default gains: the kernel the loop runs."""
    gains = PidAttitudeGains().as_array()
    return attitude_rate_setpoint_kernel(
        gains, *(np.asarray(v, dtype=float) for v in (q, target_quaternion, feedforward))
    )


def test_error_uses_the_shorter_way_round_and_body_rate_feed_forward():
    q = np.array([1.0, 0.0, 0.0, 0.0])
    # the same attitude with the quaternion's sign flipped needs no correction
    assert np.allclose(rate_setpoint(-quat_from_euler(0.0, 0.0, 0.0), q), 0.0)
    assert np.allclose(rate_setpoint(q, q), 0.0)
    # 10 deg yaw to the right -> positive yaw rate; feed-forward adds on top
    right = quat_multiply(q, quat_from_euler(0.0, 0.0, math.radians(10.0)))
    rate = rate_setpoint(right, q)
    assert rate[2] > 0 and abs(rate[0]) < 1e-9 and abs(rate[1]) < 1e-9
    fed = rate_setpoint(q, q, feedforward=(0.0, 0.0, 0.4))
    assert fed[2] == pytest.approx(0.4)


def test_gains_are_validated():
    with pytest.raises(ModelParameterError):
        PidAttitudeGains(mc_roll_p=-1.0)
    with pytest.raises(ModelParameterError):
        PidAttitudeController().update(AttitudeTarget(np.array([1.0, 0, 0, 0]), 0.5), Simulator().state, 0.0)
