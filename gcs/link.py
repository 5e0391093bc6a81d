"""The MAVLink link manager: the one owner of the GCS's connection to the vehicle (asyncio, UDP).

Why pymavlink and not MAVSDK: the service is one Python process on one asyncio loop, and pymavlink is only a
message codec, so it needs no gRPC `mavsdk_server` beside it, and it gives full access to every message the
vehicle and the offboard controller publish (DEBUG_VECT, NAMED_VALUE_FLOAT, POSITION_TARGET_LOCAL_NED), which
MAVSDK's plugins do not expose. The socket is a non-blocking asyncio datagram endpoint; pymavlink only packs
and parses bytes.

What it does: sends the GCS heartbeat at 1 Hz (sysid 255, compid 190, type GCS); keeps `status`, the latest
vehicle state; detects link loss (no heartbeat for `heartbeat_timeout_s`, wall clock) and vehicle restarts
(`time_boot_ms` going backwards), and reconnects by itself since every datagram it sends makes it the
vehicle's peer again; sends COMMAND_LONG with acknowledgement and retries; hands chosen messages to
subscribers (the mission protocol, the recorder) through queues and listeners. With a signing key it signs
every message it sends (MAVLink 2 message signing) and accepts only signed messages, as a keyed vehicle does.
"""

from __future__ import annotations

import asyncio
import contextlib
import math
import socket
import time
from collections.abc import Callable, Iterable, Iterator
from dataclasses import dataclass, field
from typing import Any

from uavcore.mavlink import (
    AUTOPILOT_COMPID,
    GCS_COMPID,
    GCS_SYSID,
    VEHICLE_SYSID,
    Encoder,
    mavlink,
    new_parser,
    parse_datagram,
    statustext,
)
from uavcore.modes import px4_mode_name

RECEIVE_BUFFER_BYTES = 4 << 20
# At 20 % datagram loss each way a command's round trip fails 36 % of the time: 3 tries (MAVSDK's) leave a 5 %
# chance per command of giving up on a healthy vehicle, 6 tries 0.2 %.
COMMAND_TRIES = 6
REBOOT_BACKSTEP_MS = 1000  # time_boot_ms falling by more than this means the vehicle restarted
STATUS_TEXTS_KEPT = 10
ON_GROUND = mavlink.MAV_LANDED_STATE_ON_GROUND
ARMED_FLAG = mavlink.MAV_MODE_FLAG_SAFETY_ARMED


class LinkError(RuntimeError):
    """The vehicle did not answer or cannot be reached; the message says what was asked."""


class CommandTimeoutError(LinkError):
    pass


def parse_udpout(url: str) -> tuple[str, int]:
    """`udpout:HOST:PORT` (or `udpout://HOST:PORT`) -> (host, port); the only form the service speaks."""
    scheme, _, rest = url.partition(":")
    rest = rest.removeprefix("//")
    host, _, port = rest.rpartition(":")
    if scheme != "udpout" or not host or not port.isdigit() or not 0 < int(port) < 65536:
        raise ValueError(f"vehicle connection {url!r}: expected udpout:HOST:PORT, e.g. udpout:127.0.0.1:14540")
    return host, int(port)


@dataclass
class VehicleStatus:
    """The latest state the vehicle reported. Positions NED metres from home; angles radians."""

    connected: bool = False
    last_heartbeat: float | None = None  # time.monotonic()
    reboots: int = 0
    armed: bool = False
    base_mode: int = 0
    custom_mode: int = 0
    landed_state: int | None = None
    time_boot_ms: int | None = None
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
    home: tuple[float, float, float] | None = None
    estimates: dict[str, Any] = field(default_factory=dict)  # the offboard controller's ESO outputs by name
    status_texts: list[str] = field(default_factory=list)  # the vehicle's latest STATUSTEXTs, oldest first

    @property
    def mode(self) -> str:
        return px4_mode_name(self.custom_mode)

    def as_dict(self) -> dict[str, Any]:
        age = None if self.last_heartbeat is None else time.monotonic() - self.last_heartbeat
        data = {k: v for k, v in self.__dict__.items() if k not in ("last_heartbeat", "home")}
        data["heartbeat_age_s"] = age
        data["mode"] = self.mode if self.connected else None
        data["home"] = None if self.home is None else {"lat": self.home[0], "lon": self.home[1], "alt": self.home[2]}
        data["t_s"] = None if self.time_boot_ms is None else self.time_boot_ms / 1000.0
        return data


def _finite(value: float) -> float | None:
    return float(value) if math.isfinite(value) else None


class _Protocol(asyncio.DatagramProtocol):
    def __init__(self, link: LinkManager) -> None:
        self.link = link

    def datagram_received(self, data: bytes, addr: tuple[str, int]) -> None:
        self.link._datagram(data)

    def error_received(self, exc: Exception) -> None:
        # ICMP port unreachable while no vehicle listens: expected, the heartbeat watchdog reports it
        pass


class LinkManager:
    """Owns the UDP socket to the vehicle. Create, `await start()`, use, `await stop()`."""

    def __init__(
        self, url: str = "udpout:127.0.0.1:14540", heartbeat_timeout_s: float = 3.0, signing_key: bytes | None = None
    ) -> None:
        self.address = parse_udpout(url)
        self.heartbeat_timeout_s = heartbeat_timeout_s
        self.status = VehicleStatus()
        self._encoder = Encoder(GCS_SYSID, GCS_COMPID, signing_key)
        self.encoder = self._encoder.mav  # builds messages: link.encoder.command_long_encode(...)
        self._parser = new_parser(GCS_SYSID, GCS_COMPID, signing_key)
        self.signing_key = signing_key
        self._transport: asyncio.DatagramTransport | None = None
        self._tasks: list[asyncio.Task] = []
        self._queues: list[tuple[frozenset[str], asyncio.Queue]] = []
        self._listeners: list[Callable[[Any], None]] = []
        self._datagram_ends: list[Callable[[], None]] = []
        self._connected_event = asyncio.Event()
        self.messages_received = 0

    # ----- lifecycle
    async def start(self) -> None:
        loop = asyncio.get_running_loop()
        self._connected_event = asyncio.Event()
        self._transport, _ = await loop.create_datagram_endpoint(lambda: _Protocol(self), remote_addr=self.address)
        sock = self._transport.get_extra_info("socket")
        # a vehicle in lockstep sends bursts faster than real time: a larger buffer rides out a busy loop
        sock.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, RECEIVE_BUFFER_BYTES)
        self._tasks = [asyncio.create_task(self._heartbeat_loop(), name="gcs-heartbeat")]

    async def stop(self) -> None:
        for task in self._tasks:
            task.cancel()
        for task in self._tasks:
            with contextlib.suppress(asyncio.CancelledError):
                await task
        self._tasks = []
        if self._transport is not None:
            self._transport.close()
            self._transport = None

    async def wait_connected(self, timeout_s: float) -> bool:
        """True once the vehicle's heartbeat is seen, False after timeout_s without one."""
        if self.status.connected:
            return True
        try:
            await asyncio.wait_for(self._connected_event.wait(), timeout_s)
        except TimeoutError:
            return False
        return self.status.connected

    # ----- sending
    def send(self, message: Any) -> None:
        if self._transport is None:
            raise LinkError("the link is not started")
        self._transport.sendto(self._encoder.pack(message))

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
        last = self.status.last_heartbeat
        if self.status.connected and last is not None and time.monotonic() - last > self.heartbeat_timeout_s:
            self.status.connected = False
            self._connected_event.clear()

    async def command_long(
        self, command: int, params: Iterable[float] = (), tries: int = COMMAND_TRIES, timeout_s: float = 0.7
    ) -> int:
        """Send COMMAND_LONG to the autopilot and return the MAV_RESULT of its COMMAND_ACK; retries `tries`
        times `timeout_s` apart (wall clock, as MAVSDK) and raises CommandTimeoutError if no ack arrives."""
        values = [*params, *[math.nan] * 7][:7]
        with self.subscribe({"COMMAND_ACK"}) as acks:
            for attempt in range(tries):
                self.send(self.encoder.command_long_encode(VEHICLE_SYSID, AUTOPILOT_COMPID, command, attempt, *values))
                deadline = time.monotonic() + timeout_s
                while (remaining := deadline - time.monotonic()) > 0:
                    try:
                        ack = await asyncio.wait_for(acks.get(), remaining)
                    except TimeoutError:
                        break
                    if ack.command == command and ack.result != mavlink.MAV_RESULT_IN_PROGRESS:
                        return int(ack.result)
        raise CommandTimeoutError(f"no COMMAND_ACK for command {command} after {tries} tries")

    # ----- receiving
    @contextlib.contextmanager
    def subscribe(self, names: set[str]) -> Iterator[asyncio.Queue]:
        """A queue receiving every message of these types from the autopilot while the block runs."""
        entry = (frozenset(names), asyncio.Queue())
        self._queues.append(entry)
        try:
            yield entry[1]
        finally:
            self._queues.remove(entry)

    def add_listener(self, listener: Callable[[Any], None], end_of_datagram: Callable[[], None] | None = None) -> None:
        """Call listener(message) for every message from the vehicle's system, after `status` is updated, and
        end_of_datagram() once every message of a datagram is in `status`. The vehicle sends what one tick
        produced as one datagram, so only then do position, reference and attitude in `status` belong to the
        same instant (reading them on the first message of a tick pairs it with the previous tick's rest)."""
        self._listeners.append(listener)
        if end_of_datagram is not None:
            self._datagram_ends.append(end_of_datagram)

    def remove_listener(
        self, listener: Callable[[Any], None], end_of_datagram: Callable[[], None] | None = None
    ) -> None:
        with contextlib.suppress(ValueError):
            self._listeners.remove(listener)
        with contextlib.suppress(ValueError):
            self._datagram_ends.remove(end_of_datagram)

    def _datagram(self, data: bytes) -> None:
        try:
            messages = parse_datagram(self._parser, data)
        except Exception:  # pymavlink raises a zoo of errors on hostile input; none may escape
            return
        for message in messages:
            if message.get_type() == "BAD_DATA" or message.get_srcSystem() != VEHICLE_SYSID:
                continue
            self.messages_received += 1
            self._update(message)
            if message.get_srcComponent() == AUTOPILOT_COMPID:
                for names, queue in self._queues:
                    if message.get_type() in names:
                        queue.put_nowait(message)
            for listener in list(self._listeners):
                listener(message)
        for end in list(self._datagram_ends):
            end()

    def _update(self, m: Any) -> None:
        """Fold one message into `status`. Offboard-controller messages only add their estimates."""
        kind, s = m.get_type(), self.status
        if kind == "DEBUG_VECT":
            s.estimates[m.name] = [_finite(m.x), _finite(m.y), _finite(m.z)]
            return
        if kind == "NAMED_VALUE_FLOAT":
            s.estimates[m.name] = _finite(m.value)
            return
        if m.get_srcComponent() != AUTOPILOT_COMPID:
            return
        if kind == "HEARTBEAT":
            s.last_heartbeat = time.monotonic()
            s.base_mode, s.custom_mode = m.base_mode, m.custom_mode
            s.armed = bool(m.base_mode & ARMED_FLAG)
            if not s.connected:
                s.connected = True
                self._connected_event.set()
                self._request_home()
            return
        boot_ms = getattr(m, "time_boot_ms", None)
        if boot_ms is not None:
            if s.time_boot_ms is not None and boot_ms < s.time_boot_ms - REBOOT_BACKSTEP_MS:
                self._rebooted()
            s.time_boot_ms = boot_ms
        if kind == "GLOBAL_POSITION_INT":
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
        elif kind == "MISSION_CURRENT":
            s.mission_seq, s.mission_total = m.seq, m.total
            s.mission_state = m.mission_state
        elif kind == "HOME_POSITION":
            s.home = (m.latitude * 1e-7, m.longitude * 1e-7, m.altitude / 1000.0)
        elif kind == "STATUSTEXT":
            s.status_texts = [*s.status_texts[1 - STATUS_TEXTS_KEPT :], statustext(m)]

    def _rebooted(self) -> None:
        s = self.status
        s.reboots += 1
        s.mission_seq = s.mission_total = s.mission_state = None
        s.home = None
        self._request_home()

    def _request_home(self) -> None:
        # REQUEST_MESSAGE(HOME_POSITION); its ack is not awaited: HOME_POSITION itself is the answer
        self.send(
            self.encoder.command_long_encode(
                VEHICLE_SYSID,
                AUTOPILOT_COMPID,
                mavlink.MAV_CMD_REQUEST_MESSAGE,
                0,
                mavlink.MAVLINK_MSG_ID_HOME_POSITION,
                *[math.nan] * 6,
            )
        )
