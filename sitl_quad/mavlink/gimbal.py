"""Gimbal protocol v2: the autopilot component (compid 1) is the gimbal manager of gimbal device 1, built into
the autopilot, as PX4 is with a non-MAVLink gimbal (src/modules/gimbal/input_mavlink.cpp, InputMavlinkGimbalV2).

- REQUEST_MESSAGE answers GIMBAL_MANAGER_INFORMATION (280) and GIMBAL_DEVICE_INFORMATION (283); MAVSDK 3's Gimbal
  plugin finds the gimbal by the first and asks for the second from the manager, device id 1..6 meaning "built
  into the manager".
- Streamed on simulated time to every peer: GIMBAL_DEVICE_ATTITUDE_STATUS and GIMBAL_MANAGER_STATUS at
  STATUS_RATE_HZ (the spec's suggested 5 Hz; PX4 streams 1 and 0.5 Hz, MAVSDK works with both). The manager's
  status also goes out at once when control changes, so a client reads its take_control back without waiting.
- MAV_CMD_DO_GIMBAL_MANAGER_CONFIGURE: p1/p2 primary sysid/compid: 0..255 that client, -1 unchanged, -2 the
  autopilot itself, -3 release (only by the holder). Secondary control is not supported (PX4 neither). ACCEPTED.
- MAV_CMD_DO_GIMBAL_MANAGER_PITCHYAW (p1 pitch, p2 yaw deg; p3/p4 rates deg/s; p5 GIMBAL_MANAGER_FLAGS) and the
  GIMBAL_MANAGER_SET_ATTITUDE / SET_PITCHYAW messages: from the primary client only; the command is DENIED to
  anyone else and the messages ignored, as PX4 does.
- MAV_CMD_DO_SET_ROI_LOCATION (p5/p6 lat/lon, p7 altitude AMSL whatever COMMAND_INT's frame, as PX4's receiver
  takes it) and MAV_CMD_DO_SET_ROI_NONE (back to neutral), over COMMAND_LONG and COMMAND_INT, from anyone.
- The same three commands as mission items (`run_mission_item`), executed when the navigator reaches them, as
  PX4's navigator re-issues them as commands; there the item's own frame says what its altitude is relative to,
  and a PITCHYAW item first takes control for the autopilot (PX4's navigator acquires gimbal control).
"""

from __future__ import annotations

import math

from sitl_quad.gimbal import Gimbal
from sitl_quad.mavlink.commands import Commands, CommandSource
from sitl_quad.vehicle import CommandResult, Vehicle
from uavcore.mavlink import mavlink
from uavcore.mission import MavFrame, MissionItem
from uavcore.rotation import euler_from_quat

GIMBAL_DEVICE_ID = 1  # a device without its own MAVLink component, driven by the autopilot (PX4 MNT_MODE_OUT=AUX)
STATUS_RATE_HZ = 5.0
# What PX4 publishes in GIMBAL_MANAGER_INFORMATION: neutral, roll/pitch lock, pitch and yaw axes, yaw lock, ROI
MANAGER_CAPABILITIES = (
    mavlink.GIMBAL_MANAGER_CAP_FLAGS_HAS_NEUTRAL
    | mavlink.GIMBAL_MANAGER_CAP_FLAGS_HAS_ROLL_LOCK
    | mavlink.GIMBAL_MANAGER_CAP_FLAGS_HAS_PITCH_AXIS
    | mavlink.GIMBAL_MANAGER_CAP_FLAGS_HAS_PITCH_LOCK
    | mavlink.GIMBAL_MANAGER_CAP_FLAGS_HAS_YAW_AXIS
    | mavlink.GIMBAL_MANAGER_CAP_FLAGS_HAS_YAW_LOCK
    | mavlink.GIMBAL_MANAGER_CAP_FLAGS_CAN_POINT_LOCATION_GLOBAL
)
# GIMBAL_DEVICE_CAP_FLAGS share their low bits with the manager's
DEVICE_CAPABILITIES = MANAGER_CAPABILITIES & 0x0FFF
KEEP, AUTOPILOT_ITSELF, RELEASE = -1, -2, -3  # DO_GIMBAL_MANAGER_CONFIGURE's special ids
RELATIVE_FRAMES = (MavFrame.GLOBAL_RELATIVE_ALT, MavFrame.GLOBAL_RELATIVE_ALT_INT)


def _control_id(value: int, current: int, own: int) -> int:
    """One of DO_GIMBAL_MANAGER_CONFIGURE's ids: -1 keeps, -2 is the autopilot itself, else 0..255 (ValueError:
    DENIED)."""
    if value == KEEP:
        return current
    if value == AUTOPILOT_ITSELF:
        return own
    if not 0 <= value <= 255:
        raise ValueError(f"gimbal control id {value}")
    return value


def _text(value: str, size: int = 32) -> bytes:
    return value.encode()[:size]


class GimbalManager:
    def __init__(self, vehicle: Vehicle, link, commands: Commands) -> None:
        self.vehicle = vehicle
        self.link = link
        self.gimbal = Gimbal()
        self.primary = (0, 0)  # (sysid, compid) of the client in control; (0, 0): nobody
        self._next_status_t = 0.0
        self._last_t = vehicle.t
        commands.register_sourced(mavlink.MAV_CMD_DO_GIMBAL_MANAGER_CONFIGURE, self.configure)
        commands.register_sourced(mavlink.MAV_CMD_DO_GIMBAL_MANAGER_PITCHYAW, self.pitch_yaw_command)
        commands.register(mavlink.MAV_CMD_DO_SET_ROI_LOCATION, lambda p: self.set_roi(p[4], p[5], p[6]))
        commands.register(mavlink.MAV_CMD_DO_SET_ROI_NONE, lambda p: self.roi_none())

    def handlers(self) -> dict:
        return {
            "GIMBAL_MANAGER_SET_ATTITUDE": self.set_attitude_message,
            "GIMBAL_MANAGER_SET_PITCHYAW": self.set_pitch_yaw_message,
        }

    # ----- the gimbal's motion, on simulated time
    def update(self) -> None:
        """Move the gimbal over the tick just flown (called after each tick), toward what the vehicle's estimate
        says the target is."""
        v = self.vehicle
        dt, self._last_t = v.t - self._last_t, v.t
        _, _, yaw = euler_from_quat(v.estimate.quaternion)
        self.gimbal.update(dt, [float(c) for c in v.estimate.position], yaw)

    def publish_due(self) -> None:
        t = self.vehicle.t
        if t >= self._next_status_t:
            self._next_status_t = max(self._next_status_t + 1.0 / STATUS_RATE_HZ, t)
            self.link.send_batch([self.device_attitude_status(), self.manager_status()], self.link.live_peers())

    # ----- messages
    def request_message(self, msg_id: int) -> CommandResult | None:
        """REQUEST_MESSAGE for the manager's messages: sent, ACCEPTED; None for any other message."""
        builders = {
            mavlink.MAVLINK_MSG_ID_GIMBAL_MANAGER_INFORMATION: self.manager_information,
            mavlink.MAVLINK_MSG_ID_GIMBAL_DEVICE_INFORMATION: self.device_information,
            mavlink.MAVLINK_MSG_ID_GIMBAL_MANAGER_STATUS: self.manager_status,
            mavlink.MAVLINK_MSG_ID_GIMBAL_DEVICE_ATTITUDE_STATUS: self.device_attitude_status,
        }
        builder = builders.get(msg_id)
        if builder is None:
            return None
        self.link.send(builder())
        return CommandResult.ACCEPTED

    def manager_information(self):
        lim = self.gimbal.limits
        return mavlink.MAVLink_gimbal_manager_information_message(
            self.vehicle.time_boot_ms, MANAGER_CAPABILITIES, GIMBAL_DEVICE_ID,
            0.0, 0.0, lim.pitch_min, lim.pitch_max, lim.yaw_min, lim.yaw_max,
        )  # fmt: skip

    def device_information(self):
        lim = self.gimbal.limits
        return mavlink.MAVLink_gimbal_device_information_message(
            self.vehicle.time_boot_ms, _text("buoy-sim"), _text("SimGimbal 2-axis"), _text(""), 0x00000101, 1,
            0, DEVICE_CAPABILITIES, 0, 0.0, 0.0, lim.pitch_min, lim.pitch_max, lim.yaw_min, lim.yaw_max,
            GIMBAL_DEVICE_ID,
        )  # fmt: skip

    def _device_flags(self) -> int:
        flags = mavlink.GIMBAL_DEVICE_FLAGS_ROLL_LOCK | mavlink.GIMBAL_DEVICE_FLAGS_PITCH_LOCK
        flags |= mavlink.GIMBAL_DEVICE_FLAGS_YAW_IN_VEHICLE_FRAME  # the quaternion's yaw: see sitl_quad.gimbal
        if self.gimbal.yaw_lock:
            flags |= mavlink.GIMBAL_DEVICE_FLAGS_YAW_LOCK
        if self.gimbal.mode == "neutral":
            flags |= mavlink.GIMBAL_DEVICE_FLAGS_NEUTRAL
        return flags

    def device_attitude_status(self):
        _, _, vehicle_yaw = euler_from_quat(self.vehicle.estimate.quaternion)
        return mavlink.MAVLink_gimbal_device_attitude_status_message(
            0, 0, self.vehicle.time_boot_ms, self._device_flags(), list(self.gimbal.device_quaternion()),
            math.nan, math.nan, math.nan, 0, vehicle_yaw, math.nan, GIMBAL_DEVICE_ID,
        )  # fmt: skip

    def manager_status(self):
        # PX4 copies the device's flags into the manager's status (GIMBAL_MANAGER_FLAGS share their values)
        return mavlink.MAVLink_gimbal_manager_status_message(
            self.vehicle.time_boot_ms, self._device_flags(), GIMBAL_DEVICE_ID, *self.primary, 0, 0
        )

    # ----- control
    def _in_control(self, sysid: int, compid: int) -> bool:
        return self.primary != (0, 0) and self.primary == (sysid, compid)

    @staticmethod
    def _device_addressed(value: float) -> bool:
        """p7 / gimbal_device_id: 0 (all), NaN (unset) or ours."""
        return not math.isfinite(value) or int(value) in (0, GIMBAL_DEVICE_ID)

    def configure(self, p: tuple, source: CommandSource) -> CommandResult:
        if not self._device_addressed(p[6]):
            return CommandResult.DENIED
        sysid, compid = (round(v) if math.isfinite(v) else KEEP for v in p[:2])
        if RELEASE in (sysid, compid):
            if self._in_control(source.sysid, source.compid):
                self.primary = (0, 0)
        else:
            own = (self.link.sysid, self.link.compid)
            self.primary = (_control_id(sysid, self.primary[0], own[0]), _control_id(compid, self.primary[1], own[1]))
        self.link.send(self.manager_status())
        return CommandResult.ACCEPTED

    def pitch_yaw_command(self, p: tuple, source: CommandSource) -> CommandResult:
        if not self._device_addressed(p[6]):
            return CommandResult.DENIED
        if not self._in_control(source.sysid, source.compid):
            return CommandResult.DENIED
        self._pitch_yaw(p[0], p[1], p[2], p[3], p[4])
        return CommandResult.ACCEPTED

    def _pitch_yaw(self, pitch_deg: float, yaw_deg: float, pitch_rate: float, yaw_rate: float, flags: float) -> None:
        yaw_lock = math.isfinite(flags) and bool(int(flags) & mavlink.GIMBAL_MANAGER_FLAGS_YAW_LOCK)
        if math.isfinite(pitch_deg) or math.isfinite(yaw_deg):
            self.gimbal.set_angles(math.radians(pitch_deg), math.radians(yaw_deg), yaw_lock)
        else:
            self.gimbal.set_rates(math.radians(pitch_rate), math.radians(yaw_rate), yaw_lock)

    def set_attitude_message(self, peer, msg) -> None:
        if not self._in_control(msg.get_srcSystem(), msg.get_srcComponent()):
            return  # PX4 ignores a client not in control
        yaw_lock = bool(msg.flags & mavlink.GIMBAL_MANAGER_FLAGS_YAW_LOCK)
        if all(math.isfinite(c) for c in msg.q):
            _, pitch, yaw = euler_from_quat(msg.q)
            self.gimbal.set_angles(pitch, yaw, yaw_lock)
        else:
            self.gimbal.set_rates(msg.angular_velocity_y, msg.angular_velocity_z, yaw_lock)

    def set_pitch_yaw_message(self, peer, msg) -> None:
        if not self._in_control(msg.get_srcSystem(), msg.get_srcComponent()):
            return
        rates = (math.degrees(msg.pitch_rate), math.degrees(msg.yaw_rate))
        self._pitch_yaw(math.degrees(msg.pitch), math.degrees(msg.yaw), *rates, msg.flags)

    # ----- region of interest
    def set_roi(self, lat: float, lon: float, alt_amsl: float) -> CommandResult:
        if not (math.isfinite(lat) and math.isfinite(lon) and math.isfinite(alt_amsl)):
            return CommandResult.DENIED
        if not (-90 <= lat <= 90 and -180 <= lon <= 180):
            return CommandResult.DENIED
        north, east, down = (float(c) for c in self.vehicle.frame.to_ned(lat, lon, alt_amsl))
        self.gimbal.point_at((north, east, down))
        return CommandResult.ACCEPTED

    def roi_none(self) -> CommandResult:
        self.gimbal.neutral()
        return CommandResult.ACCEPTED

    # ----- mission items
    def run_mission_item(self, item: MissionItem) -> bool:
        """Execute a gimbal mission item; False if the item is not the gimbal's."""
        if item.command == mavlink.MAV_CMD_DO_SET_ROI_LOCATION:
            base = self.vehicle.home[2] if item.frame in RELATIVE_FRAMES else 0.0
            self.set_roi(item.lat, item.lon, base + item.z)
        elif item.command == mavlink.MAV_CMD_DO_SET_ROI_NONE:
            self.roi_none()
        elif item.command == mavlink.MAV_CMD_DO_GIMBAL_MANAGER_PITCHYAW:
            self.primary = (self.link.sysid, self.link.compid)
            self._pitch_yaw(item.param1, item.param2, item.param3, item.param4, float(item.x))
        else:
            return False
        return True
