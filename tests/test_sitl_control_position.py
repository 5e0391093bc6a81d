"""The PX4-style position loop on its own: equilibrium thrust, limits, NaN conventions, anti-windup."""

from __future__ import annotations

import math

import numpy as np
import pytest

from sitl_quad.position_control import PidPositionController, PidPositionGains
from uavcore.airframe import Airframe, ModelParameterError
from uavcore.rotation import euler_from_quat, quat_from_euler, rotate
from uavcore.state import TrajectorySetpoint, VehicleState

AIRFRAME = Airframe.table2()


def at(position, velocity=(0.0, 0.0, 0.0), yaw: float = 0.0) -> VehicleState:
    return VehicleState(
        position=np.array(position, dtype=float),
        velocity=np.array(velocity, dtype=float),
        quaternion=quat_from_euler(0.0, 0.0, yaw),
    )


def tilt_deg(quaternion) -> float:
    down = rotate(quaternion, (0.0, 0.0, 1.0))
    return math.degrees(math.acos(min(1.0, float(down[2]))))


def test_on_the_setpoint_it_asks_for_hover_thrust_level():
    controller = PidPositionController(AIRFRAME)
    target = controller.update(
        TrajectorySetpoint(position=np.array([1.0, 2.0, -5.0]), yaw=0.4), at([1.0, 2.0, -5.0]), 0.02
    )
    assert target.thrust == pytest.approx(AIRFRAME.hover_thrust)
    roll, pitch, yaw = euler_from_quat(target.quaternion)
    assert abs(roll) < 1e-12 and abs(pitch) < 1e-12 and yaw == pytest.approx(0.4)


def test_far_setpoints_respect_velocity_acceleration_and_tilt_limits():
    gains = PidPositionGains()
    controller = PidPositionController(AIRFRAME, gains)
    target = controller.update(TrajectorySetpoint(position=np.array([500.0, 500.0, -100.0])), at([0, 0, -5]), 0.02)
    assert np.hypot(*controller.velocity_setpoint[:2]) == pytest.approx(gains.mpc_xy_vel_max)
    assert controller.velocity_setpoint[2] == pytest.approx(-gains.mpc_z_vel_max_up)
    assert np.hypot(*controller.acceleration_setpoint[:2]) <= gains.mpc_acc_hor_max + 1e-9
    assert tilt_deg(target.quaternion) <= gains.mpc_tiltmax_air + 1e-6
    # pitched toward north-east: nose down (negative pitch) after rotating to yaw 0
    assert euler_from_quat(target.quaternion)[1] < 0 and euler_from_quat(target.quaternion)[0] > 0
    controller.update(TrajectorySetpoint(position=np.array([0.0, 0.0, 100.0])), at([0, 0, -5]), 0.02)
    assert controller.velocity_setpoint[2] == pytest.approx(gains.mpc_z_vel_max_dn)


def test_nan_position_means_velocity_control_and_nan_yaw_keeps_heading():
    controller = PidPositionController(AIRFRAME)
    setpoint = TrajectorySetpoint(
        position=np.array([math.nan, 0.0, math.nan]),
        velocity=np.array([2.0, 0.0, 1.0]),
        acceleration=np.array([math.nan, 0.0, 0.0]),
        yaw=math.nan,
    )
    target = controller.update(setpoint, at([50.0, 0.0, -5.0], yaw=1.2), 0.02)
    np.testing.assert_allclose(controller.velocity_setpoint, [2.0, 0.0, 1.0])
    # heading kept: the body x axis projected on the horizontal plane points along yaw 1.2 (the convention of
    # acceleration_to_attitude, PX4's), whatever the tilt
    forward = rotate(target.quaternion, (1.0, 0.0, 0.0))
    assert float(forward @ [-math.sin(1.2), math.cos(1.2), 0.0]) == pytest.approx(0.0, abs=1e-12)
    assert float(forward @ [math.cos(1.2), math.sin(1.2), 0.0]) > 0.0
    assert np.all(np.isfinite(target.quaternion)) and math.isfinite(target.thrust)


def test_integrator_is_clamped_and_frozen_while_saturated():
    gains = PidPositionGains()
    controller = PidPositionController(AIRFRAME, gains)
    far = TrajectorySetpoint(position=np.array([1000.0, 0.0, -5.0]))
    for _ in range(5000):  # 100 s stuck far away: horizontal acceleration limited throughout
        controller.update(far, at([0.0, 0.0, -5.0]), 0.02)
    assert np.hypot(*controller.integral[:2]) == 0.0
    slow = TrajectorySetpoint(position=np.array([0.0, 0.0, -5.0]), velocity=np.array([1.0, 0.0, 0.0]))
    for _ in range(5000):  # a small steady velocity error: integrates up to the clamp
        controller.update(slow, at([0.0, 0.0, -5.0]), 0.02)
    assert np.hypot(*controller.integral[:2]) == pytest.approx(gains.integrator_limit_xy)
    controller.reset()
    assert np.all(controller.integral == 0.0)


def test_gains_are_validated():
    with pytest.raises(ModelParameterError):
        PidPositionGains(mpc_xy_p=-1.0)
    with pytest.raises(ModelParameterError):
        PidPositionGains(mpc_tiltmax_air=95.0)
    with pytest.raises(ModelParameterError):
        PidPositionController(AIRFRAME).update(TrajectorySetpoint(position=np.zeros(3)), at([0, 0, 0]), 0.0)
