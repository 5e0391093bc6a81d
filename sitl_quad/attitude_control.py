"""The inner (attitude) loop's interface. Implementations: PID here, ADRC in adrc_offboard.adrc_attitude."""

from __future__ import annotations

from typing import Protocol

import numpy as np

from sitl_quad.state import AttitudeTarget, VehicleState


class AttitudeController(Protocol):
    """Runs at the attitude-loop rate (250 Hz); turns an attitude target into body torques."""

    def reset(self) -> None:
        """Forget integrators and observer states (on arming, after a mode switch to the ground)."""

    def update(self, target: AttitudeTarget, state: VehicleState, dt: float) -> np.ndarray:
        """Body torque command [roll, pitch, yaw] in N m for the given target and measured state."""
        ...
