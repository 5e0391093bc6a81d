"""Integration-test helpers: the vehicle (`python -m sitl_quad`) as a subprocess, and a pymavlink GCS.

`SitlProcess` starts the vehicle on a free UDP port, waits for its "listening" line and stops it with SIGTERM
(then SIGKILL); its stderr goes to a file so a test can check that no handler raised. `GroundStation` is the
GCS side of the MAVLink protocols written out with pymavlink, with the retries a lossy link needs.
"""

from __future__ import annotations

import os

os.environ.setdefault("MAVLINK20", "1")  # pymavlink picks its wire protocol at import time

import math
import queue
import subprocess
import sys
import tempfile
import threading
import time
from collections.abc import Callable
from pathlib import Path

from pymavlink import mavutil
from pymavlink.dialects.v20 import common as mavlink

from bench.processes import free_udp_port, stop_process

REPO = Path(__file__).resolve().parent.parent
VEHICLE_SYSID, VEHICLE_COMPID = 1, 1
GCS_SYSID, GCS_COMPID = 255, 190
START_TIMEOUT_S = 60.0  # a loaded 2-core machine can take long to import numpy/numba
# A wait's deadline: only reached when the behaviour is wrong, however loaded the machine (a paced vehicle covers
# less simulated time per wall second when it is, and a lockstep one runs at the CPU's pace).
WAIT_S = 60.0
HEARTBEAT_PERIOD_S = 1.0  # a ground station's heartbeat (MAVLink's heartbeat protocol: 1 Hz)


def start_lockstep_pair(port: int, seed: int, log: Path) -> tuple[subprocess.Popen, subprocess.Popen]:
    """`python -m sitl_quad --lockstep --log` on port and `python -m adrc_offboard` for it: (vehicle, controller),
    stderr piped so a test can check neither printed a traceback."""

    def start(*args: str) -> subprocess.Popen:
        return subprocess.Popen(
            [sys.executable, "-m", *args], cwd=REPO, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True
        )

    vehicle = start("sitl_quad", "--port", str(port), "--lockstep", "--seed", str(seed), "--log", str(log))
    controller = start("adrc_offboard", "--connect", f"udpout:127.0.0.1:{port}")
    return vehicle, controller


class PortTakenError(RuntimeError):
    """The vehicle could not bind its UDP port."""


class SitlProcess:
    """The vehicle as a child process on 127.0.0.1:port."""

    def __init__(self, speed: float = 20.0, extra_args: tuple[str, ...] = (), port: int | None = None) -> None:
        self.port = port or free_udp_port()
        self.args = [sys.executable, "-m", "sitl_quad", "--port", str(self.port), "--speed", f"{speed:g}", *extra_args]
        self.stderr_path = Path(tempfile.mkstemp(prefix="sitl_quad_", suffix=".stderr")[1])
        self.process: subprocess.Popen | None = None
        self.returncode: int | None = None

    def start(self, timeout: float = START_TIMEOUT_S, attempts: int = 3) -> SitlProcess:
        """Start and wait for the "listening" line. The free port can be taken by another process between
        free_udp_port() and the vehicle's bind (parallel test workers): then try again on a new port."""
        for _ in range(attempts - 1):
            try:
                return self._start_once(timeout)
            except PortTakenError:
                self.port = free_udp_port()
                self.args[self.args.index("--port") + 1] = str(self.port)
        return self._start_once(timeout)

    def _start_once(self, timeout: float) -> SitlProcess:
        with open(self.stderr_path, "w") as stderr:
            self.process = subprocess.Popen(self.args, cwd=REPO, stdout=subprocess.PIPE, stderr=stderr, text=True)
        lines: queue.Queue[str] = queue.Queue()
        # A thread drains stdout for the whole run, so the vehicle can never block on a full pipe.
        threading.Thread(target=_pump, args=(self.process.stdout, lines), daemon=True).start()
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            try:
                line = lines.get(timeout=0.2)
            except queue.Empty:
                if self.process.poll() is not None:
                    break
                continue
            if "listening" in line:
                return self
        self.stop()
        if "cannot listen" in self.stderr():
            raise PortTakenError(self.stderr())
        raise RuntimeError(f"sitl_quad did not start listening on port {self.port}: {self.stderr()}")

    def alive(self) -> bool:
        return self.process is not None and self.process.poll() is None

    def stop(self, timeout: float = 10.0) -> int | None:
        """SIGTERM, then SIGKILL if it has not exited within timeout; returns the exit code."""
        if self.process is None:
            return None
        self.returncode = stop_process(self.process, timeout)
        return self.returncode

    def stderr(self) -> str:
        return self.stderr_path.read_text() if self.stderr_path.exists() else ""

    def cleanup(self) -> None:
        self.stop()
        self.stderr_path.unlink(missing_ok=True)


def _pump(stream, lines: queue.Queue) -> None:
    for line in stream:
        lines.put(line)


class GroundStation:
    """A pymavlink GCS talking to the vehicle at udp 127.0.0.1:port (or through a relay on that port)."""

    def __init__(
        self, port: int, sysid: int = GCS_SYSID, compid: int = GCS_COMPID, vehicle_sysid: int = VEHICLE_SYSID
    ) -> None:
        self.conn = mavutil.mavlink_connection(f"udpout:127.0.0.1:{port}", source_system=sysid, source_component=compid)
        self.mav = self.conn.mav
        self.vehicle_sysid = vehicle_sysid  # whose messages it reads (a fleet's vehicles have their own)
        self._next_heartbeat = 0.0

    def close(self) -> None:
        self.conn.close()

    def drain(self) -> None:
        """Forget every message already received and not yet read."""
        while self.conn.recv_match(blocking=False) is not None:
            pass

    def send_heartbeat(self) -> None:
        self.mav.heartbeat_send(mavlink.MAV_TYPE_GCS, mavlink.MAV_AUTOPILOT_INVALID, 0, 0, 0)
        self._next_heartbeat = time.monotonic() + HEARTBEAT_PERIOD_S

    def _keep_alive(self) -> None:
        """A heartbeat a second while waiting, as every ground station sends: the vehicle drops a peer silent for
        10 s, and on a busy machine a wait for slow replies (camera frames made in a worker) can last longer."""
        if time.monotonic() >= self._next_heartbeat:
            self.send_heartbeat()

    def recv(self, kinds: str | list[str], timeout: float = 5.0, condition: Callable[[object], bool] | None = None):
        """The next message of one of `kinds` from the vehicle satisfying condition, or None after timeout."""
        deadline = time.monotonic() + timeout
        while (remaining := deadline - time.monotonic()) > 0:
            self._keep_alive()
            msg = self.conn.recv_match(type=kinds, blocking=True, timeout=min(remaining, 0.2))
            if msg is None or msg.get_srcSystem() != self.vehicle_sysid:
                continue
            if condition is None or condition(msg):
                return msg
        return None

    def connect(self, timeout: float = 20.0):
        """Become a peer (the vehicle answers whoever sends it a datagram) and wait for a HEARTBEAT."""
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            self.send_heartbeat()
            heartbeat = self.recv("HEARTBEAT", timeout=1.0)
            if heartbeat is not None:
                return heartbeat
        raise TimeoutError("no HEARTBEAT from the vehicle")

    def command(
        self,
        command: int,
        *params: float,
        timeout: float = 5.0,
        use_int: bool = False,
        target_system: int = VEHICLE_SYSID,
    ):
        """Send COMMAND_LONG (or COMMAND_INT) and return its COMMAND_ACK, resent every second like MAVSDK."""
        p = [*params, *[math.nan] * (7 - len(params))]
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            if use_int:
                x, y = (int(v) if math.isfinite(v) else 0 for v in p[4:6])
                self.mav.command_int_send(
                    target_system,
                    VEHICLE_COMPID,
                    mavlink.MAV_FRAME_GLOBAL,
                    command,
                    0,
                    0,
                    p[0],
                    p[1],
                    p[2],
                    p[3],
                    x,
                    y,
                    p[6],
                )
            else:
                self.mav.command_long_send(target_system, VEHICLE_COMPID, command, 0, *p)
            ack = self.recv("COMMAND_ACK", timeout=1.0, condition=lambda m: m.command == command)
            if ack is not None:
                return ack
        return None

    def request(self, command: int, *params: float, reply: str, timeout: float = 5.0):
        """Send a command that makes the vehicle send a message (before or after its ACK): (ack, message)."""
        p = [*params, *[math.nan] * (7 - len(params))]
        self.mav.command_long_send(VEHICLE_SYSID, VEHICLE_COMPID, command, 0, *p)
        ack = answer = None
        deadline = time.monotonic() + timeout
        while (ack is None or answer is None) and (remaining := deadline - time.monotonic()) > 0:
            msg = self.recv(["COMMAND_ACK", reply], timeout=remaining)
            if msg is None:
                break
            if msg.get_type() == reply:
                answer = answer or msg
            elif msg.command == command:
                ack = msg
        return ack, answer

    def set_mode(self, main_mode: int, sub_mode: int = 0):
        return self.command(mavlink.MAV_CMD_DO_SET_MODE, mavlink.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED, main_mode, sub_mode)

    def wait_heartbeat(self, condition: Callable[[object], bool], timeout: float = 10.0):
        return self.recv("HEARTBEAT", timeout=timeout, condition=condition)

    # ----- parameters
    def read_param(self, name: str | None = None, index: int = -1, timeout: float = 5.0):
        """PARAM_REQUEST_READ by name (index -1) or by index, retried every second: PARAM_VALUE or None."""
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            self.mav.param_request_read_send(VEHICLE_SYSID, VEHICLE_COMPID, (name or "").encode(), index)
            value = self.recv(
                "PARAM_VALUE",
                timeout=1.0,
                condition=lambda m: m.param_id == name if index < 0 else m.param_index == index,
            )
            if value is not None:
                return value
        return None

    def set_param(self, name: str, raw_value: float, param_type: int, timeout: float = 5.0):
        """PARAM_SET with the wire value as given (already encoded); the PARAM_VALUE that answers it."""
        self.mav.param_set_send(VEHICLE_SYSID, VEHICLE_COMPID, name.encode(), raw_value, param_type)
        return self.recv("PARAM_VALUE", timeout=timeout, condition=lambda m: m.param_id == name)

    # ----- mission protocol, GCS side
    def upload_mission(
        self,
        items: list,
        mission_type: int = mavlink.MAV_MISSION_TYPE_MISSION,
        timeout: float = 20.0,
        stop_after: int | None = None,
    ):
        """Upload MISSION_ITEM_INT messages; the vehicle's MISSION_ACK, or None on timeout.

        Retries the way MAVSDK does: MISSION_COUNT is resent until the first request arrives, and the item
        last asked for is resent when nothing is heard for a while (a lost final ACK is answered again by a
        conforming vehicle when it sees the last item twice). With stop_after=n the GCS goes silent after
        sending n items, an upload aborted half-way.
        """
        deadline = time.monotonic() + timeout
        requested: int | None = None
        sent = 0
        self.mav.mission_count_send(VEHICLE_SYSID, VEHICLE_COMPID, len(items), mission_type)
        while time.monotonic() < deadline:
            msg = self.recv(
                ["MISSION_REQUEST_INT", "MISSION_REQUEST", "MISSION_ACK"],
                timeout=0.4,
                condition=lambda m: m.mission_type == mission_type,
            )
            if stop_after is not None and sent >= stop_after:
                return None
            if msg is None:  # lost on the way, in either direction: say the last thing again
                if requested is None:
                    self.mav.mission_count_send(VEHICLE_SYSID, VEHICLE_COMPID, len(items), mission_type)
                else:
                    self.send_item(items[requested])
                continue
            if msg.get_type() == "MISSION_ACK":
                return msg
            if not 0 <= msg.seq < len(items):
                return None
            requested = msg.seq
            self.send_item(items[requested])
            sent += 1
        return None

    def send_item(self, item) -> None:
        self.mav.send(item)

    def download_mission(
        self, mission_type: int = mavlink.MAV_MISSION_TYPE_MISSION, timeout: float = 20.0
    ) -> list | None:
        """MISSION_REQUEST_LIST, then each item by MISSION_REQUEST_INT with retries, then MISSION_ACK."""
        deadline = time.monotonic() + timeout
        count = None
        while count is None and time.monotonic() < deadline:
            self.mav.mission_request_list_send(VEHICLE_SYSID, VEHICLE_COMPID, mission_type)
            count = self.recv("MISSION_COUNT", timeout=0.5, condition=lambda m: m.mission_type == mission_type)
        if count is None:
            return None
        items = []
        while len(items) < count.count and time.monotonic() < deadline:
            seq = len(items)
            self.mav.mission_request_int_send(VEHICLE_SYSID, VEHICLE_COMPID, seq, mission_type)
            item = self.recv("MISSION_ITEM_INT", timeout=0.3, condition=lambda m, s=seq: m.seq == s)
            if item is not None:
                items.append(item)
        if len(items) < count.count:
            return None
        self.mav.mission_ack_send(VEHICLE_SYSID, VEHICLE_COMPID, mavlink.MAV_MISSION_ACCEPTED, mission_type)
        return items


def mission_item(
    seq: int,
    command: int,
    lat: float = 0.0,
    lon: float = 0.0,
    alt: float = 0.0,
    frame: int = mavlink.MAV_FRAME_GLOBAL_RELATIVE_ALT_INT,
    params: tuple = (0.0, 0.0, 0.0, math.nan),
    mission_type: int = mavlink.MAV_MISSION_TYPE_MISSION,
):
    """One MISSION_ITEM_INT addressed to the vehicle; lat/lon in degrees."""
    return mavlink.MAVLink_mission_item_int_message(
        VEHICLE_SYSID,
        VEHICLE_COMPID,
        seq,
        frame,
        command,
        int(seq == 0),
        1,
        *params,
        round(lat * 1e7),
        round(lon * 1e7),
        alt,
        mission_type,
    )


def short_mission(home: tuple[float, float, float], leg_m: float = 30.0) -> list:
    """Takeoff to 5 m, two waypoints leg_m apart (north, then east), return to launch: seconds at 20x."""
    from uavcore.geodesy import LocalFrame

    frame = LocalFrame(*home)
    north = frame.from_ned(leg_m, 0.0, 0.0)
    north_east = frame.from_ned(leg_m, leg_m, 0.0)
    return [
        mission_item(0, mavlink.MAV_CMD_NAV_TAKEOFF, home[0], home[1], 5.0),
        mission_item(1, mavlink.MAV_CMD_NAV_WAYPOINT, north[0], north[1], 5.0, params=(0.0, 2.0, 0.0, math.nan)),
        mission_item(
            2, mavlink.MAV_CMD_NAV_WAYPOINT, north_east[0], north_east[1], 5.0, params=(0.0, 2.0, 0.0, math.nan)
        ),
        mission_item(3, mavlink.MAV_CMD_NAV_RETURN_TO_LAUNCH, frame=mavlink.MAV_FRAME_MISSION),
    ]
