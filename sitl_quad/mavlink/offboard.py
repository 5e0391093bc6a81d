"""Offboard setpoints: SET_ATTITUDE_TARGET from the offboard controller (and the lockstep handshake built on
it), body rates + thrust, and SET_POSITION_TARGET_LOCAL_NED / _GLOBAL_INT as MAVSDK's offboard plugin and QGC
send them (what they ask of the vehicle: sitl_quad.offboard_setpoints).

A SET_ATTITUDE_TARGET counts as proof of life only with a thrust and an attitude or body rates (as PX4
requires); a position target with a position, velocity or acceleration. In lockstep an attitude target's
time_boot_ms names the vehicle state it answers; the server waits for that answer before advancing simulated
time.
"""

from __future__ import annotations

import logging
import math
import time

import numpy as np

from sitl_quad.offboard_setpoints import (
    PositionTarget,
    RatesTarget,
    SetpointError,
    global_to_local,
    local_position_target,
)
from sitl_quad.vehicle import Vehicle
from uavcore.mavlink import mavlink
from uavcore.mission import MavFrame
from uavcore.state import AttitudeTarget

log = logging.getLogger(__name__)

# No setpoint this long (wall clock): lockstep stops waiting for the peer. Generous, because a loaded machine
# (the test suite's workers plus a CPU burner on both cores) can stall a process for seconds, and a tick taken
# without the answer breaks repeatability: with simulated time then running freely, the vehicle's offboard-loss
# failsafe (OFFB_LOSS_T, simulated) would end a healthy flight. A controller that really died costs 5 s.
STREAM_TIMEOUT_WALL_S = 5.0
IGNORE_ATTITUDE = mavlink.ATTITUDE_TARGET_TYPEMASK_ATTITUDE_IGNORE
IGNORE_THROTTLE = mavlink.ATTITUDE_TARGET_TYPEMASK_THROTTLE_IGNORE
IGNORE_RATES = (
    mavlink.ATTITUDE_TARGET_TYPEMASK_BODY_ROLL_RATE_IGNORE
    | mavlink.ATTITUDE_TARGET_TYPEMASK_BODY_PITCH_RATE_IGNORE
    | mavlink.ATTITUDE_TARGET_TYPEMASK_BODY_YAW_RATE_IGNORE
)
RATE_IGNORE_BITS = (
    mavlink.ATTITUDE_TARGET_TYPEMASK_BODY_ROLL_RATE_IGNORE,
    mavlink.ATTITUDE_TARGET_TYPEMASK_BODY_PITCH_RATE_IGNORE,
    mavlink.ATTITUDE_TARGET_TYPEMASK_BODY_YAW_RATE_IGNORE,
)
# POSITION_TARGET_TYPEMASK: which axes of a SET_POSITION_TARGET_* to ignore
POSITION_IGNORE_BITS = (
    mavlink.POSITION_TARGET_TYPEMASK_X_IGNORE,
    mavlink.POSITION_TARGET_TYPEMASK_Y_IGNORE,
    mavlink.POSITION_TARGET_TYPEMASK_Z_IGNORE,
)
VELOCITY_IGNORE_BITS = (
    mavlink.POSITION_TARGET_TYPEMASK_VX_IGNORE,
    mavlink.POSITION_TARGET_TYPEMASK_VY_IGNORE,
    mavlink.POSITION_TARGET_TYPEMASK_VZ_IGNORE,
)
ACCELERATION_IGNORE_BITS = (
    mavlink.POSITION_TARGET_TYPEMASK_AX_IGNORE,
    mavlink.POSITION_TARGET_TYPEMASK_AY_IGNORE,
    mavlink.POSITION_TARGET_TYPEMASK_AZ_IGNORE,
)
FORCE_SETPOINT = mavlink.POSITION_TARGET_TYPEMASK_FORCE_SET  # PX4 refuses force setpoints too
YAW_IGNORE = mavlink.POSITION_TARGET_TYPEMASK_YAW_IGNORE
YAW_RATE_IGNORE = mavlink.POSITION_TARGET_TYPEMASK_YAW_RATE_IGNORE
GLOBAL_SETPOINT_FRAMES = {  # frame -> altitude above home (else AMSL); the ground is flat at home's altitude
    mavlink.MAV_FRAME_GLOBAL_INT: False,
    mavlink.MAV_FRAME_GLOBAL_RELATIVE_ALT_INT: True,
    mavlink.MAV_FRAME_GLOBAL_TERRAIN_ALT_INT: True,
}


def _masked(values, bits, type_mask: int) -> tuple[float, float, float]:
    """The three values with the ignored ones (and any non-finite one) as NaN."""
    kept = (not type_mask & bit and math.isfinite(v) for v, bit in zip(values, bits, strict=True))
    return tuple(float(v) if keep else math.nan for v, keep in zip(values, kept, strict=True))


def parse_rates_target(msg) -> RatesTarget | None:
    """Body rates + thrust of a SET_ATTITUDE_TARGET whose attitude is ignored, or None if it is not that (an
    ignored rate axis is a zero rate)."""
    if not msg.type_mask & IGNORE_ATTITUDE or msg.type_mask & IGNORE_THROTTLE:
        return None
    if (msg.type_mask & IGNORE_RATES) == IGNORE_RATES or not 0.0 <= msg.thrust <= 1.0:
        return None
    rates = _masked((msg.body_roll_rate, msg.body_pitch_rate, msg.body_yaw_rate), RATE_IGNORE_BITS, msg.type_mask)
    return RatesTarget(tuple(r if math.isfinite(r) else 0.0 for r in rates), float(msg.thrust))


def parse_position_target(msg, vehicle: Vehicle) -> PositionTarget:
    """A SET_POSITION_TARGET_LOCAL_NED or _GLOBAL_INT in the vehicle's local NED frame, taken against its estimate
    now (offset and body frames). Raises SetpointError for what PX4 would not fly."""
    mask = msg.type_mask
    if mask & FORCE_SETPOINT:
        raise SetpointError("force setpoints are not supported")
    velocity = _masked((msg.vx, msg.vy, msg.vz), VELOCITY_IGNORE_BITS, mask)
    acceleration = _masked((msg.afx, msg.afy, msg.afz), ACCELERATION_IGNORE_BITS, mask)
    yaw = msg.yaw if not mask & YAW_IGNORE else math.nan
    yaw_rate = msg.yaw_rate if not mask & YAW_RATE_IGNORE else math.nan
    if msg.get_type() == "SET_POSITION_TARGET_GLOBAL_INT":
        if msg.coordinate_frame not in GLOBAL_SETPOINT_FRAMES:
            raise SetpointError(f"frame {msg.coordinate_frame} is not a global frame")
        lat, lon, alt = _masked((msg.lat_int * 1e-7, msg.lon_int * 1e-7, msg.alt), POSITION_IGNORE_BITS, mask)
        relative = GLOBAL_SETPOINT_FRAMES[msg.coordinate_frame]
        position = global_to_local(vehicle.frame, vehicle.home[2], lat, lon, alt, relative)
        frame = MavFrame.LOCAL_NED
    else:
        position = _masked((msg.x, msg.y, msg.z), POSITION_IGNORE_BITS, mask)
        frame = msg.coordinate_frame
    return local_position_target(frame, position, velocity, acceleration, yaw, yaw_rate, vehicle.estimate)


def parse_attitude_target(msg) -> AttitudeTarget | None:
    """The target carried by a SET_ATTITUDE_TARGET, or None if it is not a usable attitude + thrust.

    Body rates sent with the attitude are the attitude loop's body-frame feed-forward (the offboard outer loops
    send the reference's yaw rate as R^T e_z yaw_rate). PX4 also feeds them forward when the attitude is given,
    but reads only body_yaw_rate, as a rate about the world down axis it rotates into body axes itself; for
    the small tilts of a turn on the spot the two differ by the cosine of the tilt."""
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
        return {
            "SET_ATTITUDE_TARGET": self.on_attitude_target,
            "SET_POSITION_TARGET_LOCAL_NED": self.on_position_target,
            "SET_POSITION_TARGET_GLOBAL_INT": self.on_position_target,
        }

    def on_position_target(self, peer, msg) -> None:
        try:
            target = parse_position_target(msg, self.vehicle)
        except SetpointError as exc:
            self.rejected += 1
            log.info("%s refused: %s", msg.get_type(), exc)
            return
        self.vehicle.set_offboard_position_target(target)

    def on_attitude_target(self, peer, msg) -> None:
        rates = parse_rates_target(msg)
        if rates is not None:
            self.vehicle.set_offboard_rates_target(rates)
            return
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
