"""The controller contracts: what the vehicle and the offboard process expect of a controller they are given.

- `AttitudeController`, the inner loop (250 Hz): the vehicle's PID (sitl_quad.attitude_pid), the paper's ADRC
  (adrc_offboard.adrc_attitude) or Lee's geometric law (sitl_quad.attitude_geometric), injected into
  `sitl_quad.vehicle.Vehicle` by MC_ATT_CTRL.
- `OuterLoopController`, the position loop (50 Hz): ADRC (TD + ESO + NLSEF, eq. 9-13) or the PID baseline
  (adrc_offboard.outer_loop), or the geometric SE(3) baseline (adrc_offboard.geometric), run by the offboard
  process or the in-process lockstep harness.
Plain arrays and the `uavcore.state` types in, an attitude target or body torques out; no I/O.
"""

from __future__ import annotations

from typing import Protocol

import numpy as np

from uavcore.state import AttitudeTarget, TrajectorySetpoint, VehicleState


class AttitudeController(Protocol):
    """Runs at the attitude-loop rate (250 Hz); turns an attitude target into body torques."""

    def reset(self) -> None:
        """Forget integrators and observer states (on arming, after a mode switch to the ground)."""

    def update(self, target: AttitudeTarget, state: VehicleState, dt: float) -> np.ndarray:
        """Body torque command [roll, pitch, yaw] in N m for the given target and measured state."""
        ...


class OuterLoopController(Protocol):
    """Runs at the outer-loop rate (50 Hz by default)."""

    def reset(self) -> None:
        """Forget observer and integrator states."""

    def update(self, setpoint: TrajectorySetpoint, estimate: VehicleState, dt: float) -> AttitudeTarget:
        """Attitude target (quaternion + normalised thrust) for this step."""
        ...

    def disturbance_estimates(self) -> dict[str, float]:
        """Each channel's ESO z3 (m/s^2, NED); empty for controllers without an observer."""
        ...

    def telemetry(self) -> dict[str, float]:
        """Extra internals worth logging (optional content)."""
        ...
