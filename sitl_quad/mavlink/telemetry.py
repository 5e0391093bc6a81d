"""Telemetry streams: what MAVSDK, QGroundControl and the offboard controller read.

Streams are scheduled on simulated time (so a lockstep flight's telemetry is the same at any speed) with
PX4-like default rates that SET_MESSAGE_INTERVAL can change; REQUEST_MESSAGE answers a single message.
State messages report the vehicle's *estimate* (what a real autopilot knows), never the physics' truth.
"""

from __future__ import annotations

import math
import time

from sitl_quad.battery import Battery, BatteryWarning
from sitl_quad.config import GeofenceAction
from sitl_quad.mavlink.heartbeat import heartbeat_message
from sitl_quad.vehicle import CommandResult, Vehicle
from uavcore.mavlink import mavlink
from uavcore.modes import FlightMode
from uavcore.rotation import euler_from_quat

# MAV_PROTOCOL_CAPABILITY bits MAVSDK and QGC look for (mavlink-conformance.md)
CAPABILITIES = (
    mavlink.MAV_PROTOCOL_CAPABILITY_MISSION_FLOAT
    | mavlink.MAV_PROTOCOL_CAPABILITY_PARAM_FLOAT
    | mavlink.MAV_PROTOCOL_CAPABILITY_MISSION_INT
    | mavlink.MAV_PROTOCOL_CAPABILITY_COMMAND_INT
    | mavlink.MAV_PROTOCOL_CAPABILITY_PARAM_ENCODE_BYTEWISE
    | mavlink.MAV_PROTOCOL_CAPABILITY_SET_ATTITUDE_TARGET
    | mavlink.MAV_PROTOCOL_CAPABILITY_SET_POSITION_TARGET_LOCAL_NED
    | mavlink.MAV_PROTOCOL_CAPABILITY_SET_POSITION_TARGET_GLOBAL_INT
    | mavlink.MAV_PROTOCOL_CAPABILITY_MISSION_FENCE
    | mavlink.MAV_PROTOCOL_CAPABILITY_MISSION_RALLY
    | mavlink.MAV_PROTOCOL_CAPABILITY_MAVLINK2
)
FLIGHT_SW_VERSION = (1 << 24) | (15 << 16) | (0 << 8) | 255  # reads as PX4 v1.15.0 release

# SYS_STATUS sensor bits: present, enabled and healthy (MAVSDK's is_armable reads PREARM_CHECK)
SENSORS = (
    mavlink.MAV_SYS_STATUS_SENSOR_3D_GYRO
    | mavlink.MAV_SYS_STATUS_SENSOR_3D_ACCEL
    | mavlink.MAV_SYS_STATUS_SENSOR_3D_MAG
    | mavlink.MAV_SYS_STATUS_SENSOR_ABSOLUTE_PRESSURE
    | mavlink.MAV_SYS_STATUS_SENSOR_GPS
    | mavlink.MAV_SYS_STATUS_SENSOR_ANGULAR_RATE_CONTROL
    | mavlink.MAV_SYS_STATUS_SENSOR_ATTITUDE_STABILIZATION
    | mavlink.MAV_SYS_STATUS_SENSOR_YAW_POSITION
    | mavlink.MAV_SYS_STATUS_SENSOR_Z_ALTITUDE_CONTROL
    | mavlink.MAV_SYS_STATUS_SENSOR_XY_POSITION_CONTROL
    | mavlink.MAV_SYS_STATUS_SENSOR_MOTOR_OUTPUTS
    | mavlink.MAV_SYS_STATUS_SENSOR_BATTERY
    | mavlink.MAV_SYS_STATUS_PREARM_CHECK
)
# Without a geofence none is breached: the GEOFENCE health bit alone (not present, not enabled), as ArduPilot
# reports it; without it MAVProxy announces "fence breach" as soon as it connects. Once a fence is uploaded
# the bit is also present, enabled while GF_ACTION acts, and healthy unless the vehicle is breaching it.
HEALTH = SENSORS | mavlink.MAV_SYS_STATUS_GEOFENCE

# The offboard controller closes its loop on these: onboard peers get them at every outer-loop tick, as
# PX4 streams its "onboard" MAVLink instance faster than a GCS link.
ONBOARD_STREAMS = ("LOCAL_POSITION_NED", "ATTITUDE_QUATERNION", "POSITION_TARGET_LOCAL_NED")

# Default stream rates in Hz of simulated time, for every peer (ground stations).
DEFAULT_RATES_HZ = {
    "LOCAL_POSITION_NED": 10.0,
    "ATTITUDE_QUATERNION": 10.0,
    "POSITION_TARGET_LOCAL_NED": 10.0,
    "GLOBAL_POSITION_INT": 10.0,
    "ATTITUDE": 10.0,
    "VFR_HUD": 4.0,
    "EXTENDED_SYS_STATE": 2.0,
    "SYS_STATUS": 2.0,
    "GPS_RAW_INT": 2.0,
    "BATTERY_STATUS": 1.0,
    "MISSION_CURRENT": 1.0,
    "HOME_POSITION": 0.5,
    "SYSTEM_TIME": 1.0,
}

UINT16_MAX, INT16_MAX = 65535, 32767  # BATTERY_STATUS: cell not present, temperature unknown


class Telemetry:
    """Builds and schedules the vehicle's outgoing state messages."""

    def __init__(self, vehicle: Vehicle, link) -> None:
        self.vehicle = vehicle
        self.link = link
        self.send = link.send  # callable(msg, peer=None): None means every live peer
        self.intervals: dict[str, float] = {name: 1.0 / hz for name, hz in DEFAULT_RATES_HZ.items()}
        self.next_due: dict[str, float] = dict.fromkeys(self.intervals, 0.0)
        self.builders = {
            "LOCAL_POSITION_NED": self.local_position_ned,
            "ATTITUDE_QUATERNION": self.attitude_quaternion,
            "POSITION_TARGET_LOCAL_NED": self.position_target_local_ned,
            "GLOBAL_POSITION_INT": self.global_position_int,
            "ATTITUDE": self.attitude,
            "VFR_HUD": self.vfr_hud,
            "EXTENDED_SYS_STATE": self.extended_sys_state,
            "SYS_STATUS": self.sys_status,
            "GPS_RAW_INT": self.gps_raw_int,
            "BATTERY_STATUS": self.battery_status,
            "MISSION_CURRENT": self.mission_current,
            "HOME_POSITION": self.home_position,
            "AUTOPILOT_VERSION": self.autopilot_version,
            "SYSTEM_TIME": self.system_time,
        }
        # The vehicle's own unix clock runs on simulated time from the wall-clock instant it booted (as PX4 SITL
        # in lockstep): unix time minus time since boot is then this boot's constant instant, which a ground
        # station compares to recognise a new boot even when a fast lockstep clock has overtaken the old one.
        self.boot_unix_us = int(time.time() * 1e6)
        self.link_stats = link.stats  # drop counters go into SYS_STATUS
        self._geodetic_cache: tuple[float, tuple[float, float, float]] = (-1.0, (0.0, 0.0, 0.0))

    # ----- scheduling
    def publish_due(self) -> None:
        """Send every stream whose interval has elapsed in simulated time (called after each tick).

        What is due in a tick goes out as one datagram per peer, as PX4 batches its UDP output: a loopback
        datagram costs a context switch on the receiving side, a MAVLink frame inside it almost nothing.
        """
        t = self.vehicle.t
        peers = self.link.live_peers()
        onboard = [p for p in peers if p.onboard]
        ground = [p for p in peers if not p.onboard]
        for_everyone, for_ground = [], []
        for name, interval in self.intervals.items():
            if interval > 0 and t >= self.next_due[name]:
                self.next_due[name] = max(self.next_due[name] + interval, t)
                (for_ground if name in ONBOARD_STREAMS else for_everyone).append(self.builders[name]())
        if onboard:
            # Heartbeat and landed state with every tick's state let the offboard controller act on mode,
            # arming and takeoff in step with simulated time (what keeps a lockstep flight repeatable).
            state = [
                heartbeat_message(self.vehicle),
                self.extended_sys_state(),
                *(self.builders[name]() for name in ONBOARD_STREAMS),
            ]
            self.link.send_batch(state + for_everyone, onboard)
        if ground:
            self.link.send_batch(for_ground + for_everyone, ground)

    def set_interval(self, msg_id: int, interval_us: float) -> CommandResult:
        """MAV_CMD_SET_MESSAGE_INTERVAL: -1 disables, 0 restores the default, >0 microseconds."""
        name = _name_of(msg_id)
        if name not in self.builders or name == "AUTOPILOT_VERSION":
            return CommandResult.UNSUPPORTED
        if not math.isfinite(interval_us):
            return CommandResult.DENIED
        if interval_us == 0:
            self.intervals[name] = 1.0 / DEFAULT_RATES_HZ[name] if name in DEFAULT_RATES_HZ else 0.0
        elif interval_us < 0:
            self.intervals[name] = 0.0  # disabled
        else:
            self.intervals[name] = max(interval_us * 1e-6, self.vehicle.outer_dt)
        self.next_due.setdefault(name, 0.0)
        return CommandResult.ACCEPTED

    def request_message(self, msg_id: int) -> CommandResult:
        """MAV_CMD_REQUEST_MESSAGE / GET_HOME_POSITION: send one now."""
        name = _name_of(msg_id)
        if name not in self.builders:
            return CommandResult.UNSUPPORTED
        self.send(self.builders[name]())
        return CommandResult.ACCEPTED

    # ----- message builders
    def local_position_ned(self):
        est = self.vehicle.estimate
        return mavlink.MAVLink_local_position_ned_message(
            self.vehicle.time_boot_ms, *map(float, est.position), *map(float, est.velocity)
        )

    def attitude_quaternion(self):
        est = self.vehicle.estimate
        w, x, y, z = map(float, est.quaternion)
        p, q, r = map(float, est.angular_velocity)
        return mavlink.MAVLink_attitude_quaternion_message(
            self.vehicle.time_boot_ms, w, x, y, z, p, q, r, [0.0, 0.0, 0.0, 0.0]
        )

    def position_target_local_ned(self):
        sp = self.vehicle.setpoint
        return mavlink.MAVLink_position_target_local_ned_message(
            self.vehicle.time_boot_ms,
            mavlink.MAV_FRAME_LOCAL_NED,
            0,
            *map(float, sp.position),
            *map(float, sp.velocity),
            *map(float, sp.acceleration),
            float(sp.yaw),
            float(sp.yaw_rate),
        )

    def attitude(self):
        est = self.vehicle.estimate
        roll, pitch, yaw = euler_from_quat(est.quaternion)
        p, q, r = map(float, est.angular_velocity)
        return mavlink.MAVLink_attitude_message(self.vehicle.time_boot_ms, roll, pitch, yaw, p, q, r)

    def _geodetic(self):
        """The estimate as lat, lon, alt; computed once per tick (pymap3d is exact but not cheap)."""
        v = self.vehicle
        if self._geodetic_cache[0] != v.t:
            n, e, d = map(float, v.estimate.position)
            lat, lon, alt = v.frame.from_ned(n, e, d)
            self._geodetic_cache = (v.t, (float(lat), float(lon), float(alt)))
        return self._geodetic_cache[1]

    def global_position_int(self):
        v = self.vehicle
        lat, lon, alt = self._geodetic()
        vn, ve, vd = map(float, v.estimate.velocity)
        _, _, yaw = euler_from_quat(v.estimate.quaternion)
        heading_cdeg = round(math.degrees(yaw) % 360 * 100) % 36000
        return mavlink.MAVLink_global_position_int_message(
            v.time_boot_ms,
            round(lat * 1e7),
            round(lon * 1e7),
            round(alt * 1000),
            round(-v.estimate.position[2] * 1000),
            _cm(vn),
            _cm(ve),
            _cm(vd),
            heading_cdeg,
        )

    def gps_raw_int(self):
        v = self.vehicle
        if v.failures.gps_off:  # an injected GPS failure: the receiver reports no fix and no satellites
            return mavlink.MAVLink_gps_raw_int_message(
                int(v.t * 1e6), mavlink.GPS_FIX_TYPE_NO_FIX, 0, 0, 0, UINT16_MAX, UINT16_MAX, UINT16_MAX, UINT16_MAX, 0
            )
        lat, lon, alt = self._geodetic()
        vn, ve, _ = map(float, v.estimate.velocity)
        speed = math.hypot(vn, ve)
        cog = round(math.degrees(math.atan2(ve, vn)) % 360 * 100) % 36000 if speed > 0.2 else 65535
        return mavlink.MAVLink_gps_raw_int_message(
            int(v.t * 1e6),
            3,
            round(lat * 1e7),
            round(lon * 1e7),
            round(alt * 1000),
            80,
            120,
            round(speed * 100),
            cog,
            14,
        )

    def vfr_hud(self):
        v = self.vehicle
        vn, ve, vd = map(float, v.estimate.velocity)
        _, _, yaw = euler_from_quat(v.estimate.quaternion)
        ground_speed = math.hypot(vn, ve)
        return mavlink.MAVLink_vfr_hud_message(
            ground_speed,
            ground_speed,
            round(math.degrees(yaw) % 360) % 360,
            round(100 * v.target.thrust),
            float(-v.estimate.position[2] + v.home[2]),
            -vd,
        )

    def extended_sys_state(self):
        return mavlink.MAVLink_extended_sys_state_message(
            mavlink.MAV_VTOL_STATE_UNDEFINED, int(self.vehicle.landed_state)
        )

    def sys_status(self):
        battery = self.vehicle.battery
        stats = self.link_stats
        dropped = stats.dropped if stats else 0
        received = max(1, stats.messages + dropped) if stats else 1
        drop_rate = min(10000, int(10000 * dropped / received))  # centi-percent
        present, enabled, health = geofence_status_bits(self.vehicle)
        if battery.warning >= BatteryWarning.CRITICAL:
            health &= ~mavlink.MAV_SYS_STATUS_SENSOR_BATTERY
        if self.vehicle.failures.gps_off:
            health &= ~mavlink.MAV_SYS_STATUS_SENSOR_GPS
        if self.vehicle.failures.motors_off:
            health &= ~mavlink.MAV_SYS_STATUS_SENSOR_MOTOR_OUTPUTS
        return mavlink.MAVLink_sys_status_message(
            present,
            enabled,
            health,
            250,
            min(UINT16_MAX - 1, round(battery.reported_voltage_v * 1000)),
            _centiamperes(battery.current_a),
            _percent(battery),
            drop_rate,
            min(65535, dropped),
            min(65535, stats.malformed if stats else 0),
            min(65535, stats.unknown if stats else 0),
            min(65535, stats.wrong_target if stats else 0),
            min(65535, stats.unsigned_rejected if stats else 0),
        )

    def battery_status(self):
        """The pack as PX4 reports it (MAVSDK's telemetry.battery reads the cell sum and battery_remaining)."""
        battery = self.vehicle.battery
        cells = battery.config.cells
        cell_mv = min(UINT16_MAX - 1, round(battery.reported_voltage_v / cells * 1000))
        per_cell = [cell_mv] * cells + [UINT16_MAX] * (14 - cells)  # cells 11-14 go in voltages_ext (0: none)
        remaining_s = battery.time_remaining_s()
        return mavlink.MAVLink_battery_status_message(
            0,
            mavlink.MAV_BATTERY_FUNCTION_ALL,
            mavlink.MAV_BATTERY_TYPE_LIPO,
            INT16_MAX,
            per_cell[:10],
            _centiamperes(battery.current_a),
            round(battery.consumed_mah),
            round(battery.consumed_wh * 36.0),  # hJ
            _percent(battery),
            round(remaining_s) if remaining_s is not None else 0,
            int(battery.warning) + 1,  # MAV_BATTERY_CHARGE_STATE_OK = PX4's WARNING_NONE + 1, and so on
            [v if v != UINT16_MAX else 0 for v in per_cell[10:]],
        )

    def mission_current(self):
        v = self.vehicle
        nav = v.navigator
        state = {
            "no_mission": mavlink.MISSION_STATE_NO_MISSION,
            "not_started": mavlink.MISSION_STATE_NOT_STARTED,
            "active": mavlink.MISSION_STATE_ACTIVE,
            "paused": mavlink.MISSION_STATE_PAUSED,
            "complete": mavlink.MISSION_STATE_COMPLETE,
        }.get(nav.mission_state, mavlink.MISSION_STATE_UNKNOWN)
        seq = nav.current_seq if v.mission else 0
        mission_mode = 1 if v.mode == FlightMode.AUTO_MISSION else 0
        return mavlink.MAVLink_mission_current_message(seq, len(v.mission), state, mission_mode)

    def home_position(self):
        lat, lon, alt = self.vehicle.home
        return mavlink.MAVLink_home_position_message(
            round(lat * 1e7),
            round(lon * 1e7),
            round(alt * 1000),
            0.0,
            0.0,
            0.0,
            [1.0, 0.0, 0.0, 0.0],
            0.0,
            0.0,
            0.0,
            int(self.vehicle.t * 1e6),
        )

    def system_time(self):
        boot_ms = self.vehicle.time_boot_ms
        return mavlink.MAVLink_system_time_message(self.boot_unix_us + boot_ms * 1000, boot_ms)

    def autopilot_version(self):
        return mavlink.MAVLink_autopilot_version_message(
            CAPABILITIES, FLIGHT_SW_VERSION, 0, 0, 0, [0] * 8, [0] * 8, [0] * 8, 0x26AC, 0x0011, 0x4255_4F59_5349_544C
        )  # uid: "BUOYSITL"


def geofence_status_bits(vehicle: Vehicle) -> tuple[int, int, int]:
    """SYS_STATUS onboard_control_sensors present, enabled, health with the geofence's bit as it stands: healthy
    unless the vehicle is where the fence does not let it be (armed or not)."""
    fence = mavlink.MAV_SYS_STATUS_GEOFENCE
    if not vehicle.geofence.present:
        return SENSORS, SENSORS, HEALTH
    enabled = SENSORS | fence if vehicle.config.failsafe.geofence_action != GeofenceAction.NONE else SENSORS
    north, east, _ = (float(c) for c in vehicle.estimate.position)
    health = HEALTH & ~fence if vehicle.geofence.violation(north, east) is not None else HEALTH
    return SENSORS | fence, enabled, health


def _centiamperes(current_a: float) -> int:
    return min(INT16_MAX, round(current_a * 100))


def _percent(battery: Battery) -> int:
    """battery_remaining: whole percent."""
    return round(battery.reported_charge * 100)


def _cm(metres_per_second: float) -> int:
    return max(-32768, min(32767, round(metres_per_second * 100)))


def _name_of(msg_id: float) -> str | None:
    try:
        cls = mavlink.mavlink_map.get(int(msg_id))
    except (ValueError, OverflowError):
        return None
    return cls.msgname if cls is not None else None
