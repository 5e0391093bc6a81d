"""The offboard setpoint stream and what happens when it stops (OFFB_LOSS_T, OFFB_LOSS_ACT).

The offboard controller's SET_ATTITUDE_TARGETs fly the vehicle only in OFFBOARD and only while fresh: no
new target for `offboard_loss_timeout_s` of simulated time and the vehicle leaves OFFBOARD for the mode
OFFB_LOSS_ACT names, as PX4's commander does. Ages are counted in integer physics steps, so a lockstep
flight decides the loss at the same tick whatever the wall clock did.
"""

from __future__ import annotations

from dataclasses import dataclass

from sitl_quad.config import FailsafeAction, FailsafeConfig
from uavcore.modes import FlightMode
from uavcore.state import AttitudeTarget

OFFBOARD_LOSS_MODES = {
    FailsafeAction.HOLD: FlightMode.AUTO_LOITER,
    FailsafeAction.LAND: FlightMode.AUTO_LAND,
    FailsafeAction.RETURN: FlightMode.AUTO_RTL,
}


@dataclass
class OffboardStream:
    """The latest SET_ATTITUDE_TARGET from the offboard controller."""

    target: AttitudeTarget | None = None
    received_step: int = -(10**12)  # the physics step it arrived at
    answered_ms: int = -1  # the state time_boot_ms it answers (lockstep)
    count: int = 0

    def receive(self, target: AttitudeTarget, answered_ms: int, step_index: int) -> None:
        self.target = target
        self.received_step = step_index
        self.answered_ms = answered_ms
        self.count += 1

    def age_s(self, step_index: int, dt: float) -> float:
        """Simulated seconds since the last target, at physics step `step_index` of `dt` seconds."""
        return (step_index - self.received_step) * dt

    def fresh(self, step_index: int, dt: float, failsafe: FailsafeConfig) -> bool:
        return self.age_s(step_index, dt) <= failsafe.offboard_loss_timeout_s + 1e-9


def offboard_loss_mode(failsafe: FailsafeConfig) -> FlightMode:
    """The mode OFFB_LOSS_ACT switches to when the stream is lost."""
    return OFFBOARD_LOSS_MODES[FailsafeAction(failsafe.offboard_loss_action)]
