"""The attitude loops a vehicle can fly, by MC_ATT_CTRL: its own PX4-style PID and the paper's ADRC.

Whoever builds a `Vehicle` (the vehicle process, the lockstep harness's users, benchmarks, tests) injects
these factories, as RotorPy injects controllers into its environment, so the vehicle module itself imports
no controller package. The ADRC loop is `adrc_offboard`'s control core (eq. 9-13 serving as the cascade's
inner loop); the PID is the vehicle's built-in one.
"""

from __future__ import annotations

from adrc_offboard.adrc_attitude import AdrcAttitudeController
from sitl_quad.config import AttitudeControllerKind, VehicleConfig
from sitl_quad.vehicle import AttitudeLoopFactory, builtin_pid_loop
from uavcore.control import AttitudeController


def adrc_attitude_loop(config: VehicleConfig, rate_hz: float) -> AttitudeController:
    """The paper's ADRC attitude loop for the configured airframe, its observers modelling the motor lag."""
    return AdrcAttitudeController.for_airframe(config.airframe, rate_hz=rate_hz)


def attitude_loops() -> dict[AttitudeControllerKind, AttitudeLoopFactory]:
    """Every attitude loop MC_ATT_CTRL can select."""
    return {AttitudeControllerKind.PID: builtin_pid_loop, AttitudeControllerKind.ADRC: adrc_attitude_loop}
