"""The attitude loops a vehicle can fly, by MC_ATT_CTRL: its own PX4-style PID and the paper's ADRC.

Whoever builds a `Vehicle` (the vehicle process, the lockstep harness's users, benchmarks, tests) injects
these factories, as RotorPy injects controllers into its environment, so the vehicle module itself imports
no controller package. The ADRC loop is `adrc_offboard`'s control core (eq. 9-13 serving as the cascade's
inner loop); the PID is the vehicle's built-in one.

The ADRC loop flies each outer tick in one compiled call, as the PID does (sitl_quad.inner_loop): `adrc_inner_loop`
orders the same kernels FlightLoop.fly() calls step by step (measure, the ADRC's `adrc_attitude_torque`, mix and
physics), and `CompiledAdrcAttitudeLoop` hands it to the flight loop. numba's cache does not see edits to
adrc_offboard's kernels: after one, delete sitl_quad/__pycache__/*.nbi.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from adrc_offboard.adrc_attitude import AdrcAttitudeController, adrc_attitude_torque
from sitl_quad.config import AttitudeControllerKind, VehicleConfig
from sitl_quad.inner_loop import fly_attitude_step, measure
from sitl_quad.rigid_body import STATE_SIZE
from sitl_quad.vehicle import AttitudeLoopFactory, builtin_pid_loop
from uavcore.control import AttitudeController


@njit(cache=True)
def adrc_inner_loop(
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
    """The inner loop (sitl_quad.inner_loop's docstring) with the ADRC attitude law; law = the controller's
    arguments to adrc_attitude_torque (AdrcAttitudeController.kernel_arguments), the target quaternion and its
    feed-forward body rates."""
    controller, qd, feedforward = law
    channel_params, channel_states, loop_state, actuator_step, use_measured_rate = controller
    measured = np.empty(STATE_SIZE)
    torque = np.empty(3)
    on_ground = physics[0][2] >= 0.0
    for k in range(attitude_steps):
        measure(physics, sensor_noise, k, measured)
        adrc_attitude_torque(
            channel_params,
            channel_states,
            loop_state,
            actuator_step,
            use_measured_rate,
            measured[6:10],
            measured[10:13],
            qd,
            feedforward,
            attitude_dt,
            torque,
        )
        finite, landed = fly_attitude_step(physics, k, physics_steps, thrust_n, torque, apply_torque, saturated)
        if not finite:
            return k, on_ground
        on_ground = landed
    return attitude_steps, on_ground


class CompiledAdrcAttitudeLoop(AdrcAttitudeController):
    """The ADRC attitude controller with its outer tick as one compiled call (a `CompiledAttitudeLoop`): its
    kernel_arguments(target) are `adrc_inner_loop`'s law."""

    inner_loop = staticmethod(adrc_inner_loop)


def adrc_attitude_loop(config: VehicleConfig, rate_hz: float) -> AttitudeController:
    """The paper's ADRC attitude loop for the airframe the controllers are designed for (config.controller_airframe:
    the true one unless a design airframe is set), its observers modelling the motor lag."""
    return CompiledAdrcAttitudeLoop.for_airframe(config.controller_airframe, rate_hz=rate_hz)


def attitude_loops() -> dict[AttitudeControllerKind, AttitudeLoopFactory]:
    """Every attitude loop MC_ATT_CTRL can select."""
    return {AttitudeControllerKind.PID: builtin_pid_loop, AttitudeControllerKind.ADRC: adrc_attitude_loop}
