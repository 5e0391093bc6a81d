"""The attitude loops a vehicle can fly, by MC_ATT_CTRL: its own PX4-style PID, the ADRC and the geometric law.

Whoever builds a `Vehicle` (the vehicle process, the lockstep harness's users, benchmarks, tests) injects
these factories, as RotorPy injects controllers into its environment, so the vehicle module itself imports
no controller package. The ADRC loop is `adrc_offboard`'s control core (eq. 9-13 serving as the cascade's
inner loop); the PID is the vehicle's built-in one.

The ADRC loop flies each outer tick in one compiled call, as the PID does (sitl_quad.inner_loop): `adrc_inner_loop`
orders the same kernels FlightLoop.fly() calls step by step (measure, the ADRC's `adrc_attitude_torque`, mix and
physics), and `CompiledAdrcAttitudeLoop` hands it to the flight loop. numba's cache does not see edits to
adrc_offboard's kernels: after one, delete sitl_quad/__pycache__/*.nbi.

The geometric loop (MC_ATT_CTRL = 2, sitl_quad.attitude_geometric: Lee, Leok and McClamroch 2010's eq. 16) is the
attitude half of adrc_offboard.geometric's controller. Every loop's gains come from its family's design
(adrc_offboard.design, gains/design.json), so a vehicle's inner loop and its offboard outer loop are tuned in one
place, and for whatever airframe the vehicle has.
"""

from __future__ import annotations

from functools import partial

import numpy as np

from adrc_offboard.adrc_attitude import AdrcAttitudeController, adrc_attitude_torque
from adrc_offboard.design import Design, adrc_attitude_gains, geometric_gains, load_design
from sitl_quad.attitude_geometric import GeometricAttitudeController
from sitl_quad.config import AttitudeControllerKind, VehicleConfig
from sitl_quad.inner_loop import fly_attitude_step, measure
from sitl_quad.rigid_body import STATE_SIZE
from sitl_quad.vehicle import AttitudeLoopFactory, builtin_pid_loop
from uavcore.control import AttitudeController
from uavcore.kernel_cache import cached_kernel


@cached_kernel
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


def adrc_attitude_loop(config: VehicleConfig, rate_hz: float, design: Design | None = None) -> AttitudeController:
    """The paper's ADRC attitude loop for the airframe the controllers are designed for (config.controller_airframe:
    the true one unless a design airframe is set), its gains from the ADRC family's design (adrc_offboard.design: the
    shipped design.json unless another is given), its observers modelling the motor lag."""
    design = design if design is not None else load_design("adrc")
    airframe = config.controller_airframe
    return CompiledAdrcAttitudeLoop.for_airframe(airframe, gains=adrc_attitude_gains(airframe, design), rate_hz=rate_hz)


def geometric_attitude_loop(config: VehicleConfig, rate_hz: float, design: Design | None = None) -> AttitudeController:
    """Lee's geometric attitude loop for the airframe the controllers are designed for, at the geometric family's
    design (the shipped design.json unless another is given; the law has no state: rate_hz does not enter it)."""
    design = design if design is not None else load_design("geometric")
    airframe = config.controller_airframe
    gains = geometric_gains(airframe, design)
    return GeometricAttitudeController.for_airframe(airframe, gains.omega_roll_pitch, gains.omega_yaw, gains.zeta)


def attitude_loops(
    adrc_design: Design | None = None, geometric_design: Design | None = None
) -> dict[AttitudeControllerKind, AttitudeLoopFactory]:
    """Every attitude loop MC_ATT_CTRL can select; a design replaces the shipped one of its family (the benchmarks
    fly each family's inner loop at its own design: "adrc_paper" has one of its own)."""
    return {
        AttitudeControllerKind.PID: builtin_pid_loop,
        AttitudeControllerKind.ADRC: partial(adrc_attitude_loop, design=adrc_design),
        AttitudeControllerKind.GEOMETRIC: partial(geometric_attitude_loop, design=geometric_design),
    }
