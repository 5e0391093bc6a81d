"""A scripted ArduPilot Copter for testing the ground station's ArduPilot flavour (no SITL binary installs here).

The double speaks MAVLink 2 over one UDP socket from a thread, and behaves as ArduCopter does where the ground
station depends on it. What it copies, and where from (ArduPilot/ardupilot sources, read with the search tool):

- Identity and modes (GCS_MAVLink_Copter.cpp `base_mode()`, `custom_mode()`; ArduCopter/mode.h `Mode::Number`):
  HEARTBEAT autopilot ARDUPILOTMEGA, type QUADROTOR, custom_mode = the Copter mode number (STABILIZE 0, AUTO 3,
  GUIDED 4, LOITER 5, RTL 6, LAND 9), base_mode CUSTOM_MODE_ENABLED, plus SAFETY_ARMED when armed.
- Streams (GCS_Common.cpp `handle_request_data_stream`; the Copter stream tables in GCS_Mavlink.cpp): nothing is
  streamed until REQUEST_DATA_STREAM; MAV_DATA_STREAM_ALL sets every group's rate. POSITION = GLOBAL_POSITION_INT +
  LOCAL_POSITION_NED, EXTENDED_STATUS = SYS_STATUS + MISSION_CURRENT, EXTRA1 = ATTITUDE, EXTRA3 = SYSTEM_TIME.
  SET_MESSAGE_INTERVAL and REQUEST_MESSAGE are answered MAV_RESULT_UNSUPPORTED, as firmware older than those
  commands does (the default branch of `handle_command_int_packet`), so a test can prove the link's fallback.
  The double's own choice: EXTENDED_SYS_STATE (ArduPilot implements it; the tables read do not list it) and
  HOME_POSITION (ArduPilot sends it when home is set, which a GCS joining later misses) ride in EXTRA3.
- Mission (AP_Mission `read_cmd_from_storage`: "special handling for command #0 which is home"): the upload
  protocol MISSION_COUNT -> MISSION_REQUEST_INT -> MISSION_ITEM_INT -> MISSION_ACK stores what it gets, but a
  download serves item 0 as the vehicle's home (MAV_CMD_NAV_WAYPOINT, frame GLOBAL, altitude AMSL).
  MISSION_CURRENT (GCS_Common.cpp `send_mission_current`) carries the vehicle's numbering and
  total = number of items excluding home, with mission_state; MISSION_ITEM_REACHED is sent when an item completes
  (ModeAuto::verify_command_callback); do-commands complete at once.
- Commands (GCS_MAVLink_Copter.cpp `handle_command_int_packet` and the handlers it calls):
  DO_SET_MODE param2 = custom mode; COMPONENT_ARM_DISARM arms only in modes that allow arming (AUTO does not
  unless AUTO_OPTIONS allows it: ModeAuto::allows_arming; RTL and LAND never); NAV_TAKEOFF param7 = altitude
  above home, accepted only when armed, landed and in a mode with a user takeoff (Mode::do_user_takeoff);
  MISSION_START is DENIED when param1 or param2 (first/last item) is not 0, else switches to AUTO and starts the
  mission (handle_MAV_CMD_MISSION_START); NAV_RETURN_TO_LAUNCH and NAV_LAND switch to RTL and LAND;
  DO_SET_MISSION_CURRENT (AP_Mission::set_current_cmd) moves the current item, which a stopped mission resumes
  from when AUTO is entered again.
- AUTO (mode_auto.cpp): entering it needs more than the home item (ModeAuto::init); items 1.. fly in order;
  at the end (ModeAuto::exit_mission) a landed vehicle disarms, a flying one switches to LOITER.
  RTL and LAND descend and disarm once landed (ModeLand::gps_run "disarm when the landing detector says we've
  landed").

What it simplifies: kinematics are straight lines in wall-clock time at `speed_m_s` horizontally and fixed climb
and descent rates (DO_CHANGE_SPEED is recorded, not obeyed, so a test runs fast); RTL climbs to `rtl_altitude_m`,
flies home and lands without RTL_LOIT_TIME; no auto-disarm on the ground, no failsafes, no parameters.

    with ArduCopterDouble(gcs_port, items_out=path) as vehicle: ...

The items an upload delivered are written to `items_out` as JSON (one object of `MissionItem` fields each), and
`mode_history`, `set_message_interval_refusals`, `data_stream_requests` and `current_requests` record what the
double was asked.
"""

from __future__ import annotations

import contextlib
import dataclasses
import enum
import json
import math
import socket
import threading
import time
from pathlib import Path
from typing import Any

from uavcore.geodesy import DEFAULT_HOME, LocalFrame
from uavcore.mavlink import (
    AUTOPILOT_COMPID,
    VEHICLE_SYSID,
    Encoder,
    item_from_message,
    item_message,
    mavlink,
    new_parser,
    parse_datagram,
)
from uavcore.mission import MavCmd, MavFrame, MissionItem

TICK_S = 0.02  # kinematics and socket polling at 50 Hz
HEARTBEAT_PERIOD_S = 1.0
UPLOAD_RETRY_S = 0.5  # re-ask for a mission item the ground station did not send
ARRIVED_M = 0.01
MISSION = mavlink.MAV_MISSION_TYPE_MISSION  # the only mission type the double keeps (no fence, no rally points)


class CopterMode(enum.IntEnum):
    """ArduCopter/mode.h Mode::Number (the ones the double flies)."""

    STABILIZE = 0
    ALT_HOLD = 2
    AUTO = 3
    GUIDED = 4
    LOITER = 5
    RTL = 6
    LAND = 9
    POSHOLD = 16


ARMABLE = {CopterMode.STABILIZE, CopterMode.ALT_HOLD, CopterMode.GUIDED, CopterMode.LOITER, CopterMode.POSHOLD}
USER_TAKEOFF = {CopterMode.ALT_HOLD, CopterMode.GUIDED, CopterMode.LOITER, CopterMode.POSHOLD}
GUIDED_FLAG_MODES = {CopterMode.AUTO, CopterMode.GUIDED, CopterMode.LOITER, CopterMode.RTL, CopterMode.POSHOLD}

# REQUEST_DATA_STREAM groups -> what the double sends in each (see the module docstring)
STREAM_GROUPS: dict[int, tuple[str, ...]] = {
    mavlink.MAV_DATA_STREAM_EXTENDED_STATUS: ("SYS_STATUS", "MISSION_CURRENT"),
    mavlink.MAV_DATA_STREAM_POSITION: ("GLOBAL_POSITION_INT", "LOCAL_POSITION_NED"),
    mavlink.MAV_DATA_STREAM_EXTRA1: ("ATTITUDE",),
    mavlink.MAV_DATA_STREAM_EXTRA3: ("SYSTEM_TIME", "EXTENDED_SYS_STATE", "HOME_POSITION"),
}


@dataclasses.dataclass
class Target:
    """Where the vehicle is flying to: north/east metres from home (None = stay), altitude above home."""

    north: float | None
    east: float | None
    alt: float


class ArduCopterDouble:
    """The vehicle, its mission and its MAVLink endpoint; `start()` runs it in a thread, `stop()` ends it."""

    def __init__(
        self,
        gcs_port: int,
        items_out: Path | None = None,
        home: tuple[float, float, float] = DEFAULT_HOME,
        speed_m_s: float = 40.0,
        climb_m_s: float = 5.0,
        descent_m_s: float = 3.0,
        rtl_altitude_m: float = 15.0,
    ) -> None:
        self.gcs_address = ("127.0.0.1", gcs_port)
        self.items_out = items_out
        self.home = home
        self.frame = LocalFrame(*home)
        self.speed_m_s, self.climb_m_s, self.descent_m_s = speed_m_s, climb_m_s, descent_m_s
        self.rtl_altitude_m = rtl_altitude_m
        self.encoder = Encoder(VEHICLE_SYSID, AUTOPILOT_COMPID)
        self.parser = new_parser(VEHICLE_SYSID, AUTOPILOT_COMPID)
        self.socket = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self.socket.bind(("127.0.0.1", 0))
        self.socket.settimeout(TICK_S)
        self.boot = time.monotonic()
        self.boot_unix_s = time.time()
        # vehicle state
        self.mode = CopterMode.STABILIZE
        self.armed = False
        self.silent = False  # True: it sends nothing (heard again once False)
        self.north = self.east = self.alt = 0.0
        self.velocity = (0.0, 0.0, 0.0)  # north, east, up m/s
        self.yaw = 0.0
        self.landed = True
        self.target: Target | None = None  # GUIDED takeoff, AUTO item, RTL or LAND goal
        self.rtl_phase: str | None = None  # "climb", "return", "land" while returning
        # mission: items as the vehicle stores them (item 0 = home)
        self.mission: list[MissionItem] = []
        self.mission_state = mavlink.MISSION_STATE_NO_MISSION
        self.current_seq = 0
        self.hold_until: float | None = None  # a waypoint's hold time ends (monotonic)
        self.upload: dict[int, MissionItem] | None = None
        self.upload_count = 0
        self.uploader = (0, 0)  # (system, component) of the ground station uploading
        self.upload_asked_at = 0.0
        # what the test reads
        self.received_items: list[MissionItem] = []
        self.mode_history: list[str] = [self.mode.name]
        self.set_message_interval_refusals = 0
        self.data_stream_requests: list[tuple[int, int, int]] = []  # (stream id, rate Hz, start/stop)
        self.requested_speed_m_s: float | None = None
        self.current_requests: list[int] = []  # DO_SET_MISSION_CURRENT's items, in the vehicle's numbering
        self.stream_rates: dict[int, float] = {}
        self.next_stream_at: dict[int, float] = {}
        self.next_heartbeat_at = 0.0
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, name="ardupilot-double", daemon=True)

    # ----- running
    def start(self) -> ArduCopterDouble:
        self._thread.start()
        return self

    def stop(self) -> None:
        self._stop.set()
        self._thread.join(10)
        self.socket.close()

    def __enter__(self) -> ArduCopterDouble:
        return self.start()

    def __exit__(self, *exc: object) -> None:
        self.stop()

    def _run(self) -> None:
        last = time.monotonic()
        while not self._stop.is_set():
            self._receive()
            now = time.monotonic()
            self._fly(now - last, now)
            last = now
            self._publish(now)

    def _receive(self) -> None:
        try:
            data = self.socket.recv(65535)
        except (TimeoutError, ConnectionRefusedError):  # nothing yet, or the GCS port is not open yet
            return
        for message in parse_datagram(self.parser, data):
            target = getattr(message, "target_system", VEHICLE_SYSID)
            if message.get_type() != "BAD_DATA" and target in (0, VEHICLE_SYSID):
                self._handle(message)

    def send(self, message: Any) -> None:
        if self.silent:  # a vehicle out of radio range: nothing reaches the ground station
            return
        with contextlib.suppress(OSError):  # the ground station is not listening (yet): dropped, as on a radio
            self.socket.sendto(self.encoder.pack(message), self.gcs_address)

    @property
    def time_boot_ms(self) -> int:
        return int((time.monotonic() - self.boot) * 1000)

    # ----- modes
    def set_mode(self, mode: int) -> bool:
        """Copter::set_mode: False when the mode is unknown or refuses to start (the mode stays)."""
        try:
            new = CopterMode(mode)
        except ValueError:
            return False
        if new == CopterMode.AUTO and len(self.mission) <= 1:  # ModeAuto::init: needs more than home
            return False
        if new == self.mode:
            return True
        if self.mode == CopterMode.AUTO and self.mission_state == mavlink.MISSION_STATE_ACTIVE:
            self.mission_state = mavlink.MISSION_STATE_NOT_STARTED  # ModeAuto::exit stops the mission
        self.mode = new
        self.mode_history.append(new.name)
        self.target, self.rtl_phase = None, None
        if new == CopterMode.AUTO and self.armed and not self.landed:
            self._start_mission()  # ModeAuto::run starts or resumes the mission
        elif new == CopterMode.RTL:
            self.rtl_phase = "climb"
        return True

    def _start_mission(self) -> None:
        if self.mission_state == mavlink.MISSION_STATE_ACTIVE:
            return
        if self.mission_state != mavlink.MISSION_STATE_NOT_STARTED or self.current_seq < 1:
            self.current_seq = 1  # a new or completed mission starts from its first item after home
        self.mission_state = mavlink.MISSION_STATE_ACTIVE
        self._begin_item()

    # ----- messages from the ground station
    def _handle(self, m: Any) -> None:
        kind = m.get_type()
        if kind == "COMMAND_LONG":
            result = self._command(m.command, [m.param1, m.param2, m.param3, m.param4, m.param5, m.param6, m.param7])
            ack = self.encoder.mav.command_ack_encode(m.command, result, 0, 0, m.get_srcSystem(), m.get_srcComponent())
            self.send(ack)
        elif kind == "REQUEST_DATA_STREAM":
            self._request_data_stream(m)
        elif kind == "MISSION_COUNT" and m.mission_type == MISSION:
            self.upload, self.upload_count = {}, m.count
            self.uploader = (m.get_srcSystem(), m.get_srcComponent())
            if m.count:
                self._ask_next_item()
            else:
                self._store_mission([])
        elif kind == "MISSION_ITEM_INT" and self.upload is not None:
            if m.seq == len(self.upload):
                self.upload[m.seq] = item_from_message(m)
            if len(self.upload) == self.upload_count:
                self._store_mission([self.upload[seq] for seq in range(self.upload_count)])
            else:
                self._ask_next_item()
        elif kind == "MISSION_REQUEST_LIST" and m.mission_type == MISSION:
            self.send(self.encoder.mav.mission_count_encode(m.get_srcSystem(), m.get_srcComponent(), len(self.mission)))
        elif kind == "MISSION_REQUEST_INT" and m.mission_type == MISSION and m.seq < len(self.mission):
            self.send(item_message(self._stored_item(m.seq), m.get_srcSystem(), m.get_srcComponent()))

    def _ask_next_item(self) -> None:
        self.upload_asked_at = time.monotonic()
        self.send(self.encoder.mav.mission_request_int_encode(*self.uploader, len(self.upload)))

    def _store_mission(self, items: list[MissionItem]) -> None:
        """A completed upload replaces the mission (stopped, from the start), as AP_Mission's does."""
        self.upload = None
        self.received_items = list(items)
        self.mission = list(items)
        self.mission_state = mavlink.MISSION_STATE_NOT_STARTED if len(items) > 1 else mavlink.MISSION_STATE_NO_MISSION
        self.current_seq = 0
        if self.items_out is not None:
            self.items_out.write_text(json.dumps([dataclasses.asdict(item) for item in items]))
        self.send(self.encoder.mav.mission_ack_encode(*self.uploader, mavlink.MAV_MISSION_ACCEPTED))

    def _stored_item(self, seq: int) -> MissionItem:
        """What a download serves: item 0 is the vehicle's home, whatever was uploaded there."""
        if seq > 0:
            return self.mission[seq]
        lat, lon, alt = self.home
        return MissionItem(
            seq=0, frame=MavFrame.GLOBAL, command=MavCmd.NAV_WAYPOINT, x=round(lat * 1e7), y=round(lon * 1e7), z=alt
        )

    def _request_data_stream(self, m: Any) -> None:
        self.data_stream_requests.append((m.req_stream_id, m.req_message_rate, m.start_stop))
        if m.start_stop not in (0, 1):
            return
        rate = float(m.req_message_rate) if m.start_stop == 1 else 0.0
        groups = STREAM_GROUPS if m.req_stream_id == mavlink.MAV_DATA_STREAM_ALL else [m.req_stream_id]
        for group in groups:
            if group in STREAM_GROUPS:
                self.stream_rates[group] = rate

    def _command(self, command: int, p: list[float]) -> int:
        if command == mavlink.MAV_CMD_SET_MESSAGE_INTERVAL:
            self.set_message_interval_refusals += 1
            return mavlink.MAV_RESULT_UNSUPPORTED
        if command == mavlink.MAV_CMD_DO_SET_MODE:
            if not int(p[0]) & mavlink.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED:
                return mavlink.MAV_RESULT_UNSUPPORTED
            return self._result(self.set_mode(int(p[1])))
        if command == mavlink.MAV_CMD_COMPONENT_ARM_DISARM:
            return self._result(self._arm() if p[0] == 1 else self._disarm())
        if command == mavlink.MAV_CMD_NAV_TAKEOFF:
            return self._result(self._user_takeoff(p[6]))
        if command == mavlink.MAV_CMD_MISSION_START:
            if p[0] != 0 or p[1] != 0:  # "first-item/last item not supported"
                return mavlink.MAV_RESULT_DENIED
            if not self.set_mode(CopterMode.AUTO):
                return mavlink.MAV_RESULT_FAILED
            if self.armed and not self.landed:
                self._start_mission()
            return mavlink.MAV_RESULT_ACCEPTED
        if command == mavlink.MAV_CMD_DO_SET_MISSION_CURRENT:
            return self._result(self._set_current(int(p[0])))
        if command == mavlink.MAV_CMD_NAV_RETURN_TO_LAUNCH:
            return self._result(self.set_mode(CopterMode.RTL))
        if command == mavlink.MAV_CMD_NAV_LAND:
            return self._result(self.set_mode(CopterMode.LAND))
        return mavlink.MAV_RESULT_UNSUPPORTED  # REQUEST_MESSAGE included: older firmware

    def _set_current(self, seq: int) -> bool:
        """AP_Mission::set_current_cmd: a running mission flies from `seq` now; a stopped one starts there when AUTO
        resumes it (MIS_RESTART 0). Home (item 0) and items past the end are refused."""
        self.current_requests.append(seq)
        if not 0 < seq < len(self.mission):
            return False
        self.current_seq = seq
        if self.mode == CopterMode.AUTO and self.mission_state == mavlink.MISSION_STATE_ACTIVE:
            self._begin_item()
        return True

    @staticmethod
    def _result(success: bool) -> int:
        return mavlink.MAV_RESULT_ACCEPTED if success else mavlink.MAV_RESULT_FAILED

    def _arm(self) -> bool:
        if self.armed:
            return True
        if self.mode not in ARMABLE:
            return False
        self.armed = True
        return True

    def _disarm(self) -> bool:
        if self.armed and not self.landed:
            return False  # the double disarms only on the ground (no forced disarm)
        self.armed = False
        return True

    def _user_takeoff(self, altitude_m: float) -> bool:
        """Mode::do_user_takeoff: armed, landed, a mode with a user takeoff, a target above the vehicle."""
        if not (self.armed and self.landed and self.mode in USER_TAKEOFF and altitude_m > self.alt):
            return False
        self.landed = False
        self.target = Target(None, None, altitude_m)
        return True

    # ----- flying
    def _fly(self, dt: float, now: float) -> None:
        if self.upload is not None and now - self.upload_asked_at > UPLOAD_RETRY_S:
            self._ask_next_item()
        if not self.armed or self.landed:
            self.velocity = (0.0, 0.0, 0.0)
            return
        if self.mode == CopterMode.AUTO and self.mission_state == mavlink.MISSION_STATE_ACTIVE:
            self._fly_mission(dt, now)
        elif self.mode == CopterMode.RTL:
            if self._fly_home(dt):
                self._touch_down()
        elif self.mode == CopterMode.LAND:
            if self._move(Target(None, None, 0.0), dt):
                self._touch_down()
        elif self.target is not None:
            self._move(self.target, dt)
        else:
            self.velocity = (0.0, 0.0, 0.0)

    def _touch_down(self) -> None:
        """The landing detector says landed: RTL and LAND disarm (ModeLand::gps_run)."""
        self.landed, self.alt, self.velocity = True, 0.0, (0.0, 0.0, 0.0)
        if self.mode in (CopterMode.RTL, CopterMode.LAND):
            self.armed = False

    def _move(self, target: Target, dt: float) -> bool:
        """One step towards target in a straight line; True once there."""
        north = self.north if target.north is None else target.north
        east = self.east if target.east is None else target.east
        d_north, d_east, d_up = north - self.north, east - self.east, target.alt - self.alt
        horizontal = math.hypot(d_north, d_east)
        step_h = min(horizontal, self.speed_m_s * dt)
        rate_v = self.climb_m_s if d_up > 0 else self.descent_m_s
        step_v = math.copysign(min(abs(d_up), rate_v * dt), d_up)
        if horizontal > 0:
            self.north += d_north / horizontal * step_h
            self.east += d_east / horizontal * step_h
            self.yaw = math.atan2(d_east, d_north)
        self.alt += step_v
        self.velocity = (
            (d_north / horizontal * step_h / dt) if horizontal > 0 and dt > 0 else 0.0,
            (d_east / horizontal * step_h / dt) if horizontal > 0 and dt > 0 else 0.0,
            step_v / dt if dt > 0 else 0.0,
        )
        arrived = horizontal - step_h <= ARRIVED_M and abs(d_up - step_v) <= ARRIVED_M
        if arrived:
            self.north, self.east, self.alt = north, east, target.alt
        return arrived

    def _fly_home(self, dt: float) -> bool:
        """ModeRTL: climb to the return altitude, fly home, land. True once on the ground."""
        if self.rtl_phase in (None, "climb"):
            self.rtl_phase = "climb"
            if self._move(Target(None, None, max(self.alt, self.rtl_altitude_m)), dt):
                self.rtl_phase = "return"
        elif self.rtl_phase == "return":
            if self._move(Target(0.0, 0.0, self.alt), dt):
                self.rtl_phase = "land"
        elif self._move(Target(0.0, 0.0, 0.0), dt):
            return True
        return False

    def _item_target(self, item: MissionItem) -> Target:
        north, east, _ = self.frame.to_ned(item.x * 1e-7, item.y * 1e-7, self.home[2])
        alt = item.z - self.home[2] if item.frame in (MavFrame.GLOBAL, MavFrame.GLOBAL_INT) else item.z
        return Target(float(north), float(east), float(alt))

    def _begin_item(self) -> None:
        """Start mission item current_seq (ModeAuto::start_command)."""
        item = self.mission[self.current_seq]
        self.hold_until, self.rtl_phase = None, None
        if item.command == MavCmd.NAV_TAKEOFF:
            self.target = Target(None, None, max(item.z, self.alt))
        elif item.command == MavCmd.NAV_WAYPOINT:
            self.target = self._item_target(item)
        elif item.command == MavCmd.NAV_LAND:
            land = self._item_target(item) if item.x or item.y else Target(None, None, 0.0)
            self.target = Target(land.north, land.east, 0.0)
        elif item.command == MavCmd.NAV_RETURN_TO_LAUNCH:
            self.target, self.rtl_phase = None, "climb"
        else:  # do-commands run at once and count as complete
            if item.command == MavCmd.DO_CHANGE_SPEED and item.param2 > 0:
                self.requested_speed_m_s = item.param2
            self.target = None

    def _fly_mission(self, dt: float, now: float) -> None:
        item = self.mission[self.current_seq]
        if item.command == MavCmd.NAV_RETURN_TO_LAUNCH:
            done = self._fly_home(dt)
        elif self.target is None:
            done = True
        elif not self._move(self.target, dt):
            done = False
        elif item.command == MavCmd.NAV_WAYPOINT and item.param1 > 0:  # hold param1 seconds at the waypoint
            self.hold_until = self.hold_until or now + item.param1
            done = now >= self.hold_until
        else:
            done = True
        if not done:
            return
        if item.command in (MavCmd.NAV_LAND, MavCmd.NAV_RETURN_TO_LAUNCH):
            self.landed, self.alt, self.velocity = True, 0.0, (0.0, 0.0, 0.0)
        self.send(self.encoder.mav.mission_item_reached_encode(self.current_seq))
        if self.current_seq + 1 < len(self.mission):
            self.current_seq += 1
            self._begin_item()
            return
        # ModeAuto::exit_mission: a landed vehicle disarms, a flying one loiters
        self.mission_state = mavlink.MISSION_STATE_COMPLETE
        if self.landed:
            self.armed = False
        else:
            self.set_mode(CopterMode.LOITER)

    # ----- telemetry
    def _publish(self, now: float) -> None:
        if now >= self.next_heartbeat_at:
            self.next_heartbeat_at = now + HEARTBEAT_PERIOD_S
            self.send(self._heartbeat())
        for group, rate in self.stream_rates.items():
            if rate > 0 and now >= self.next_stream_at.get(group, 0.0):
                self.next_stream_at[group] = now + 1.0 / rate
                for name in STREAM_GROUPS[group]:
                    self.send(getattr(self, f"_{name.lower()}")())

    def _heartbeat(self) -> Any:
        base = mavlink.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED | mavlink.MAV_MODE_FLAG_STABILIZE_ENABLED
        base |= mavlink.MAV_MODE_FLAG_MANUAL_INPUT_ENABLED
        base |= mavlink.MAV_MODE_FLAG_GUIDED_ENABLED if self.mode in GUIDED_FLAG_MODES else 0
        base |= mavlink.MAV_MODE_FLAG_SAFETY_ARMED if self.armed else 0
        state = mavlink.MAV_STATE_STANDBY if self.landed else mavlink.MAV_STATE_ACTIVE
        return self.encoder.mav.heartbeat_encode(
            mavlink.MAV_TYPE_QUADROTOR, mavlink.MAV_AUTOPILOT_ARDUPILOTMEGA, base, int(self.mode), state
        )

    def _global_position_int(self) -> Any:
        lat, lon, _ = self.frame.from_ned(self.north, self.east, 0.0)
        vn, ve, vu = self.velocity
        return self.encoder.mav.global_position_int_encode(
            self.time_boot_ms,
            round(float(lat) * 1e7),
            round(float(lon) * 1e7),
            round((self.home[2] + self.alt) * 1000),
            round(self.alt * 1000),
            round(vn * 100),
            round(ve * 100),
            round(-vu * 100),
            round(math.degrees(self.yaw) % 360 * 100),
        )

    def _local_position_ned(self) -> Any:
        vn, ve, vu = self.velocity
        return self.encoder.mav.local_position_ned_encode(
            self.time_boot_ms, self.north, self.east, -self.alt, vn, ve, -vu
        )

    def _attitude(self) -> Any:
        return self.encoder.mav.attitude_encode(self.time_boot_ms, 0.0, 0.0, self.yaw, 0.0, 0.0, 0.0)

    def _sys_status(self) -> Any:
        # a full 3S pack, as ArduCopter with a battery monitor reports it (the service's pre-flight check refuses to
        # arm a vehicle that reports no charge)
        return self.encoder.mav.sys_status_encode(0, 0, 0, 0, 12600, 0, 100, 0, 0, 0, 0, 0, 0)

    def _mission_current(self) -> Any:
        total = max(len(self.mission) - 1, 0)  # home excluded (send_mission_current)
        mission_mode = 1 if self.mode == CopterMode.AUTO else 0
        return self.encoder.mav.mission_current_encode(self.current_seq, total, self.mission_state, mission_mode)

    def _system_time(self) -> Any:
        boot_ms = self.time_boot_ms
        return self.encoder.mav.system_time_encode(int((self.boot_unix_s + boot_ms / 1000) * 1e6), boot_ms)

    def _extended_sys_state(self) -> Any:
        if self.landed:
            landed_state = mavlink.MAV_LANDED_STATE_ON_GROUND
        elif self.velocity[2] < 0 and self.mode in (CopterMode.LAND, CopterMode.RTL):
            landed_state = mavlink.MAV_LANDED_STATE_LANDING
        else:
            landed_state = mavlink.MAV_LANDED_STATE_IN_AIR
        return self.encoder.mav.extended_sys_state_encode(mavlink.MAV_VTOL_STATE_UNDEFINED, landed_state)

    def _home_position(self) -> Any:
        lat, lon, alt = self.home
        return self.encoder.mav.home_position_encode(
            round(lat * 1e7), round(lon * 1e7), round(alt * 1000), 0.0, 0.0, 0.0, [1.0, 0.0, 0.0, 0.0], 0.0, 0.0, 0.0
        )
