"""The vehicle's flight logs: one ULog file per arming, from arming to the tick after the disarm, as PX4's logger
writes them by default (SDLOG_MODE 0), in a directory (`sitl-quad --log-dir`), where the MAVLink log protocol finds them
(sitl_quad.mavlink.log_transfer).

Logged at LOG_INTERVAL_S of simulated time: vehicle_status (arming, PX4's nav_state and custom mode, injected
failures), vehicle_local_position (the estimate) and vehicle_local_position_groundtruth (the simulator's truth, as
PX4 SITL logs it), vehicle_global_position, vehicle_attitude, trajectory_setpoint,
vehicle_attitude_setpoint, battery_status and sim_rotors (the four rotor speeds); every text the vehicle says
(STATUSTEXT) as a logged string; the parameters at arming. Timestamps are microseconds since boot in simulated
time, as PX4 SITL's. A log is written to `<name>.ulg.part` and renamed to `<name>.ulg` at the disarm: only
finished logs are listed.
"""

from __future__ import annotations

import datetime as dt
import re
from dataclasses import dataclass
from pathlib import Path

from sitl_quad.params import ParameterTable
from sitl_quad.ulog import Topic, ULogEncoder
from sitl_quad.vehicle import Vehicle
from sitl_quad.vehicle_types import TickRecord
from uavcore.modes import FlightMode
from uavcore.rotation import euler_from_quat

LOG_INTERVAL_S = 0.1  # 10 Hz: a 5-minute flight's log stays under a megabyte (a second's download)
FILE_PATTERN = re.compile(r"log_(\d{4})_(\d{8}T\d{6})Z\.ulg")
TIME_FORMAT = "%Y%m%dT%H%M%S"

# PX4's vehicle_status.nav_state numbers for the modes this vehicle flies (Descend is logged as AUTO_LAND)
NAV_STATES = {
    FlightMode.POSCTL: 2,
    FlightMode.AUTO_MISSION: 3,
    FlightMode.AUTO_LOITER: 4,
    FlightMode.AUTO_RTL: 5,
    FlightMode.OFFBOARD: 14,
    FlightMode.AUTO_TAKEOFF: 17,
    FlightMode.AUTO_LAND: 18,
    FlightMode.ORBIT: 21,
}
ARMING_STATE_DISARMED, ARMING_STATE_ARMED = 1, 2  # PX4's vehicle_status.arming_state
# vehicle_status.failure_flags bits (this vehicle's own: PX4 logs injected failures only as strings)
FAILURE_GPS, FAILURE_BATTERY, FAILURE_MAVLINK = 1, 2, 4

LOCAL_POSITION_FIELDS = tuple(("float", name) for name in ("x", "y", "z", "vx", "vy", "vz", "heading"))
TOPICS = (
    Topic(
        "vehicle_status",
        (
            ("uint8_t", "arming_state"),
            ("uint8_t", "nav_state"),
            ("uint32_t", "custom_mode"),
            ("uint8_t", "failure_flags"),
            ("uint8_t", "motors_off_mask"),
        ),
    ),
    Topic("vehicle_local_position", LOCAL_POSITION_FIELDS),
    Topic("vehicle_local_position_groundtruth", LOCAL_POSITION_FIELDS),  # PX4 SITL's name: the simulator's truth
    Topic("vehicle_global_position", (("double", "lat"), ("double", "lon"), ("float", "alt"))),
    Topic("vehicle_attitude", (("float[4]", "q"),)),
    Topic(
        "trajectory_setpoint",
        (("float[3]", "position"), ("float[3]", "velocity"), ("float[3]", "acceleration"), ("float", "yaw")),
    ),
    Topic("vehicle_attitude_setpoint", (("float[4]", "q_d"), ("float[3]", "thrust_body"))),
    Topic(
        "battery_status",
        (
            ("float", "voltage_v"),
            ("float", "current_a"),
            ("float", "discharged_mah"),
            ("float", "remaining"),
            ("uint8_t", "warning"),
        ),
    ),
    Topic("sim_rotors", (("float[4]", "speed_rad_s"),)),
)


@dataclass(frozen=True)
class LogEntry:
    """A finished log: LOG_ENTRY's fields (its id is its index in `FlightLogs.entries()`)."""

    path: Path
    time_utc: int  # seconds since 1970 at arming
    size: int


class FlightLogs:
    """The log directory and the log being written (one per arming)."""

    def __init__(self, directory: Path, params: ParameterTable | None, boot_unix_us: int) -> None:
        self.directory = directory
        directory.mkdir(parents=True, exist_ok=True)
        self.params = params
        self.boot_unix_us = boot_unix_us
        self.encoder = ULogEncoder(TOPICS)
        self._file = None
        self._path: Path | None = None
        self._next_sample_t = 0.0
        self._disarm_logged = False

    # ----- the finished logs
    def entries(self) -> list[LogEntry]:
        """The finished logs, oldest first."""
        found = []
        for path in self.directory.glob("log_*.ulg"):
            match = FILE_PATTERN.fullmatch(path.name)
            if match is None:
                continue
            when = dt.datetime.strptime(match.group(2), TIME_FORMAT).replace(tzinfo=dt.UTC)
            found.append((int(match.group(1)), LogEntry(path, int(when.timestamp()), path.stat().st_size)))
        return [entry for _, entry in sorted(found, key=lambda pair: (pair[0], pair[1].path.name))]

    def erase(self) -> int:
        """Delete every finished log (LOG_ERASE); the one being written stays. Returns how many went."""
        entries = self.entries()
        for entry in entries:
            entry.path.unlink(missing_ok=True)
        return len(entries)

    @property
    def writing(self) -> bool:
        return self._file is not None

    # ----- the log being written
    def tick(self, vehicle: Vehicle, record: TickRecord) -> None:
        """After each tick: open a log at arming, sample it every LOG_INTERVAL_S, close it at the disarm."""
        if vehicle.armed and self._file is None:
            self._open(vehicle)
        if self._file is None:
            return
        if not vehicle.armed and self._disarm_logged:  # the tick after the disarm: its texts are in
            self._close()
            return
        if vehicle.t + 1e-9 >= self._next_sample_t or not vehicle.armed:
            self._next_sample_t = vehicle.t + LOG_INTERVAL_S
            self._file.write(b"".join(self._samples(vehicle, record)))
        self._disarm_logged = not vehicle.armed

    def text(self, severity: int, text: str, t: float) -> None:
        """A text the vehicle said, into the log being written (if any)."""
        if self._file is not None:
            self._file.write(self.encoder.text(severity, round(t * 1e6), text))

    def close(self) -> None:
        """The vehicle stops: a log still open is finished as it is (PX4 closes it on shutdown too)."""
        if self._file is not None:
            self._close()

    def _open(self, vehicle: Vehicle) -> None:
        sequence = max((int(m.group(1)) for p in self.directory.iterdir() if (m := _numbered(p.name))), default=0) + 1
        unix_s = (self.boot_unix_us + round(vehicle.t * 1e6)) // 1_000_000
        stamp = dt.datetime.fromtimestamp(unix_s, dt.UTC).strftime(TIME_FORMAT)
        self._path = self.directory / f"log_{sequence:04d}_{stamp}Z.ulg"
        self._file = open(self._path.with_name(self._path.name + ".part"), "wb")  # noqa: SIM115 (closed at disarm)
        info = {"sys_name": "sitl_quad", "ver_hw": "SITL", "sys_os_name": "Python", "sys_mcu": "simulated"}
        parameters = {}
        if self.params is not None:
            parameters = {spec.name: (spec.type, self.params.get(spec.name)) for spec in self.params.specs}
        self._file.write(self.encoder.definitions(round(vehicle.t * 1e6), info, parameters))
        self._next_sample_t = vehicle.t

    def _close(self) -> None:
        assert self._file is not None and self._path is not None
        self._file.close()
        self._path.with_name(self._path.name + ".part").rename(self._path)
        self._file = self._path = None
        self._disarm_logged = False

    def _samples(self, vehicle: Vehicle, record: TickRecord) -> list[bytes]:
        us = round(vehicle.t * 1e6)
        est, truth, sp, target = record.estimate, record.truth, record.setpoint, record.target
        failures = vehicle.failures
        flags = FAILURE_GPS * failures.gps_off | FAILURE_BATTERY * failures.battery_empty
        flags |= FAILURE_MAVLINK * failures.mavlink_off
        motors_mask = sum(1 << (motor - 1) for motor in failures.motors_off)
        lat, lon, alt = vehicle.frame.from_ned(*map(float, est.position))
        battery = vehicle.battery
        arming = ARMING_STATE_ARMED if vehicle.armed else ARMING_STATE_DISARMED
        encode = self.encoder.sample
        return [
            encode(
                "vehicle_status",
                us,
                (arming, NAV_STATES.get(vehicle.mode, 255), vehicle.mode.custom_mode, flags, motors_mask),
            ),
            encode("vehicle_local_position", us, (*est.position, *est.velocity, _yaw(est.quaternion))),
            encode(
                "vehicle_local_position_groundtruth", us, (*truth.position, *truth.velocity, _yaw(truth.quaternion))
            ),
            encode("vehicle_global_position", us, (float(lat), float(lon), float(alt))),
            encode("vehicle_attitude", us, tuple(est.quaternion)),
            encode("trajectory_setpoint", us, (*sp.position, *sp.velocity, *sp.acceleration, sp.yaw)),
            encode("vehicle_attitude_setpoint", us, (*target.quaternion, 0.0, 0.0, -target.thrust)),
            encode(
                "battery_status",
                us,
                (
                    battery.reported_voltage_v,
                    battery.current_a,
                    battery.consumed_mah,
                    battery.reported_charge,
                    int(battery.warning),
                ),
            ),
            encode("sim_rotors", us, tuple(vehicle.sim.rotor_speeds)),
        ]


def _numbered(name: str) -> re.Match | None:
    return re.match(r"log_(\d{4})_", name)


def _yaw(quaternion) -> float:
    return float(euler_from_quat(quaternion)[2])
