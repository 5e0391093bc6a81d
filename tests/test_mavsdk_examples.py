"""MAVSDK-Python's own example programs fly the vehicle as they fly PX4 SITL.

Each example in tests/mavsdk_examples/ makes the same MAVSDK calls, with the same arguments and waits, as the
program of that name in MAVSDK-Python's examples/ folder; it runs under .venv-mavsdk3 (MAVSDK-Python 3.x with
its bundled mavsdk_server, which `make test` installs) against the vehicle started as a real process:

    python -m sitl_quad --port VEHICLE_PORT --out 127.0.0.1:PORT --home 47.397742,8.545594,488
    .venv-mavsdk3/bin/python tests/mavsdk_examples/<name>.py udp://:PORT GRPC_PORT

The example listens on PORT as it listens on 14540 for PX4 SITL, and the vehicle pushes its telemetry there;
every port is a free one picked per test. Beside the example, a pymavlink ground station on the vehicle's own
port (as QGroundControl would be) records what the vehicle reports: the outcome is judged from that record,
the example's exit code and what it printed.

Speeds: the examples' waits are wall-clock sleeps. Where the vehicle's own flying is what takes time (landing
after the script, a mission), the vehicle runs 2-5x faster than real time. The offboard examples run at real
time: they stream setpoints for so many wall-clock seconds, and at 5x "climb 2 m/s for 4 s" would be 40 m.
"""

from __future__ import annotations

import contextlib
import math
import os
import signal
import subprocess
import threading
import time
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from pathlib import Path

import pytest
from sitl_process import REPO, VEHICLE_SYSID, GroundStation, SitlProcess, mavlink

from bench.processes import free_tcp_port, free_udp_port
from uavcore.geodesy import LocalFrame
from uavcore.modes import FlightMode

pytestmark = [pytest.mark.integration, pytest.mark.slow, pytest.mark.timeout(400)]

EXAMPLES = REPO / "tests" / "mavsdk_examples"
PLAN_DIR = REPO / "tests" / "data"  # holds example-mission.plan, which mission_import.py opens from its cwd
MAVSDK3_PYTHON = REPO / ".venv-mavsdk3" / "bin" / "python"
HOME = (47.397742, 8.545594, 488.0)  # PX4 SITL's default home, which the examples' coordinates are around
HOME_ARG = "47.397742,8.545594,488"
ON_GROUND = mavlink.MAV_LANDED_STATE_ON_GROUND
# goto: a backstop only (the example is interrupted once the vehicle is there); fully loaded (a CPU burner on
# both cores beside the suite) the flight took over 180 s of wall clock
EXAMPLE_BACKSTOP_S = 600.0
ARMED_FLAG = mavlink.MAV_MODE_FLAG_SAFETY_ARMED
CTRL_C_REPEAT_S = 5.0  # a Ctrl-C the example did not exit on is pressed again after this long
EXCEPTION_GRACE_S = 5.0  # for an example that raised to exit by itself
SETTLE_TIMEOUT_S = 180.0  # for the vehicle to finish what the example started (wall clock, a loaded machine)
# For the observer's thread to have read what the vehicle sent before the example exited (a loaded machine's
# scheduler may leave it behind the example): what happened is waited for, never judged the moment the example ends.
CATCH_UP_S = 60.0


# ----- what the vehicle reports, recorded by a second ground station
@dataclass
class Sample:
    """One GLOBAL_POSITION_INT, in metres from home (north, east, height above home)."""

    north: float
    east: float
    height: float


@dataclass
class FlightRecord:
    armed: bool = False
    mode: FlightMode | None = None
    landed_state: int | None = None
    modes_seen: list[FlightMode] = field(default_factory=list)
    track: list[Sample] = field(default_factory=list)
    rolls_deg: list[float] = field(default_factory=list)
    yaws_deg: list[float] = field(default_factory=list)
    reached: set[int] = field(default_factory=set)  # MISSION_ITEM_REACHED seqs
    texts: list[str] = field(default_factory=list)  # STATUSTEXT

    def max_height(self) -> float:
        return max((s.height for s in self.track), default=0.0)

    def settled_on_ground(self) -> bool:
        return not self.armed and self.landed_state == ON_GROUND

    def passed_near(self, north: float, east: float, height: float, tolerance_m: float) -> bool:
        return any(math.dist((s.north, s.east, s.height), (north, east, height)) <= tolerance_m for s in self.track)

    def summary(self) -> str:
        last = self.track[-1] if self.track else None
        return (
            f"armed {self.armed}, mode {self.mode}, landed_state {self.landed_state}, last {last}, "
            f"max height {self.max_height():.1f} m, modes {[m.name for m in self.modes_seen]}, "
            f"reached {sorted(self.reached)}, texts {self.texts}"
        )


class VehicleObserver:
    """A pymavlink ground station on the vehicle's own port, recording what the vehicle reports in a thread."""

    def __init__(self, vehicle_port: int) -> None:
        self.station = GroundStation(vehicle_port)
        self.station.connect()
        self.frame = LocalFrame(*HOME)
        self.record = FlightRecord()
        self._lock = threading.Lock()
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, daemon=True)
        self._thread.start()

    def _run(self) -> None:
        next_heartbeat = 0.0
        while not self._stop.is_set():
            if time.monotonic() >= next_heartbeat:  # stay a live peer (the vehicle drops one silent for 10 s)
                self.station.send_heartbeat()
                next_heartbeat = time.monotonic() + 1.0
            msg = self.station.conn.recv_match(blocking=True, timeout=0.2)
            if msg is not None and msg.get_srcSystem() == VEHICLE_SYSID:
                with self._lock:
                    self._note(msg)

    def _note(self, msg) -> None:
        record, kind = self.record, msg.get_type()
        if kind == "HEARTBEAT":
            record.armed = bool(msg.base_mode & ARMED_FLAG)
            record.mode = FlightMode.from_custom_mode(msg.custom_mode)
            if record.mode is not None and (not record.modes_seen or record.modes_seen[-1] != record.mode):
                record.modes_seen.append(record.mode)
        elif kind == "EXTENDED_SYS_STATE":
            record.landed_state = msg.landed_state
        elif kind == "GLOBAL_POSITION_INT":
            north, east, _ = self.frame.to_ned(msg.lat * 1e-7, msg.lon * 1e-7)
            record.track.append(Sample(float(north), float(east), msg.relative_alt * 1e-3))
        elif kind == "ATTITUDE":
            record.rolls_deg.append(math.degrees(msg.roll))
            record.yaws_deg.append(math.degrees(msg.yaw) % 360.0)
        elif kind == "MISSION_ITEM_REACHED":
            record.reached.add(msg.seq)
        elif kind == "STATUSTEXT":
            record.texts.append(msg.text)

    def check(self, condition: Callable[[FlightRecord], bool]) -> bool:
        with self._lock:
            return condition(self.record)

    def wait_for(self, condition: Callable[[FlightRecord], bool], what: str, timeout: float = SETTLE_TIMEOUT_S):
        deadline = time.monotonic() + timeout
        while not self.check(condition):
            if time.monotonic() > deadline:
                raise AssertionError(f"timed out after {timeout:.0f} s waiting for {what}: {self.summary()}")
            time.sleep(0.1)

    def summary(self) -> str:
        with self._lock:
            return self.record.summary()

    def stop_recording(self) -> GroundStation:
        """Stop the thread and hand over the ground station, for request/answer exchanges of the test's own."""
        self._stop.set()
        self._thread.join(timeout=5.0)
        return self.station

    def close(self) -> None:
        self.stop_recording()
        self.station.close()


# ----- running one example
@dataclass
class ExampleRun:
    name: str
    returncode: int | None  # None: killed at the deadline
    stdout: str
    stderr: str
    wall_s: float

    def describe(self) -> str:
        return (
            f"{self.name} exited {self.returncode} after {self.wall_s:.1f} s\n"
            f"--- stdout\n{self.stdout[-4000:]}\n--- stderr\n{self.stderr[-4000:]}"
        )


def _ctrl_c_as_in_a_terminal() -> None:
    """In the example's process: Ctrl-C (SIGINT) does what it does in a terminal. A test run started in the
    background of a shell (`make test &`, a CI runner) inherits SIGINT ignored, and Python then never raises
    KeyboardInterrupt: the goto example, which ends only by Ctrl-C, ran to the test's backstop."""
    signal.signal(signal.SIGINT, signal.SIG_DFL)


def run_example(
    name: str,
    mavlink_port: int,
    tmp_path: Path,
    timeout: float,
    cwd: Path = EXAMPLES,
    interrupt_when: Callable[[], bool] | None = None,
) -> ExampleRun:
    """Run tests/mavsdk_examples/<name>.py listening on udp://:mavlink_port until it exits (or the deadline).

    With interrupt_when, press Ctrl-C once it says True (and again every CTRL_C_REPEAT_S while the example runs):
    SIGINT to the example's process group, as a terminal
    sends it to the example and the mavsdk_server it started. An example whose run() raised does not exit by
    itself (MAVSDK-Python's thread reading mavsdk_server's output keeps it alive): once its traceback is out,
    it is given EXCEPTION_GRACE_S and then counted as failed. At the end anything left of the example's
    process group (its own session, with the mavsdk_server it started) is killed.
    """
    assert MAVSDK3_PYTHON.exists(), f"{MAVSDK3_PYTHON} is missing: `make test` creates it (.venv-mavsdk3)"
    out_path, err_path = tmp_path / f"{name}.stdout", tmp_path / f"{name}.stderr"
    args = [str(MAVSDK3_PYTHON), str(EXAMPLES / f"{name}.py"), f"udp://:{mavlink_port}", str(free_tcp_port())]
    env = {**os.environ, "PYTHONUNBUFFERED": "1"}
    start = time.monotonic()
    with open(out_path, "w") as out, open(err_path, "w") as err:
        process = subprocess.Popen(
            args, cwd=cwd, stdout=out, stderr=err, env=env, start_new_session=True, preexec_fn=_ctrl_c_as_in_a_terminal
        )
    interrupted_at: float | None = None
    deadline = start + timeout
    try:
        while process.poll() is None and time.monotonic() < deadline:
            # Ctrl-C, and again every CTRL_C_REPEAT_S while it is still running, as a user would press it: a
            # KeyboardInterrupt that lands while MAVSDK-Python's reader thread is busy can leave the
            # interpreter waiting for that thread at exit
            if interrupted_at is not None:
                press = time.monotonic() - interrupted_at > CTRL_C_REPEAT_S
            else:
                press = interrupt_when is not None and interrupt_when()
            if press:
                os.killpg(process.pid, signal.SIGINT)
                interrupted_at = time.monotonic()
            if "Traceback (most recent call last)" in err_path.read_text():
                deadline = min(deadline, time.monotonic() + EXCEPTION_GRACE_S)
            time.sleep(0.1)
        returncode = process.poll()
    finally:
        with contextlib.suppress(ProcessLookupError):
            os.killpg(process.pid, signal.SIGKILL)
        process.wait()
    return ExampleRun(name, returncode, out_path.read_text(), err_path.read_text(), time.monotonic() - start)


@dataclass
class Flight:
    """A vehicle of the test's own, listening on a free port and pushing telemetry to a free port for the
    example, and the observer beside the example."""

    vehicle: SitlProcess
    mavlink_port: int
    observer: VehicleObserver


@pytest.fixture
def flight(start_sitl) -> Iterator[Callable[[float], Flight]]:
    observers: list[VehicleObserver] = []

    def start(speed: float) -> Flight:
        mavlink_port = free_udp_port()
        vehicle = start_sitl(speed=speed, extra_args=("--out", f"127.0.0.1:{mavlink_port}", "--home", HOME_ARG))
        observers.append(VehicleObserver(vehicle.port))
        return Flight(vehicle, mavlink_port, observers[-1])

    yield start
    for observer in observers:
        observer.close()


def assert_exit_0(run: ExampleRun) -> None:
    assert run.returncode == 0, run.describe()
    assert "Traceback" not in run.stderr, run.describe()


# ----- the examples
def test_takeoff_and_land(flight, tmp_path):
    """Arms, takes off to the vehicle's MIS_TAKEOFF_ALT, lands after 10 s; the example returns right after
    the land command, so the landing is watched here."""
    f = flight(speed=2)
    run = run_example("takeoff_and_land", f.mavlink_port, tmp_path, timeout=120)
    assert_exit_0(run)
    assert "Status: INFO: Armed" in run.stdout, run.describe()  # status texts reach the example
    f.observer.wait_for(FlightRecord.settled_on_ground, "landed and disarmed")
    record = f.observer.record
    takeoff_altitude = listed_parameters()["MIS_TAKEOFF_ALT"]
    assert record.max_height() == pytest.approx(takeoff_altitude, abs=0.5), record.summary()
    assert {FlightMode.AUTO_TAKEOFF, FlightMode.AUTO_LAND} <= set(record.modes_seen), record.summary()


def test_telemetry_takeoff_and_land(flight, tmp_path):
    """Takes off to the 10 m it sets, lands, and returns only once MAVSDK sees it on the ground."""
    f = flight(speed=2)
    run = run_example("telemetry_takeoff_and_land", f.mavlink_port, tmp_path, timeout=180)
    assert_exit_0(run)
    assert "Altitude: 10" in run.stdout, run.describe()
    assert "Flight mode: LAND" in run.stdout, run.describe()
    f.observer.wait_for(lambda r: r.landed_state == ON_GROUND, "on the ground", CATCH_UP_S)
    f.observer.wait_for(FlightRecord.settled_on_ground, "disarmed after the landing")
    assert 9.0 < f.observer.record.max_height() < 11.0, f.observer.summary()


GOTO_TARGET = (47.397606, 8.543060)


@pytest.mark.timeout(900)  # above the example's backstop
def test_goto(flight, tmp_path):
    """Goes to 47.397606, 8.543060 at 20 m above home (~190 m west) right after the takeoff command; the
    example then stays connected until Ctrl-C, pressed here once the vehicle is there."""
    f = flight(speed=5)
    north, east, _ = f.observer.frame.to_ned(*GOTO_TARGET)

    def arrived(record: FlightRecord) -> bool:
        return bool(record.track) and record.passed_near(float(north), float(east), 20.0, tolerance_m=2.0)

    started, there_after_s = time.monotonic(), []

    def there() -> bool:  # also notes when the vehicle was first seen there (Ctrl-C is pressed then)
        if f.observer.check(arrived):
            there_after_s[:] = there_after_s or [time.monotonic() - started]
            return True
        return False

    run = run_example("goto", f.mavlink_port, tmp_path, timeout=EXAMPLE_BACKSTOP_S, interrupt_when=there)
    assert f.observer.check(arrived), f"{run.describe()}\n{f.observer.summary()}"
    assert "Staying connected" in run.stdout, run.describe()
    # the example ends by Ctrl-C only
    assert run.returncode == -signal.SIGINT, f"{run.describe()}\nthere after {there_after_s} s; {f.observer.summary()}"


ORBIT_CENTRE = (47.398036222362471, 8.5450146439425509)


def test_do_orbit(flight, tmp_path):
    """Orbits a point 55 m north-west of home, 10 m radius at 2 m/s, 10 m up, for 60 s, then returns to launch
    (the example returns right after the return-to-launch command, so the landing is watched here)."""
    f = flight(speed=2)
    run = run_example("do_orbit", f.mavlink_port, tmp_path, timeout=240)
    assert_exit_0(run)
    north, east, _ = f.observer.frame.to_ned(*ORBIT_CENTRE)

    def on_circle(s: Sample) -> bool:
        return abs(math.hypot(s.north - north, s.east - east) - 10.0) < 2.0 and abs(s.height - 10.0) < 2.0

    def bearings_on_circle(record: FlightRecord) -> set[int]:
        """The 45° sectors around the centre in which the vehicle was seen on the circle."""
        return {
            int(math.degrees(math.atan2(s.east - east, s.north - north)) % 360 // 45)
            for s in record.track
            if on_circle(s)
        }

    f.observer.wait_for(lambda r: len(bearings_on_circle(r)) == 8, "all around the circle", CATCH_UP_S)
    f.observer.wait_for(FlightRecord.settled_on_ground, "landed and disarmed after the return to launch")
    assert FlightMode.AUTO_RTL in f.observer.record.modes_seen, f.observer.summary()


MISSION_WAYPOINTS = (  # mission.py's three waypoints, 25 m up
    (47.398039859999997, 8.5455725400000002),
    (47.398036222362471, 8.5450146439425509),
    (47.397825620791885, 8.5450092830163271),
)


def test_mission(flight, tmp_path):
    """Uploads three waypoints with return to launch after the mission, arms, starts it, returns once landed."""
    f = flight(speed=5)
    run = run_example("mission", f.mavlink_port, tmp_path, timeout=240)
    assert_exit_0(run)
    assert "Mission progress: 3/3" in run.stdout, run.describe()
    for latitude, longitude in MISSION_WAYPOINTS:
        north, east, _ = f.observer.frame.to_ned(latitude, longitude)
        f.observer.wait_for(lambda r, n=north, e=east: r.passed_near(n, e, 25.0, 3.0), "each waypoint", CATCH_UP_S)
    f.observer.wait_for(FlightRecord.settled_on_ground, "disarmed after the landing")
    record = f.observer.record
    assert {0, 1, 2} <= record.reached, record.summary()
    assert math.hypot(record.track[-1].north, record.track[-1].east) < 2.0, record.summary()  # back home


PLAN_ITEMS = (  # tests/data/example-mission.plan's mission: (command, latitude, longitude, altitude)
    (mavlink.MAV_CMD_NAV_TAKEOFF, 47.397742, 8.545594, 30.0),
    (mavlink.MAV_CMD_NAV_WAYPOINT, 47.398192, 8.545594, 30.0),
    (mavlink.MAV_CMD_NAV_WAYPOINT, 47.398192, 8.546257, 30.0),
    (mavlink.MAV_CMD_NAV_WAYPOINT, 47.397742, 8.546257, 30.0),
    (mavlink.MAV_CMD_NAV_RETURN_TO_LAUNCH, 0.0, 0.0, 0.0),
)
PLAN_RALLY_POINTS = (  # and its rally points
    (mavlink.MAV_CMD_NAV_RALLY_POINT, 47.397942, 8.545894, 20.0),
    (mavlink.MAV_CMD_NAV_RALLY_POINT, 47.397542, 8.545294, 20.0),
)


def test_mission_import(flight, tmp_path):
    """Imports tests/data/example-mission.plan (QGroundControl format) and uploads its mission, then its rally
    points; the vehicle then holds both. (The plan has rally points because MAVSDK refuses to upload an empty
    list, NO_MISSION_AVAILABLE, without asking the vehicle: with MAVSDK-Python's own example-mission.plan, which
    has none, the example fails against any autopilot.)"""
    f = flight(speed=2)
    run = run_example("mission_import", f.mavlink_port, tmp_path, timeout=120, cwd=PLAN_DIR)
    assert "5 mission items and 2 rally items imported." in run.stdout, run.describe()
    assert_exit_0(run)
    assert "Mission uploaded" in run.stdout, run.describe()
    station = f.observer.stop_recording()
    for mission_type, expected in (
        (mavlink.MAV_MISSION_TYPE_MISSION, PLAN_ITEMS),
        (mavlink.MAV_MISSION_TYPE_RALLY, PLAN_RALLY_POINTS),
    ):
        items = station.download_mission(mission_type=mission_type)
        assert items is not None, f"the vehicle did not hand back its items of mission type {mission_type}"
        got = [(i.command, i.x * 1e-7, i.y * 1e-7, i.z) for i in items]
        assert got == [pytest.approx(item, abs=1e-6) for item in expected]


DISCARDED_ZONE = "Geofence invalid, doesn't contain Home position"  # PX4's text for a fence zone barring home


def test_geofence(flight, tmp_path):
    """Uploads an inclusion polygon of ±0.0001° around home with a zero-radius inclusion circle at (0, 0), the
    example's "no circle": the vehicle accepts the list and hands it back whole, and, as PX4, discards the circle
    (it holds no point, so not home) with a critical text, keeping the polygon as its fence."""
    f = flight(speed=2)
    run = run_example("geofence", f.mavlink_port, tmp_path, timeout=120)
    assert_exit_0(run)
    assert "Geofence uploaded!" in run.stdout, run.describe()
    f.observer.wait_for(lambda r: DISCARDED_ZONE in r.texts, "the circle discarded", CATCH_UP_S)
    items = f.observer.stop_recording().download_mission(mission_type=mavlink.MAV_MISSION_TYPE_FENCE)
    assert items is not None, "the vehicle did not hand its fence back"
    lat, lon = HOME[0], HOME[1]
    corners = [(lat - 1e-4, lon - 1e-4), (lat + 1e-4, lon - 1e-4), (lat + 1e-4, lon + 1e-4), (lat - 1e-4, lon + 1e-4)]
    vertices, circle = items[:4], items[4:]
    assert [v.command for v in vertices] == [mavlink.MAV_CMD_NAV_FENCE_POLYGON_VERTEX_INCLUSION] * 4
    assert [v.param1 for v in vertices] == [4] * 4  # the polygon's vertex count
    assert [(v.x * 1e-7, v.y * 1e-7) for v in vertices] == [pytest.approx(c, abs=1e-7) for c in corners]
    assert [(c.command, c.param1, c.x, c.y) for c in circle] == [(mavlink.MAV_CMD_NAV_FENCE_CIRCLE_INCLUSION, 0, 0, 0)]


def listed_parameters() -> dict[str, float]:
    """`sitl-quad --list-params`: NAME VALUE description, one parameter a line."""
    listing = subprocess.run(
        [REPO / ".venv" / "bin" / "python", "-m", "sitl_quad", "--list-params"],
        cwd=REPO,
        capture_output=True,
        text=True,
        check=True,
        timeout=120,
    ).stdout
    return {name: float(value) for name, value, *_ in (line.split() for line in listing.splitlines() if line.strip())}


def test_all_params(flight, tmp_path):
    """Prints every parameter: the same names and values as the vehicle lists."""
    f = flight(speed=2)
    run = run_example("all_params", f.mavlink_port, tmp_path, timeout=120)
    assert_exit_0(run)
    printed = {name: float(value) for name, value in (line.split(": ") for line in run.stdout.splitlines())}
    expected = listed_parameters()
    assert printed.keys() == expected.keys(), run.describe()
    assert printed == pytest.approx(expected, rel=1e-5)  # the listing prints 6 significant digits


def test_firmware_version(flight, tmp_path):
    """Prints the flight software version the vehicle's AUTOPILOT_VERSION carries."""
    f = flight(speed=2)
    run = run_example("firmware_version", f.mavlink_port, tmp_path, timeout=120)
    assert_exit_0(run)
    ack, version = f.observer.stop_recording().request(
        mavlink.MAV_CMD_REQUEST_MESSAGE,
        mavlink.MAVLINK_MSG_ID_AUTOPILOT_VERSION,
        reply="AUTOPILOT_VERSION",
    )
    assert version is not None, f"no AUTOPILOT_VERSION (ack {ack})"
    major, minor, patch = (version.flight_sw_version >> shift & 0xFF for shift in (24, 16, 8))
    assert f"flight_sw_major: {major}, flight_sw_minor: {minor}, flight_sw_patch: {patch}," in run.stdout, (
        run.describe()
    )


# ----- offboard (real time: see the module docstring)
# MAVSDK's Offboard plugin drops the setpoint an example has just set when an autopilot heartbeat not in OFFBOARD
# arrives before offboard.start() (OffboardImpl::process_heartbeat stops the setpoints unless a start came in
# the last 3 s, and none has): start() then answers NO_SETPOINT_SET without asking the vehicle. Against PX4 too
# (1 Hz heartbeats); the window is the few milliseconds between the example's two calls, longer on a loaded
# machine. That result, and only it, runs the example again (it has disarmed the vehicle and exited 0).
MAVSDK_SETPOINT_RACE = "Starting offboard mode failed with error code: NO_SETPOINT_SET"
SETPOINT_RACE_RERUNS = 2


def fly_offboard_example(flight, tmp_path: Path, name: str, timeout: float) -> VehicleObserver:
    """Run an offboard example at real time; it must have exited 0 with the vehicle flown in OFFBOARD (an
    example whose offboard.start() fails prints so, disarms and still exits 0)."""
    f = flight(speed=1)
    for _ in range(1 + SETPOINT_RACE_RERUNS):
        run = run_example(name, f.mavlink_port, tmp_path, timeout=timeout)
        assert_exit_0(run)
        if MAVSDK_SETPOINT_RACE not in run.stdout:
            break
    assert "Starting offboard mode failed" not in run.stdout, f"{run.describe()}\n{f.observer.summary()}"
    f.observer.wait_for(lambda r: FlightMode.OFFBOARD in r.modes_seen, "OFFBOARD", CATCH_UP_S)
    return f.observer


def saw_yaw(record: FlightRecord, degrees: float, tolerance: float = 10.0) -> bool:
    return any(abs((yaw - degrees + 180.0) % 360.0 - 180.0) < tolerance for yaw in record.yaws_deg)


def test_offboard_attitude(flight, tmp_path):
    """Attitude setpoints: up at 70 % thrust, roll +30° and -30° at 60 %, level; then stop offboard and land."""
    observer = fly_offboard_example(flight, tmp_path, "offboard_attitude", timeout=120)
    observer.wait_for(lambda r: max(r.rolls_deg) > 25.0 and min(r.rolls_deg) < -25.0, "both rolls", CATCH_UP_S)
    observer.wait_for(lambda r: r.max_height() > 1.0, "above 1 m", CATCH_UP_S)
    observer.wait_for(FlightRecord.settled_on_ground, "landed and disarmed")


def test_offboard_position_ned(flight, tmp_path):
    """Position setpoints in the local NED frame: 5 m up, 5 m north facing east, 10 m east, then down."""
    observer = fly_offboard_example(flight, tmp_path, "offboard_position_ned", timeout=150)
    for north, east, height in ((0.0, 0.0, 5.0), (5.0, 0.0, 5.0), (5.0, 10.0, 5.0)):
        observer.wait_for(
            lambda r, p=(north, east, height): r.passed_near(*p, 1.0), f"at {(north, east, height)}", CATCH_UP_S
        )
    observer.wait_for(lambda r: saw_yaw(r, 90.0) and saw_yaw(r, 180.0), "facing east and south", CATCH_UP_S)
    observer.wait_for(lambda r: r.mode == FlightMode.AUTO_LOITER, "offboard.stop's hold", CATCH_UP_S)


def test_offboard_velocity_ned(flight, tmp_path):
    """Velocity setpoints in NED: up 2 m/s, north, south, west, east at 2 m/s for 4 s each, turning as told."""
    observer = fly_offboard_example(flight, tmp_path, "offboard_velocity_ned", timeout=150)
    observer.wait_for(lambda r: r.max_height() > 6.0, "above 6 m (8 m nominal)", CATCH_UP_S)
    observer.wait_for(lambda r: max(s.north for s in r.track) > 5.0, "5 m north (8 m nominal)", CATCH_UP_S)
    observer.wait_for(lambda r: min(s.east for s in r.track) < -5.0, "5 m west", CATCH_UP_S)
    yaws = (90.0, 270.0, 180.0)
    observer.wait_for(lambda r: all(saw_yaw(r, yaw) for yaw in yaws), f"facing {yaws} degrees", CATCH_UP_S)
    observer.wait_for(lambda r: r.mode == FlightMode.AUTO_LOITER, "offboard.stop's hold", CATCH_UP_S)


def test_offboard_velocity_body(flight, tmp_path):
    """Body-frame velocity setpoints: climb 1 m/s turning, a 5 m/s circle forwards and one sideways."""
    observer = fly_offboard_example(flight, tmp_path, "offboard_velocity_body", timeout=180)
    # 1 m/s up for the example's 5 s, of which the motors' 1 s spool-up (COM_SPOOLUP_TIME) and the ramp to 1 m/s
    # leave at most 4 m: a 4 m bar was met only by the example's sleeps overrunning (fresh-clone run at 52ecf82:
    # 4.0 m, failed); 3 m still says it climbed as told
    observer.wait_for(lambda r: r.max_height() > 3.0, "above 3 m (5 s at 1 m/s, less the spool-up)", CATCH_UP_S)
    # a 5 m/s, 30°/s circle has a radius of 9.5 m: the vehicle gets well away from where it started
    observer.wait_for(lambda r: max(math.hypot(s.north, s.east) for s in r.track) > 12.0, "12 m away", CATCH_UP_S)
    observer.wait_for(lambda r: {int(y // 45) for y in r.yaws_deg} == set(range(8)), "every heading", CATCH_UP_S)
    observer.wait_for(lambda r: r.mode == FlightMode.AUTO_LOITER, "offboard.stop's hold", CATCH_UP_S)
