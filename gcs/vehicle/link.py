"""The vehicle link: the one owner of the ground station's MAVLink connection to a vehicle (asyncio).

Why pymavlink and not MAVSDK: the service is one Python process on one asyncio loop, and pymavlink is only a
message codec (`uavcore.mavlink`), so it needs no gRPC `mavsdk_server` beside it and sees every message the
vehicle and its companions publish (DEBUG_VECT, NAMED_VALUE_FLOAT, POSITION_TARGET_LOCAL_NED).

What it does, as QGroundControl and MAVSDK do:
- connects by a connection string (`gcs.vehicle.connection`: udpin, udpout, tcp, serial) and sends the GCS heartbeat at
  1 Hz (sysid 255, compid 190, type GCS);
- discovers the vehicle: the first autopilot heartbeat names its system and component id, autopilot flavour
  (`gcs.vehicle.autopilots`: PX4 or ArduPilot Copter) and vehicle type; other ground stations, cameras, gimbals and
  companions on the link are not taken for it (a companion's estimates on the same system are still read);
  once the vehicle is silent past the timeout, an autopilot with another system id is a different vehicle;
  a link made for one system id (`sysid`, a fleet's vehicle) takes only that system's autopilot;
- detects a new boot for certain by the vehicle's boot instant (SYSTEM_TIME: unix time minus time since boot,
  constant through one boot) as well as by `time_boot_ms` going back;
- asks for the streams it needs with SET_MESSAGE_INTERVAL (and REQUEST_DATA_STREAM for ArduPilot), and never
  assumes one datagram is one vehicle tick or that messages come at any particular rate;
- offers typed actions (`arm`, `start_mission`, `return_to_launch`, `reset_battery`, `upload_mission`,
  `download_mission`, `read_parameters`, `download_file`) that raise typed errors, as MAVSDK's Action, MissionRaw,
  Param and Ftp plugins do, so callers hold no MAVLink numbers;
- keeps the first battery's state (BATTERY_STATUS id 0; SYS_STATUS's battery fields from an autopilot that
  sends no BATTERY_STATUS);
- hands chosen messages to subscribers through queues and listeners. With a signing key it signs every message
  and accepts only signed ones (`uavcore.mavlink`).
"""

from __future__ import annotations

import asyncio
import contextlib
import logging
import math
import time
from collections.abc import Callable, Iterable, Iterator, Sequence
from dataclasses import dataclass, field
from typing import Any

from gcs.vehicle.autopilots import CUSTOM_MODE_ENABLED, Autopilot, Px4, autopilot_for
from gcs.vehicle.camera import CameraClient
from gcs.vehicle.connection import Connection, ConnectionStringError, Transport, open_transport, parse_connection
from gcs.vehicle.errors import CommandDeniedError, CommandTimeoutError, LinkError
from gcs.vehicle.ftp import CAMERA_COMPID, DEFAULT_MAX_BYTES, FtpClient
from gcs.vehicle.logs import LogClient
from gcs.vehicle.mission_protocol import download_items, upload_items
from gcs.vehicle.parameters import read_parameters
from uavcore.geofence import Geofence
from uavcore.mavlink import (
    GCS_COMPID,
    GCS_SYSID,
    MAV_CMD_BATTERY_RESET,
    VEHICLE_UDP_PORT,
    Encoder,
    mavlink,
    new_parser,
    parse_datagram,
    statustext,
)
from uavcore.mission import MavCmd, MissionItem, MissionType, rally_point_items

log = logging.getLogger(__name__)

# At 20 % datagram loss each way a command's round trip fails 36 % of the time: 3 tries (MAVSDK's) leave a 5 %
# chance per command of giving up on a healthy vehicle, 6 tries 0.2 %.
COMMAND_TRIES = 6
REBOOT_BACKSTEP_MS = 1000  # time_boot_ms falling by more than this means the vehicle restarted
BOOT_INSTANT_TOLERANCE_S = 2.0  # a boot instant (SYSTEM_TIME) moving by more than this is a new boot
STATUS_TEXTS_KEPT = 10
REFUSAL_TEXT_WAIT_S = 1.0  # how long a refused command waits for the vehicle's STATUSTEXT giving the cause
ARM_CONFIRM_S = 3.0
TAKEOFF_TIMEOUT_S = 60.0
ON_GROUND = mavlink.MAV_LANDED_STATE_ON_GROUND
ARMED_FLAG = mavlink.MAV_MODE_FLAG_SAFETY_ARMED

# Heartbeats from these are never taken for the vehicle, whatever their autopilot field says.
NOT_A_VEHICLE = frozenset(
    {
        mavlink.MAV_TYPE_GCS,
        mavlink.MAV_TYPE_ONBOARD_CONTROLLER,
        mavlink.MAV_TYPE_GIMBAL,
        mavlink.MAV_TYPE_CAMERA,
        mavlink.MAV_TYPE_ADSB,
        mavlink.MAV_TYPE_ANTENNA_TRACKER,
        mavlink.MAV_TYPE_CHARGING_STATION,
        mavlink.MAV_TYPE_SERVO,
        mavlink.MAV_TYPE_FLARM,
        mavlink.MAV_TYPE_ODID,
    }
)

# What the service reads, and how often (Hz).
STREAMS = {
    "GLOBAL_POSITION_INT": 10.0,
    "LOCAL_POSITION_NED": 10.0,
    "ATTITUDE": 10.0,
    "POSITION_TARGET_LOCAL_NED": 10.0,
    "EXTENDED_SYS_STATE": 2.0,
    "MISSION_CURRENT": 2.0,
    "SYS_STATUS": 1.0,
    "BATTERY_STATUS": 1.0,
    "SYSTEM_TIME": 1.0,
}

FIRST_BATTERY_MASK = 1  # MAV_CMD_BATTERY_RESET's param1: bit 0 is the first battery (BATTERY_STATUS id 0)
UINT16_MAX = 65535  # BATTERY_STATUS.voltages: no such cell; SYS_STATUS.voltage_battery: unknown
# Charge states in which the pack must not fly on (PX4: critical and emergency land or return at once)
BATTERY_CRITICAL_STATES = frozenset(
    {
        mavlink.MAV_BATTERY_CHARGE_STATE_CRITICAL,
        mavlink.MAV_BATTERY_CHARGE_STATE_EMERGENCY,
        mavlink.MAV_BATTERY_CHARGE_STATE_FAILED,
        mavlink.MAV_BATTERY_CHARGE_STATE_UNHEALTHY,
    }
)


BATTERY_THRESHOLDS = ("BAT_LOW_THR", "BAT_CRIT_THR")


@dataclass(frozen=True)
class VehicleIdentity:
    """Who the link is talking to, from the vehicle's heartbeat."""

    sysid: int
    compid: int
    autopilot: int  # MAV_AUTOPILOT
    vehicle_type: int  # MAV_TYPE

    @property
    def autopilot_name(self) -> str:
        entry = mavlink.enums["MAV_AUTOPILOT"].get(self.autopilot)
        return entry.name.removeprefix("MAV_AUTOPILOT_") if entry is not None else str(self.autopilot)

    @property
    def type_name(self) -> str:
        entry = mavlink.enums["MAV_TYPE"].get(self.vehicle_type)
        return entry.name.removeprefix("MAV_TYPE_") if entry is not None else str(self.vehicle_type)


@dataclass
class VehicleStatus:
    """The latest state the vehicle reported. Positions NED metres from home; angles radians; mission sequence
    numbers in the planned numbering (the flavour's own home item is hidden)."""

    connected: bool = False
    last_heartbeat: float | None = None  # time.monotonic()
    sysid: int | None = None
    compid: int | None = None
    autopilot: str | None = None
    vehicle_type: str | None = None
    reboots: int = 0  # new boots of the same vehicle seen
    incarnation: int = 0  # rises with every new boot or new vehicle: what a mission in flight must not outlive
    armed: bool = False
    base_mode: int = 0
    custom_mode: int = 0
    mode: str | None = None
    landed_state: int | None = None
    time_boot_ms: int | None = None
    boot_instant_s: float | None = None  # unix time of the vehicle's boot, from SYSTEM_TIME
    lat: float | None = None
    lon: float | None = None
    alt_m: float | None = None  # above home
    north: float | None = None
    east: float | None = None
    down: float | None = None
    vn: float | None = None
    ve: float | None = None
    vd: float | None = None
    roll: float | None = None
    pitch: float | None = None
    yaw: float | None = None
    ref_north: float | None = None
    ref_east: float | None = None
    ref_down: float | None = None
    ref_yaw: float | None = None
    mission_seq: int | None = None
    mission_total: int | None = None
    mission_state: int | None = None
    # the first battery (BATTERY_STATUS id 0, else SYS_STATUS); None: not reported
    battery_remaining_pct: float | None = None
    battery_voltage_v: float | None = None  # the pack: sum of its cells
    battery_current_a: float | None = None  # drawn from the pack
    battery_consumed_wh: float | None = None  # since the pack was put in (or the vehicle booted)
    battery_charge_state: int | None = None  # MAV_BATTERY_CHARGE_STATE (OK 1, LOW 2, CRITICAL 3, ...)
    battery_status_seen: bool = field(default=False, repr=False)  # then SYS_STATUS's battery fields are ignored
    # the vehicle's own warning levels (PX4's BAT_LOW_THR, BAT_CRIT_THR), read at connection; None: not known
    battery_low_pct: float | None = None
    battery_critical_pct: float | None = None
    home: tuple[float, float, float] | None = None
    estimates: dict[str, Any] = field(default_factory=dict)  # a companion controller's ESO outputs by name
    status_texts: list[str] = field(default_factory=list)  # the vehicle's latest STATUSTEXTs, oldest first
    # each one's MAV_SEVERITY (parallel to status_texts): the page alerts on CRITICAL or worse
    status_severities: list[int] = field(default_factory=list)
    # every STATUSTEXT heard: which of status_texts came after a moment (a refused command's cause), and for a
    # client, a new text told from a repeated one by this count rising
    status_texts_heard: int = 0

    @property
    def on_ground(self) -> bool:
        """EXTENDED_SYS_STATE says so; from an autopilot that never reports a landed state (ArduPilot's classic
        stream groups have no EXTENDED_SYS_STATE), within half a metre of home's altitude."""
        if self.landed_state not in (None, mavlink.MAV_LANDED_STATE_UNDEFINED):
            return self.landed_state == ON_GROUND
        return self.alt_m is not None and abs(self.alt_m) < 0.5

    @property
    def mission_complete(self) -> bool:
        """MISSION_CURRENT.mission_state says COMPLETE (autopilots that report it: PX4, recent ArduPilot)."""
        return self.mission_state == mavlink.MISSION_STATE_COMPLETE

    @property
    def battery_critical(self) -> bool:
        """The autopilot says the pack is at its critical or emergency level, failed or unhealthy."""
        return self.battery_charge_state in BATTERY_CRITICAL_STATES

    def as_dict(self) -> dict[str, Any]:
        age = None if self.last_heartbeat is None else time.monotonic() - self.last_heartbeat
        hidden = ("last_heartbeat", "home", "battery_status_seen")
        data = {k: v for k, v in self.__dict__.items() if k not in hidden}
        data["battery_critical"] = self.battery_critical
        data["heartbeat_age_s"] = age
        data["mode"] = self.mode if self.connected else None
        data["home"] = None if self.home is None else {"lat": self.home[0], "lon": self.home[1], "alt": self.home[2]}
        data["t_s"] = None if self.time_boot_ms is None else self.time_boot_ms / 1000.0
        return data


def _finite(value: float) -> float | None:
    return float(value) if math.isfinite(value) else None


def _known(value: int, unknown: int, per_unit: float = 1.0) -> float | None:
    """An integer field in units (value / per_unit: mV / 1000 is V), or None where it holds its "unknown" marker."""
    return None if value == unknown else value / per_unit


def _pack_voltage_v(m: Any) -> float | None:
    """BATTERY_STATUS's pack voltage: the sum of the cells present. voltages[] marks an absent cell UINT16_MAX,
    voltages_ext[] (cells 11-14) 0; a pack measured only as a whole comes as cell 1 (above 65.534 V spread over
    the next cells), so the sum is right in every case."""
    cells = [v for v in m.voltages if v != UINT16_MAX]
    cells += [v for v in m.voltages_ext if v not in (0, UINT16_MAX)]
    return sum(cells) / 1000.0 if cells else None


class LinkManager:
    """Owns the connection to one vehicle. Create, `await start()`, use, `await stop()`."""

    def __init__(
        self,
        url: str = f"udpout://127.0.0.1:{VEHICLE_UDP_PORT}",
        heartbeat_timeout_s: float = 3.0,
        signing_key: bytes | None = None,
        sysid: int | None = None,
        transports: Callable[[Connection], Transport] = open_transport,
    ) -> None:
        self.connection = parse_connection(url)
        self._open_transport = transports  # a TransportHub's when fleet links share a connection
        self.sysid = sysid  # only this system's autopilot is the vehicle (None: the first autopilot heard)
        self.heartbeat_timeout_s = heartbeat_timeout_s
        self.status = VehicleStatus()
        self.vehicle: VehicleIdentity | None = None
        self.autopilot: Autopilot = Px4()
        self._encoder = Encoder(GCS_SYSID, GCS_COMPID, signing_key)
        self.encoder = self._encoder.mav  # builds messages: link.encoder.command_long_encode(...)
        self._parser = new_parser(GCS_SYSID, GCS_COMPID, signing_key)
        self.signing_key = signing_key
        self._transport: Transport | None = None
        self._tasks: list[asyncio.Task] = []
        self._queues: list[tuple[frozenset[str], int | None, asyncio.Queue]] = []
        self._listeners: list[Callable[[Any], None]] = []
        self._chunk_ends: list[Callable[[], None]] = []
        self._connected_event = asyncio.Event()
        self._command_lock = asyncio.Lock()
        self.messages_received = 0
        self.positions_received = 0  # GLOBAL_POSITION_INT from the vehicle: its position stream's rate, measured
        self.fence: Geofence | None = None  # the vehicle's geofence as last read this connection (None: not read)
        self._ftp = FtpClient(self)
        self.logs = LogClient(self)  # the vehicle's flight logs (MAVSDK's LogFiles)
        self.camera = CameraClient(self)  # the vehicle's camera, once its heartbeat is heard (MAVSDK's Camera)

    @property
    def target(self) -> tuple[int, int]:
        """(system id, component id) commands go to: the discovered vehicle, or 1/1 until one is heard."""
        if self.vehicle is None:
            return self.sysid or 1, 1
        return self.vehicle.sysid, self.vehicle.compid

    # ----- lifecycle
    async def start(self) -> None:
        self._connected_event = asyncio.Event()
        self._command_lock = asyncio.Lock()
        self._transport = self._open_transport(self.connection)
        try:
            await self._transport.open(self._received)
        except OSError as error:
            self._transport = None
            raise LinkError(f"cannot open {self.connection}: {error.strerror or error}") from error
        except ConnectionStringError as error:
            self._transport = None
            raise LinkError(str(error)) from error
        self._tasks = [asyncio.create_task(self._heartbeat_loop(), name="gcs-heartbeat")]

    async def stop(self) -> None:
        for task in self._tasks:
            task.cancel()
        for task in self._tasks:
            with contextlib.suppress(asyncio.CancelledError):
                await task
        self._tasks = []
        if self._transport is not None:
            await self._transport.close()
            self._transport = None

    async def wait_connected(self, timeout_s: float) -> bool:
        """True once the vehicle's heartbeat is seen, False after timeout_s without one."""
        if self.status.connected:
            return True
        try:
            async with asyncio.timeout(timeout_s):
                await self._connected_event.wait()
        except TimeoutError:
            return False
        return self.status.connected

    # ----- sending
    def send(self, message: Any) -> None:
        if self._transport is None:
            raise LinkError("the link is not started")
        self._transport.send(self._encoder.pack(message))

    async def _heartbeat_loop(self) -> None:
        while True:
            self.send(
                self.encoder.heartbeat_encode(
                    mavlink.MAV_TYPE_GCS, mavlink.MAV_AUTOPILOT_INVALID, 0, 0, mavlink.MAV_STATE_ACTIVE
                )
            )
            self._check_heartbeat_timeout()
            await asyncio.sleep(1.0)

    def _check_heartbeat_timeout(self) -> None:
        """The link is lost after heartbeat_timeout_s without a heartbeat read, unless what the vehicle sent is
        still waiting to be read: then this service is behind, and the vehicle may well not be silent."""
        last = self.status.last_heartbeat
        if self._transport is not None and self._transport.backlogged():
            return
        if self.status.connected and last is not None and time.monotonic() - last > self.heartbeat_timeout_s:
            self.status.connected = False
            self._connected_event.clear()

    async def command_long(
        self, command: int, params: Iterable[float] = (), tries: int = COMMAND_TRIES, timeout_s: float = 0.7
    ) -> int:
        """Send COMMAND_LONG to the autopilot and return the MAV_RESULT of its COMMAND_ACK; retries `tries`
        times `timeout_s` apart (wall clock, as MAVSDK) and raises CommandTimeoutError if no ack arrives.
        One command at a time: acknowledgements name only the command, not which request they answer."""
        values = [*params, *[math.nan] * 7][:7]
        async with self._command_lock:
            with self.subscribe({"COMMAND_ACK"}) as acks:
                for attempt in range(tries):
                    self.send(self.encoder.command_long_encode(*self.target, command, attempt, *values))
                    deadline = time.monotonic() + timeout_s
                    while (remaining := deadline - time.monotonic()) > 0:
                        try:
                            async with asyncio.timeout(remaining):
                                ack = await acks.get()
                        except TimeoutError:
                            break
                        if ack.command == command and ack.result != mavlink.MAV_RESULT_IN_PROGRESS:
                            return int(ack.result)
        name = mavlink.enums["MAV_CMD"].get(command)
        raise CommandTimeoutError(
            f"no COMMAND_ACK for {name.name if name else command} after {tries} tries ({self.connection})"
        )

    async def _command(self, what: str, command: int, params: Iterable[float] = ()) -> None:
        heard = self.status.status_texts_heard
        result = await self.command_long(command, params)
        if result != mavlink.MAV_RESULT_ACCEPTED:
            raise await self._refusal(what, result, heard)

    async def _refusal(self, what: str, result: int, heard: int) -> CommandDeniedError:
        """The refusal with what the vehicle said since `heard` (status_texts_heard before the command). PX4 and
        ArduPilot send the cause as a STATUSTEXT beside the COMMAND_ACK, either side of it: wait a moment for it."""
        deadline = time.monotonic() + REFUSAL_TEXT_WAIT_S
        while self.status.status_texts_heard == heard and time.monotonic() < deadline:
            await asyncio.sleep(0.05)
        new = min(self.status.status_texts_heard - heard, len(self.status.status_texts))
        return CommandDeniedError(what, result, tuple(self.status.status_texts[-new:]) if new else ())

    # ----- actions (MAVSDK's Action plugin, per autopilot flavour)
    async def set_mode(self, purpose: str) -> None:
        """Switch to the flavour's mode for "mission", "return", "land", "hold" or "guided"."""
        custom_mode = self.autopilot.custom_mode(purpose)
        base = CUSTOM_MODE_ENABLED | (ARMED_FLAG if self.status.armed else 0)
        if isinstance(self.autopilot, Px4):  # PX4 reads main and sub mode as separate params
            params = [base, (custom_mode >> 16) & 0xFF, (custom_mode >> 24) & 0xFF]
        else:
            params = [base, custom_mode]
        await self._command(f"switch to {self.autopilot.mode_name(custom_mode)}", mavlink.MAV_CMD_DO_SET_MODE, params)

    async def arm(self) -> None:
        """Arm the motors. A retried ARM answered "already armed" (TEMPORARILY_REJECTED) is success once the
        heartbeat shows the vehicle armed."""
        if self.autopilot.takes_off_before_mission:
            await self.set_mode("guided")  # ArduPilot arms for a mission in GUIDED, then takes off there
        heard = self.status.status_texts_heard
        result = await self.command_long(mavlink.MAV_CMD_COMPONENT_ARM_DISARM, [1])
        if result == mavlink.MAV_RESULT_TEMPORARILY_REJECTED:
            deadline = time.monotonic() + ARM_CONFIRM_S
            while time.monotonic() < deadline and not self.status.armed:
                await asyncio.sleep(0.1)
            if self.status.armed:
                return
        if result != mavlink.MAV_RESULT_ACCEPTED:
            raise await self._refusal("arm", result, heard)

    async def disarm(self) -> None:
        await self._command("disarm", mavlink.MAV_CMD_COMPONENT_ARM_DISARM, [0])

    async def takeoff(self, altitude_m: float) -> None:
        await self._command(
            "take off", mavlink.MAV_CMD_NAV_TAKEOFF, [0, 0, 0, math.nan, math.nan, math.nan, altitude_m]
        )

    async def start_mission(self, items: Sequence[MissionItem]) -> None:
        """Fly the uploaded mission (`items` as planned: its takeoff altitude and length are used)."""
        if self.autopilot.takes_off_before_mission:
            takeoff = next((i for i in items if i.command == MavCmd.NAV_TAKEOFF), None)
            altitude = takeoff.z if takeoff is not None else 5.0
            await self.takeoff(altitude)
            deadline = time.monotonic() + TAKEOFF_TIMEOUT_S
            while (self.status.alt_m or 0.0) < 0.9 * altitude:
                if time.monotonic() > deadline:
                    raise LinkError(f"the vehicle did not climb to {altitude:g} m within {TAKEOFF_TIMEOUT_S:g} s")
                await asyncio.sleep(0.1)
            await self.set_mode("mission")
            # ArduCopter DENIES MISSION_START naming a first or last item (handle_MAV_CMD_MISSION_START): 0, 0
            await self._command("start the mission", mavlink.MAV_CMD_MISSION_START, [0, 0])
            return
        try:
            await self.set_mode("mission")
        except CommandDeniedError:
            await self._command("start the mission", mavlink.MAV_CMD_MISSION_START, [0, len(items) - 1])

    async def set_current_item(self, seq: int) -> None:
        """Fly on from mission item `seq` (planned numbering): MAV_CMD_DO_SET_MISSION_CURRENT."""
        vehicle_seq = seq + self.autopilot.mission_offset
        await self._command(f"go to mission item {seq}", mavlink.MAV_CMD_DO_SET_MISSION_CURRENT, [vehicle_seq])

    async def return_to_launch(self) -> None:
        await self._command("return to launch", mavlink.MAV_CMD_NAV_RETURN_TO_LAUNCH)

    async def reset_battery(self, percent: float = 100.0) -> None:
        """Tell the autopilot a fresh pack is in (the first battery, at `percent` charge): MAV_CMD_BATTERY_RESET.
        Autopilots take it only landed and disarmed; a refusal raises CommandDeniedError."""
        if not 0.0 <= percent <= 100.0:
            raise ValueError(f"battery charge must be 0 to 100 %, got {percent}")
        await self._command(f"reset the battery to {percent:g} %", MAV_CMD_BATTERY_RESET, [FIRST_BATTERY_MASK, percent])

    # ----- parameters (MAVSDK's Param plugin)
    async def read_parameters(self, names: Sequence[str], timeout_s: float = 3.0) -> dict[str, float]:
        """{name: value} read from the vehicle, integers decoded as its autopilot encodes them; raises
        ParameterError (a LinkError) naming the parameters that did not answer within timeout_s."""
        return await read_parameters(self, names, timeout_s)

    # ----- missions (MAVSDK's MissionRaw plugin)
    async def upload_mission(self, items: Sequence[MissionItem], home: tuple[float, float, float]) -> None:
        await upload_items(self, self.autopilot.items_for_vehicle(items, home))

    async def download_mission(self) -> list[MissionItem]:
        return self.autopilot.items_from_vehicle(await download_items(self))

    async def upload_fence(self, fence: Geofence) -> None:
        """Give the vehicle this geofence (MISSION_TYPE_FENCE: it enforces it itself, GF_ACTION), kept as `fence`."""
        await upload_items(self, fence.to_items(), mission_type=MissionType.FENCE)
        self.fence = fence

    async def upload_rally_points(self, points: Sequence[tuple[float, float, float]]) -> None:
        """Give the vehicle these rally points (MISSION_TYPE_RALLY; latitude, longitude, altitude above home m)."""
        await upload_items(self, rally_point_items(points), mission_type=MissionType.RALLY)

    async def download_rally_points(self) -> list[MissionItem]:
        """The rally points the vehicle holds (MISSION_TYPE_RALLY), as items."""
        return await download_items(self, mission_type=MissionType.RALLY)

    async def download_fence(self) -> Geofence:
        """The geofence the vehicle holds (MISSION_TYPE_FENCE), kept as `fence` for the planner."""
        self.fence = Geofence.from_items(await download_items(self, mission_type=MissionType.FENCE))
        return self.fence

    # ----- files (MAVSDK's Ftp plugin)
    async def download_file(
        self, path: str, target_component: int = CAMERA_COMPID, max_bytes: int = DEFAULT_MAX_BYTES
    ) -> bytes:
        """The file at `path` (or a camera's "mftp://[;comp=100]/..." URL) on a component of the vehicle, by
        MAVLink FTP; raises FtpError (a LinkError) naming the server's refusal, a file over max_bytes or silence."""
        return await self._ftp.download(path, target_component, max_bytes)

    # ----- receiving
    @contextlib.contextmanager
    def subscribe(self, names: set[str], component: int | None = None) -> Iterator[asyncio.Queue]:
        """A queue receiving every message of these types from the autopilot (or from another `component` of the
        vehicle's system: its camera) while the block runs."""
        entry: tuple[frozenset[str], int | None, asyncio.Queue] = (frozenset(names), component, asyncio.Queue())
        self._queues.append(entry)
        try:
            yield entry[2]
        finally:
            self._queues.remove(entry)

    def add_listener(self, listener: Callable[[Any], None], end_of_chunk: Callable[[], None] | None = None) -> None:
        """Call listener(message) for every message from the vehicle's system, after `status` is updated, and
        end_of_chunk() after each received datagram or stream chunk. Nothing is assumed about what a chunk holds:
        our vehicle sends a tick's messages in one datagram (so `status` is then of one instant), PX4 and
        ArduPilot one message per datagram (then the other fields are the latest received, one stream period
        old at most), a serial or TCP chunk any slice of the stream."""
        self._listeners.append(listener)
        if end_of_chunk is not None:
            self._chunk_ends.append(end_of_chunk)

    def remove_listener(self, listener: Callable[[Any], None], end_of_chunk: Callable[[], None] | None = None) -> None:
        with contextlib.suppress(ValueError):
            self._listeners.remove(listener)
        if end_of_chunk is not None:
            with contextlib.suppress(ValueError):
                self._chunk_ends.remove(end_of_chunk)

    def _received(self, data: bytes, source: object) -> None:
        try:
            if self._transport is not None and self._transport.datagrams:
                messages = parse_datagram(self._parser, data)
            else:
                messages = self._parser.parse_buffer(data) or []
        except Exception:  # pymavlink raises a zoo of errors on hostile input; none may escape
            return
        for message in messages:
            if message.get_type() == "BAD_DATA":
                continue
            if message.get_type() == "HEARTBEAT":
                self._discover(message, source)
            if self.vehicle is None or message.get_srcSystem() != self.vehicle.sysid:
                continue
            self.messages_received += 1
            if message.get_type() == "HEARTBEAT" and message.get_srcComponent() != self.vehicle.compid:
                self.camera.heard(message)
            if message.get_type() == "GLOBAL_POSITION_INT":
                self.positions_received += 1
            self._update(message)
            source = message.get_srcComponent()
            for names, component, queue in self._queues:
                if source == (self.vehicle.compid if component is None else component) and message.get_type() in names:
                    queue.put_nowait(message)
            for listener in list(self._listeners):
                listener(message)
        for end in list(self._chunk_ends):
            end()

    def _discover(self, m: Any, source: object) -> None:
        """Adopt the sender of an autopilot heartbeat as the vehicle if there is none (or the one there was has
        gone silent)."""
        if m.autopilot == mavlink.MAV_AUTOPILOT_INVALID or m.type in NOT_A_VEHICLE:
            return
        if self.sysid is not None and m.get_srcSystem() != self.sysid:
            return  # another vehicle of a fleet on a shared link: its own link takes it
        identity = VehicleIdentity(m.get_srcSystem(), m.get_srcComponent(), m.autopilot, m.type)
        current = self.vehicle
        if current is not None and (current.sysid, current.compid) == (identity.sysid, identity.compid):
            self._reply_to(source)
            return
        if current is not None and self.status.connected:
            return  # another vehicle on the link while ours is alive: not ours (a fleet is not flown here)
        self.vehicle, self.autopilot = identity, autopilot_for(identity.autopilot)
        self.camera.forget()
        self.status = VehicleStatus(
            sysid=identity.sysid,
            compid=identity.compid,
            autopilot=identity.autopilot_name,
            vehicle_type=identity.type_name,
            incarnation=self.status.incarnation + (current is not None),
        )
        self._reply_to(source)
        if current is not None:
            log.warning("vehicle changed: %s -> %s", current, identity)

    def _reply_to(self, source: object) -> None:
        reply_to = getattr(self._transport, "reply_to", None)
        if reply_to is not None:
            reply_to(source)

    def _update(self, m: Any) -> None:
        """Fold one message into `status`. Companion messages (another component of the system) only add their
        estimates."""
        kind, s = m.get_type(), self.status
        if kind == "DEBUG_VECT":
            s.estimates[m.name] = [_finite(m.x), _finite(m.y), _finite(m.z)]
            return
        if kind == "NAMED_VALUE_FLOAT":
            s.estimates[m.name] = _finite(m.value)
            return
        assert self.vehicle is not None  # _received folds only the adopted vehicle's messages
        if m.get_srcComponent() != self.vehicle.compid:
            return
        if kind == "HEARTBEAT":
            s.last_heartbeat = time.monotonic()
            s.base_mode, s.custom_mode = m.base_mode, m.custom_mode
            s.mode = self.autopilot.mode_name(m.custom_mode)
            s.armed = bool(m.base_mode & ARMED_FLAG)
            if not s.connected:
                s.connected = True
                self._connected_event.set()
                self._on_connected()
            return
        boot_ms = getattr(m, "time_boot_ms", None)
        if boot_ms:  # 0 is "not stamped" (MAVSDK's server plugins send SYSTEM_TIME and ATTITUDE with 0)
            if s.time_boot_ms is not None and boot_ms < s.time_boot_ms - REBOOT_BACKSTEP_MS:
                self._rebooted()
            s.time_boot_ms = boot_ms
        if kind == "SYSTEM_TIME":
            if m.time_unix_usec > 0 and m.time_boot_ms > 0:
                instant = m.time_unix_usec / 1e6 - m.time_boot_ms / 1e3
                if s.boot_instant_s is not None and abs(instant - s.boot_instant_s) > BOOT_INSTANT_TOLERANCE_S:
                    self._rebooted()
                self.status.boot_instant_s = instant
        elif kind == "GLOBAL_POSITION_INT":
            s.lat, s.lon, s.alt_m = m.lat * 1e-7, m.lon * 1e-7, m.relative_alt / 1000.0
        elif kind == "LOCAL_POSITION_NED":
            s.north, s.east, s.down, s.vn, s.ve, s.vd = m.x, m.y, m.z, m.vx, m.vy, m.vz
        elif kind == "ATTITUDE":
            s.roll, s.pitch, s.yaw = m.roll, m.pitch, m.yaw
        elif kind == "POSITION_TARGET_LOCAL_NED":
            s.ref_north, s.ref_east, s.ref_down = _finite(m.x), _finite(m.y), _finite(m.z)
            s.ref_yaw = _finite(m.yaw)
        elif kind == "EXTENDED_SYS_STATE":
            s.landed_state = m.landed_state
        elif kind == "BATTERY_STATUS" and m.id == 0:
            s.battery_status_seen = True
            s.battery_remaining_pct = _known(m.battery_remaining, -1)
            s.battery_voltage_v = _pack_voltage_v(m)
            s.battery_current_a = _known(m.current_battery, -1, 100)  # cA
            s.battery_consumed_wh = _known(m.energy_consumed, -1, 36)  # hJ: 36 hJ = 1 Wh
            s.battery_charge_state = m.charge_state or None  # 0: MAV_BATTERY_CHARGE_STATE_UNDEFINED
        elif kind == "SYS_STATUS" and not s.battery_status_seen:
            s.battery_remaining_pct = _known(m.battery_remaining, -1)
            s.battery_voltage_v = _known(m.voltage_battery, UINT16_MAX, 1000)  # mV
            s.battery_current_a = _known(m.current_battery, -1, 100)  # cA
        elif kind == "MISSION_CURRENT":
            s.mission_seq = self.autopilot.planned_seq(m.seq)
            s.mission_total = m.total  # MAVLink: "a home stored as part of the mission is excluded from the total"
            s.mission_state = m.mission_state
        elif kind == "HOME_POSITION":
            s.home = (m.latitude * 1e-7, m.longitude * 1e-7, m.altitude / 1000.0)
        elif kind == "STATUSTEXT":
            s.status_texts = [*s.status_texts[1 - STATUS_TEXTS_KEPT :], statustext(m)]
            s.status_severities = [*s.status_severities[1 - STATUS_TEXTS_KEPT :], int(m.severity)]
            s.status_texts_heard += 1

    def _rebooted(self) -> None:
        s = self.status
        s.reboots += 1
        s.incarnation += 1
        s.mission_seq = s.mission_total = s.mission_state = None
        s.home = None
        s.boot_instant_s = None
        self._on_connected()

    def _on_connected(self) -> None:
        """A vehicle (or a new boot of it) is here: ask for home and for the streams the service reads."""
        # REQUEST_MESSAGE(HOME_POSITION); its ack is not awaited: HOME_POSITION itself is the answer
        self.send(
            self.encoder.command_long_encode(
                *self.target, mavlink.MAV_CMD_REQUEST_MESSAGE, 0, mavlink.MAVLINK_MSG_ID_HOME_POSITION, *[math.nan] * 6
            )
        )
        self.fence = None
        self._tasks = [t for t in self._tasks if not t.done()]
        if not any(t.get_name() == "gcs-streams" for t in self._tasks):  # one request round at a time
            self._tasks.append(asyncio.create_task(self._request_streams(), name="gcs-streams"))

    async def _request_streams(self) -> None:
        """SET_MESSAGE_INTERVAL for each stream; ArduPilot also gets REQUEST_DATA_STREAM (its classic way)."""
        refused = False
        for name, rate_hz in STREAMS.items():
            msg_id = getattr(mavlink, f"MAVLINK_MSG_ID_{name}")
            try:
                result = await self.command_long(mavlink.MAV_CMD_SET_MESSAGE_INTERVAL, [msg_id, 1e6 / rate_hz], tries=2)
            except CommandTimeoutError:
                result = None
            refused = refused or result != mavlink.MAV_RESULT_ACCEPTED
        if refused and self.autopilot.streams_by_data_stream_request:
            self.send(self.encoder.request_data_stream_encode(*self.target, mavlink.MAV_DATA_STREAM_ALL, 10, 1))
        await self._read_battery_thresholds()

    async def _read_battery_thresholds(self) -> None:
        """The levels at which the vehicle itself warns of its battery, for the page's badge: PX4's BAT_LOW_THR and
        BAT_CRIT_THR (fractions). An autopilot without them (ArduPilot counts mAh and volts) leaves them unknown,
        and the badge shows the vehicle's own charge state alone."""
        try:
            values = await self.read_parameters(BATTERY_THRESHOLDS)
        except (LinkError, TimeoutError):
            return
        self.status.battery_low_pct = 100.0 * values["BAT_LOW_THR"]
        self.status.battery_critical_pct = 100.0 * values["BAT_CRIT_THR"]
