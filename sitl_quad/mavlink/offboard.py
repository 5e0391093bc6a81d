"""SET_ATTITUDE_TARGET from the offboard controller, and the lockstep handshake built on it.

A setpoint counts as proof of life only with both an attitude and a thrust (as PX4 requires). In lockstep
the message's time_boot_ms names the vehicle state it answers; the server waits for that answer before
advancing simulated time.
"""

from __future__ import annotations

import math
import time

import numpy as np

from sitl_quad.vehicle import Vehicle
from uavcore.mavlink import mavlink
from uavcore.state import AttitudeTarget

# No setpoint this long (wall clock): lockstep stops waiting for the peer. Generous, because a loaded machine
# can stall a process for a second, and a lockstep tick taken without the answer breaks repeatability.
STREAM_TIMEOUT_WALL_S = 2.0
IGNORE_ATTITUDE = mavlink.ATTITUDE_TARGET_TYPEMASK_ATTITUDE_IGNORE
IGNORE_THROTTLE = mavlink.ATTITUDE_TARGET_TYPEMASK_THROTTLE_IGNORE
IGNORE_RATES = (
    mavlink.ATTITUDE_TARGET_TYPEMASK_BODY_ROLL_RATE_IGNORE
    | mavlink.ATTITUDE_TARGET_TYPEMASK_BODY_PITCH_RATE_IGNORE
    | mavlink.ATTITUDE_TARGET_TYPEMASK_BODY_YAW_RATE_IGNORE
)


def parse_attitude_target(msg) -> AttitudeTarget | None:
    """The target carried by a SET_ATTITUDE_TARGET, or None if it is not a usable attitude + thrust."""
    if msg.type_mask & (IGNORE_ATTITUDE | IGNORE_THROTTLE):
        return None
    q = np.array(msg.q, dtype=float)
    norm = float(np.linalg.norm(q))
    if not (np.all(np.isfinite(q)) and 0.5 < norm < 1.5) or not math.isfinite(msg.thrust):
        return None
    if not 0.0 <= msg.thrust <= 1.0:
        return None
    rates = None
    if (msg.type_mask & IGNORE_RATES) != IGNORE_RATES:
        rates = np.array([msg.body_roll_rate, msg.body_pitch_rate, msg.body_yaw_rate], dtype=float)
        if not np.all(np.isfinite(rates)):
            rates = None
    return AttitudeTarget(quaternion=q / norm, thrust=float(msg.thrust), body_rates=rates)


class Offboard:
    def __init__(self, vehicle: Vehicle) -> None:
        self.vehicle = vehicle
        self.last_wall = -math.inf
        self.rejected = 0

    def handlers(self) -> dict:
        return {"SET_ATTITUDE_TARGET": self.on_attitude_target}

    def on_attitude_target(self, peer, msg) -> None:
        target = parse_attitude_target(msg)
        if target is None:
            self.rejected += 1
            return
        self.last_wall = time.monotonic()
        self.vehicle.set_offboard_target(target, int(msg.time_boot_ms))

    def streaming(self, now: float) -> bool:
        """Whether an offboard controller is live (wall clock): lockstep waits only for a live one."""
        return now - self.last_wall < STREAM_TIMEOUT_WALL_S

    def answered(self, time_boot_ms: int) -> bool:
        return self.vehicle.offboard.answered_ms >= time_boot_ms
