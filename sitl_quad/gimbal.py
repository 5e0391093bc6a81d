"""A stabilised 2-axis (pitch, yaw) camera gimbal: targets, slew-rate and mechanical limits, ROI pointing.

Pure computation: the MAVLink gimbal manager (sitl_quad.mavlink.gimbal) sets its targets and reads its angles.

Model
- The gimbal holds the camera level in roll and at an earth-frame pitch whatever the vehicle's roll and pitch
  (ideal stabilisation: the manager reports ROLL_LOCK | PITCH_LOCK, as PX4's does). A real 2-axis pitch/yaw
  gimbal cannot cancel roll; the model keeps the horizon level anyway, which is what the camera renders.
- Yaw is a body-relative joint, -180..+180 deg with no slip ring: a move from +170 to -170 deg turns 340 deg
  the long way, as on a gimbal with a hard stop behind. Yaw targets are either relative to the vehicle's heading
  ("follow", GIMBAL_MANAGER_FLAGS_YAW_LOCK clear) or to north ("lock", the flag set): a locked target is turned
  into the joint angle every update, so the camera keeps its bearing while the vehicle turns (within the joint's
  range).
- Pitch -90 (straight down) .. +30 deg. Each axis moves toward its target at most SLEW_RATE_DEG_S.
- Modes: angles, angular rates (the target integrates the rate, NaN rate: axis held), a region of interest
  (the target is recomputed each update from the vehicle's position to the ROI, both local NED), neutral
  (pitch 0, yaw 0 relative to the body: PX4's ROI_NONE).

Attitudes (w, x, y, z): `camera_quaternion` rotates camera-FRD vectors into NED (sitl_quad.camera_render's
CameraPose convention); `device_quaternion` is GIMBAL_DEVICE_ATTITUDE_STATUS's q with
GIMBAL_DEVICE_FLAGS_YAW_IN_VEHICLE_FRAME: roll and pitch relative to the horizon, yaw relative to the vehicle's
heading, and delta_yaw = the vehicle's yaw (q_earth = q_delta_yaw * q_vehicle, MAVLink common.xml).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Literal

from uavcore.rotation import quat_from_euler

PITCH_MIN_DEG, PITCH_MAX_DEG = -90.0, 30.0
YAW_MIN_DEG, YAW_MAX_DEG = -180.0, 180.0
SLEW_RATE_DEG_S = 90.0  # per axis; a small camera gimbal's typical top speed

GimbalMode = Literal["angles", "rates", "roi", "neutral"]


def wrap_pi(angle: float) -> float:
    """The angle in [-pi, pi)."""
    return (angle + math.pi) % (2 * math.pi) - math.pi


def _clamp(value: float, low: float, high: float) -> float:
    return min(high, max(low, value))


def _step_toward(current: float, target: float, max_step: float) -> float:
    return current + _clamp(target - current, -max_step, max_step)


@dataclass
class GimbalLimits:
    pitch_min: float = math.radians(PITCH_MIN_DEG)
    pitch_max: float = math.radians(PITCH_MAX_DEG)
    yaw_min: float = math.radians(YAW_MIN_DEG)
    yaw_max: float = math.radians(YAW_MAX_DEG)
    slew_rate: float = math.radians(SLEW_RATE_DEG_S)  # rad/s per axis


def aim_angles(from_ned: Sequence[float], to_ned: Sequence[float]) -> tuple[float, float]:
    """Earth-frame (pitch, yaw) in rad of the line of sight from one NED point to another (pitch up positive,
    yaw from north toward east)."""
    north, east, down = (float(b) - float(a) for a, b in zip(from_ned, to_ned, strict=True))
    return math.atan2(-down, math.hypot(north, east)), math.atan2(east, north)


class Gimbal:
    """Joint angles `pitch` (earth frame, stabilised) and `yaw` (relative to the body), in rad."""

    def __init__(self, limits: GimbalLimits | None = None) -> None:
        self.limits = limits or GimbalLimits()
        self.pitch = 0.0
        self.yaw = 0.0
        self.mode: GimbalMode = "neutral"
        self.yaw_lock = False  # the yaw target is relative to north, not to the vehicle's heading
        self.target_pitch = 0.0
        self.target_yaw = 0.0  # relative to the body, or to north when yaw_lock
        self.pitch_rate = 0.0
        self.yaw_rate = 0.0
        self.roi_ned: tuple[float, float, float] | None = None

    # ----- targets (what the manager's commands ask for)
    def set_angles(self, pitch: float, yaw: float, yaw_lock: bool = False) -> None:
        """Point at pitch / yaw (rad); NaN keeps that axis's current target."""
        self._leave_roi()
        if math.isfinite(pitch):
            self.target_pitch = pitch
        if math.isfinite(yaw):
            self.target_yaw = yaw
        self.yaw_lock = yaw_lock
        self.mode = "angles"

    def set_rates(self, pitch_rate: float, yaw_rate: float, yaw_lock: bool = False) -> None:
        """Move at these angular rates (rad/s); NaN: that axis holds its target."""
        self._leave_roi()
        self.pitch_rate = pitch_rate if math.isfinite(pitch_rate) else 0.0
        self.yaw_rate = yaw_rate if math.isfinite(yaw_rate) else 0.0
        self.yaw_lock = yaw_lock
        self.mode = "rates"

    def point_at(self, roi_ned: Sequence[float]) -> None:
        """Keep the optical axis on this local NED point (the ROI) as the vehicle moves."""
        north, east, down = (float(c) for c in roi_ned)
        self.roi_ned = (north, east, down)
        self.mode = "roi"

    def neutral(self) -> None:
        """Level and straight ahead (PX4 goes to neutral on DO_SET_ROI_NONE)."""
        self.roi_ned = None
        self.target_pitch = self.target_yaw = 0.0
        self.yaw_lock = False
        self.mode = "neutral"

    def _leave_roi(self) -> None:
        self.roi_ned = None

    # ----- motion
    def update(self, dt: float, camera_ned: Sequence[float], vehicle_yaw: float) -> None:
        """Advance dt seconds with the camera at camera_ned and the vehicle heading vehicle_yaw (rad)."""
        lim = self.limits
        if self.mode == "rates":
            self.target_pitch += self.pitch_rate * dt
            self.target_yaw += self.yaw_rate * dt
        if self.mode == "roi" and self.roi_ned is not None:
            pitch, bearing = aim_angles(camera_ned, self.roi_ned)
            pitch_target, yaw_target = pitch, wrap_pi(bearing - vehicle_yaw)
        else:
            pitch_target = self.target_pitch
            yaw_target = wrap_pi(self.target_yaw - vehicle_yaw) if self.yaw_lock else self.target_yaw
        pitch_target = _clamp(pitch_target, lim.pitch_min, lim.pitch_max)
        yaw_target = _clamp(yaw_target, lim.yaw_min, lim.yaw_max)
        if self.mode == "rates":  # a rate command stops at the stops instead of winding the target past them
            self.target_pitch = pitch_target
            self.target_yaw = wrap_pi(yaw_target + vehicle_yaw) if self.yaw_lock else yaw_target
        step = lim.slew_rate * dt
        self.pitch = _step_toward(self.pitch, pitch_target, step)
        self.yaw = _step_toward(self.yaw, yaw_target, step)

    # ----- attitudes
    def earth_yaw(self, vehicle_yaw: float) -> float:
        return wrap_pi(vehicle_yaw + self.yaw)

    def camera_quaternion(self, vehicle_yaw: float) -> tuple[float, float, float, float]:
        """Camera FRD -> NED (w, x, y, z): level, at the gimbal's pitch, facing the vehicle's yaw + the joint's."""
        w, x, y, z = (float(c) for c in quat_from_euler(0.0, self.pitch, self.earth_yaw(vehicle_yaw)))
        return w, x, y, z

    def device_quaternion(self) -> tuple[float, float, float, float]:
        """GIMBAL_DEVICE_ATTITUDE_STATUS q with YAW_IN_VEHICLE_FRAME (module docstring)."""
        w, x, y, z = (float(c) for c in quat_from_euler(0.0, self.pitch, self.yaw))
        return w, x, y, z
