"""MAVProxy talks to the vehicle: it connects, fetches every parameter, loads and lists a `.waypoints` file.

MAVProxy runs as a subprocess with commands typed on its stdin. Not with --non-interactive: MAVProxy 1.8.75
then never reads stdin at all (its main thread only sleeps), so the commands would be lost.
"""

from __future__ import annotations

import math
import queue
import re
import struct
import subprocess
import sys
import threading
import time
from collections.abc import Iterator
from pathlib import Path

import pytest
from sitl_process import GroundStation, mavlink

from sitl_quad.vehicle_params import VEHICLE_PARAMETERS
from uavcore.geodesy import DEFAULT_HOME, LocalFrame

pytestmark = [pytest.mark.integration, pytest.mark.slow, pytest.mark.timeout(300)]
# A wait's deadline: MAVProxy's start (imports of its modules) takes seconds on a quiet machine and several times
# that on a loaded one; only a behaviour that never comes reaches it.
WAIT_S = 60.0

MAVPROXY = Path(sys.executable).with_name("mavproxy.py")


class MavProxy:
    """mavproxy.py as a child process: type commands, wait for lines it prints."""

    def __init__(self, port: int, state_dir: Path) -> None:
        command = [sys.executable, str(MAVPROXY), f"--master=udpout:127.0.0.1:{port}", f"--state-basedir={state_dir}"]
        self.process = subprocess.Popen(
            command, stdin=subprocess.PIPE, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, cwd=state_dir
        )
        self.lines: queue.Queue[str] = queue.Queue()
        self.transcript: list[str] = []
        threading.Thread(target=self._pump, daemon=True).start()

    def _pump(self) -> None:
        for line in self.process.stdout:
            self.lines.put(line.rstrip("\n"))

    def type(self, command: str) -> None:
        self.process.stdin.write(command + "\n")
        self.process.stdin.flush()

    def wait_for(self, pattern: str, timeout: float) -> re.Match:
        """The first line from now on that matches pattern (a regex searched in the line)."""
        deadline = time.monotonic() + timeout
        while (remaining := deadline - time.monotonic()) > 0:
            try:
                line = self.lines.get(timeout=min(remaining, 0.2))
            except queue.Empty:
                continue
            self.transcript.append(line)
            match = re.search(pattern, line)
            if match:
                return match
        tail = "\n".join(self.transcript[-40:])
        raise AssertionError(f"MAVProxy never printed /{pattern}/ within {timeout} s; last lines:\n{tail}")

    def close(self) -> None:
        if self.process.poll() is None:
            self.process.stdin.close()  # MAVProxy exits at the end of its input
            try:
                self.process.wait(10)
            except subprocess.TimeoutExpired:
                self.process.kill()
                self.process.wait(10)


@pytest.fixture
def mavproxy(start_sitl, tmp_path) -> Iterator[tuple[MavProxy, int]]:
    vehicle = start_sitl(speed=10)
    proxy = MavProxy(vehicle.port, tmp_path)
    try:
        yield proxy, vehicle.port
    finally:
        proxy.close()


def write_waypoints(path: Path) -> list[tuple]:
    """A QGC WPL 110 file: home, takeoff, two waypoints, return. Returns the rows as written."""
    frame = LocalFrame(*DEFAULT_HOME)
    lat1, lon1, _ = frame.from_ned(30.0, 0.0)
    lat2, lon2, _ = frame.from_ned(30.0, 30.0)
    home_lat, home_lon, home_alt = DEFAULT_HOME
    relative, amsl = mavlink.MAV_FRAME_GLOBAL_RELATIVE_ALT, mavlink.MAV_FRAME_GLOBAL
    rows = [  # index, current, frame, command, p1..p4, lat, lon, alt, autocontinue
        (0, 1, amsl, mavlink.MAV_CMD_NAV_WAYPOINT, 0, 0, 0, 0, home_lat, home_lon, home_alt, 1),
        (1, 0, relative, mavlink.MAV_CMD_NAV_TAKEOFF, 0, 0, 0, 0, home_lat, home_lon, 5.0, 1),
        (2, 0, relative, mavlink.MAV_CMD_NAV_WAYPOINT, 0, 2.0, 0, 0, round(lat1, 7), round(lon1, 7), 5.0, 1),
        (3, 0, relative, mavlink.MAV_CMD_NAV_WAYPOINT, 0, 2.0, 0, 0, round(lat2, 7), round(lon2, 7), 5.0, 1),
        (4, 0, mavlink.MAV_FRAME_MISSION, mavlink.MAV_CMD_NAV_RETURN_TO_LAUNCH, 0, 0, 0, 0, 0, 0, 0, 1),
    ]
    lines = ["QGC WPL 110"] + ["\t".join(f"{v:.7f}" if isinstance(v, float) else str(v) for v in row) for row in rows]
    path.write_text("\n".join(lines) + "\n")
    return rows


def test_mavproxy_fetches_every_parameter_and_sets_an_int32_one(mavproxy):
    proxy, port = mavproxy
    proxy.wait_for(r"Detected vehicle 1:1", timeout=WAIT_S)
    proxy.type("param fetch")
    # MAVProxy tries MAVLink FTP first; the vehicle has none, so it falls back to PARAM_REQUEST_LIST.
    received = proxy.wait_for(r"Received (\d+) parameters", timeout=WAIT_S)
    assert int(received.group(1)) == len(VEHICLE_PARAMETERS)
    proxy.type("param show OFFB_LOSS_T")
    shown = proxy.wait_for(r"OFFB_LOSS_T\s+(\S+)", timeout=WAIT_S)
    assert float(shown.group(1)) == pytest.approx(1.0)
    # MAVProxy reads the GEOFENCE health bit of SYS_STATUS: clear, it announces a breach of no fence.
    assert not any("fence breach" in line for line in proxy.transcript)

    # An INT32 set by MAVProxy (it packs the int's bytes into the float, as PX4 expects) lands as that int.
    proxy.type("param set OFFB_LOSS_ACT 2")
    gcs = GroundStation(port)
    gcs.connect()
    deadline = time.monotonic() + WAIT_S
    while (value := gcs.read_param("OFFB_LOSS_ACT")) is not None and time.monotonic() < deadline:
        if struct.unpack("<i", struct.pack("<f", value.param_value))[0] == 2:
            break
        time.sleep(0.2)
    gcs.close()
    assert value is not None and struct.unpack("<i", struct.pack("<f", value.param_value))[0] == 2
    # MAVProxy shows its own copy, updated when it reads the vehicle's PARAM_VALUE: on a loaded machine that can
    # come after the vehicle already answers 2 above, so ask again until it shows the vehicle's value.
    deadline = time.monotonic() + WAIT_S
    while True:
        proxy.type("param show OFFB_LOSS_ACT")
        shown = proxy.wait_for(r"OFFB_LOSS_ACT\s+(\S+)", timeout=WAIT_S).group(1)
        if shown == "2":
            break
        assert time.monotonic() < deadline, f"MAVProxy still shows OFFB_LOSS_ACT = {shown}"
        time.sleep(0.5)


def test_mavproxy_loads_and_lists_a_waypoints_file(mavproxy, tmp_path):
    proxy, port = mavproxy
    rows = write_waypoints(tmp_path / "short.waypoints")
    proxy.wait_for(r"Detected vehicle 1:1", timeout=WAIT_S)
    proxy.type(f"wp load {tmp_path / 'short.waypoints'}")
    proxy.wait_for(rf"Sent all {len(rows)} waypoints", timeout=WAIT_S)

    proxy.type("wp list")
    listed = []
    for _ in rows:  # MAVProxy prints one line per item: command frame lat lon alt p1= p2= p3= p4= cur= auto=
        match = proxy.wait_for(r"^(\d+) (\d+) (-?[\d.]+) (-?[\d.]+) (-?[\d.]+) p1=(\S+) p2=(\S+)", timeout=WAIT_S)
        listed.append(match.groups())
    proxy.wait_for(rf"Saved {len(rows)} waypoints", timeout=WAIT_S)
    for row, got in zip(rows, listed, strict=True):
        command, frame, lat, lon, alt, _, p2 = got
        assert (int(command), int(frame)) == (row[3], row[2])
        assert float(lat) == pytest.approx(row[8], abs=1e-7) and float(lon) == pytest.approx(row[9], abs=1e-7)
        assert float(alt) == pytest.approx(row[10]) and float(p2) == pytest.approx(row[5])

    # What the vehicle stored, seen by a second ground station: the file's rows verbatim, the home line
    # included (MAVProxy sends it as item 0).
    gcs = GroundStation(port)
    gcs.connect()
    stored = gcs.download_mission()
    gcs.close()
    assert [(i.seq, i.command, i.frame) for i in stored] == [(row[0], row[3], row[2]) for row in rows]
    for item, row in zip(stored, rows, strict=True):
        assert math.isclose(item.x, row[8] * 1e7, abs_tol=1) and math.isclose(item.y, row[9] * 1e7, abs_tol=1)
        assert item.z == pytest.approx(row[10]) and item.param2 == pytest.approx(row[5])
