"""The ground station's vehicle link over every connection form, with vehicle discovery by heartbeat.

Each form talks to the real vehicle process: udpout to its port, udpin with the vehicle streaming to the service
(`sitl-quad --out`, as PX4 SITL and radios do to 14550), TCP and serial through small byte bridges to the
vehicle's UDP port (what mavlink-router's TCP server and a telemetry radio are). On each, the link discovers the
vehicle's system id, uploads and downloads a mission, and arms.
"""

from __future__ import annotations

import asyncio
import contextlib
import math
import os
import select
import socket
import threading
import time
import tty

import pytest
from sitl_process import SitlProcess

from bench.processes import free_port, free_udp_port, stop_process
from gcs.vehicle.connection import ConnectionStringError, parse_connection
from gcs.vehicle.link import LinkManager
from uavcore.geodesy import DEFAULT_HOME, LocalFrame
from uavcore.mavlink import Encoder, mavlink
from uavcore.mission import MavCmd, MavFrame, MissionItem

pytestmark = pytest.mark.integration

CONNECT_S = 60.0


# ----- connection strings


@pytest.mark.parametrize(
    ("url", "kind", "host", "port"),
    [
        ("udpin://0.0.0.0:14550", "udpin", "0.0.0.0", 14550),
        ("udpin://:14550", "udpin", "0.0.0.0", 14550),
        ("udp://:14540", "udpin", "0.0.0.0", 14540),  # MAVSDK's form for listening
        ("udpin:127.0.0.1:14550", "udpin", "127.0.0.1", 14550),  # pymavlink's form
        ("udpout://127.0.0.1:14540", "udpout", "127.0.0.1", 14540),
        ("udpout:127.0.0.1:14540", "udpout", "127.0.0.1", 14540),
        ("tcp://127.0.0.1:5760", "tcp", "127.0.0.1", 5760),
        ("tcp://[::1]:5760", "tcp", "::1", 5760),
    ],
)
def test_connection_strings_as_mavsdk_and_pymavlink_users_write_them(url, kind, host, port):
    connection = parse_connection(url)
    assert (connection.kind, connection.host, connection.port) == (kind, host, port)


def test_serial_connection_strings():
    assert parse_connection("serial:///dev/ttyUSB0:57600").device == "/dev/ttyUSB0"
    assert parse_connection("serial:///dev/ttyACM0:921600").baud == 921600
    assert parse_connection("serial:///dev/ttyUSB0").baud == 57600


@pytest.mark.parametrize(
    ("url", "why"),
    [
        ("14550", "no scheme"),
        ("http://127.0.0.1:8000", "unknown scheme 'http'"),
        ("udpout://127.0.0.1", "port"),
        ("udpout://:14540", "needs a host"),
        ("tcp://127.0.0.1:99999", "port"),
        ("udpin://0.0.0.0:abc", "port"),
        ("serial://ttyUSB0:57600", "device path"),
        ("serial:///dev/ttyUSB0:9", "baud rate 9"),
    ],
)
def test_a_malformed_connection_string_is_a_clear_error(url, why):
    with pytest.raises(ConnectionStringError) as error:
        parse_connection(url)
    assert why in str(error.value) and "udpin://0.0.0.0:14550" in str(error.value)


def test_the_cli_refuses_a_malformed_vehicle_connection(capsys):
    from gcs.cli import main

    assert main(["serve", "--vehicle", "udp:127.0.0.1"]) == 2
    assert "vehicle connection" in capsys.readouterr().err


# ----- helpers


def _mission(home: tuple[float, float, float]) -> list[MissionItem]:
    frame = LocalFrame(*home)
    north = frame.from_ned(30.0, 0.0, 0.0)
    rel = MavFrame.GLOBAL_RELATIVE_ALT_INT
    return [
        MissionItem(0, rel, MavCmd.NAV_TAKEOFF, current=1, x=round(home[0] * 1e7), y=round(home[1] * 1e7), z=5.0),
        MissionItem(
            1, rel, MavCmd.NAV_WAYPOINT, param1=0.0, param2=2.0, x=round(north[0] * 1e7), y=round(north[1] * 1e7), z=5.0
        ),
        MissionItem(2, MavFrame.MISSION, MavCmd.NAV_RETURN_TO_LAUNCH),
    ]


def _same(a: list[MissionItem], b: list[MissionItem]) -> bool:
    def key(item: MissionItem) -> tuple:
        return tuple(v if not (isinstance(v, float) and math.isnan(v)) else "nan" for v in vars(item).values())

    return [key(i) for i in a] == [key(i) for i in b]


async def _exercise(url: str, sysid: int) -> LinkManager:
    """Connect, check the discovered identity, round-trip a mission, arm and disarm; returns the stopped link."""
    link = LinkManager(url, heartbeat_timeout_s=5.0)
    await link.start()
    try:
        assert await link.wait_connected(CONNECT_S), f"no vehicle heartbeat on {url}"
        assert link.vehicle.sysid == sysid and link.vehicle.compid == 1
        assert link.status.autopilot == "PX4" and link.status.vehicle_type == "QUADROTOR"
        items = _mission(DEFAULT_HOME)
        await link.upload_mission(items, DEFAULT_HOME)
        assert _same(await link.download_mission(), items)
        await link.arm()
        deadline = time.monotonic() + CONNECT_S
        while not link.status.armed:
            assert time.monotonic() < deadline, "the heartbeat never showed the vehicle armed"
            await asyncio.sleep(0.05)
        await link.disarm()
    finally:
        await link.stop()
    return link


class StreamBridge(threading.Thread):
    """Bytes between a stream endpoint (a connected TCP socket or a pty's master side) and the vehicle's UDP port,
    one UDP datagram per chunk read (MAVLink frames may be split across chunks: the link parses a stream)."""

    def __init__(self, vehicle_port: int) -> None:
        super().__init__(daemon=True)
        self.udp = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self.udp.bind(("127.0.0.1", 0))
        self.vehicle = ("127.0.0.1", vehicle_port)
        self.read_stream = self.write_stream = None
        self.stream_fd: int | None = None
        self.running = True

    def run(self) -> None:
        while self.running:
            fds = [self.udp] + ([self.stream_fd] if self.stream_fd is not None else [])
            ready, _, _ = select.select(fds, [], [], 0.05)
            for fd in ready:
                if fd is self.udp:
                    data = self.udp.recv(65535)
                    if self.write_stream is not None:
                        with contextlib.suppress(OSError):  # the link closed its end at the test's end
                            self.write_stream(data)
                else:
                    try:
                        data = self.read_stream()
                    except OSError:
                        data = b""
                    if data:
                        self.udp.sendto(data, self.vehicle)

    def stop(self) -> None:
        self.running = False
        self.join(timeout=5)
        self.udp.close()


@pytest.fixture
def vehicle(request):
    """A vehicle process; request.param: extra command-line arguments."""
    started = []

    def start(*extra: str) -> SitlProcess:
        process = SitlProcess(speed=5.0, extra_args=extra)
        started.append(process)
        return process.start()

    yield start
    for process in started:
        process.cleanup()


# ----- each connection form against the real vehicle


def test_udpout_to_the_vehicle(vehicle):
    sitl = vehicle()
    asyncio.run(_exercise(f"udpout://127.0.0.1:{sitl.port}", sysid=1))


def test_udpin_with_the_vehicle_streaming_to_the_service_and_sysid_discovered(vehicle):
    port = free_udp_port()
    vehicle("--sysid", "7", "--out", f"127.0.0.1:{port}")
    asyncio.run(_exercise(f"udpin://127.0.0.1:{port}", sysid=7))


def test_tcp_through_a_tcp_server_in_front_of_the_vehicle(vehicle):
    sitl = vehicle("--sysid", "3")
    server = socket.create_server(("127.0.0.1", 0))
    bridge = StreamBridge(sitl.port)

    def accept() -> None:
        conn, _ = server.accept()
        bridge.read_stream = lambda: conn.recv(65535)
        bridge.write_stream = conn.sendall
        bridge.stream_fd = conn.fileno()

    threading.Thread(target=accept, daemon=True).start()
    bridge.start()
    try:
        asyncio.run(_exercise(f"tcp://127.0.0.1:{server.getsockname()[1]}", sysid=3))
    finally:
        bridge.stop()
        server.close()


def test_serial_through_a_pty_pair(vehicle):
    sitl = vehicle("--sysid", "4")
    master, slave = os.openpty()
    tty.setraw(slave)  # no echo or line editing before the link sets its own raw mode
    bridge = StreamBridge(sitl.port)
    bridge.read_stream = lambda: os.read(master, 65535)
    bridge.write_stream = lambda data: os.write(master, data)
    bridge.stream_fd = master
    bridge.start()
    try:
        asyncio.run(_exercise(f"serial://{os.ttyname(slave)}:115200", sysid=4))
    finally:
        bridge.stop()
        os.close(master)
        os.close(slave)


# ----- other components on the link, a different vehicle, a new boot


class OtherComponents(threading.Thread):
    """Heartbeats of things that are not the vehicle, sent to the service's udpin port from their own socket:
    a camera and a companion computer on the vehicle's system, and another ground station."""

    def __init__(self, service_port: int, vehicle_sysid: int) -> None:
        super().__init__(daemon=True)
        self.sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self.sock.bind(("127.0.0.1", 0))
        self.target = ("127.0.0.1", service_port)
        self.senders = [
            (Encoder(vehicle_sysid, mavlink.MAV_COMP_ID_CAMERA), mavlink.MAV_TYPE_CAMERA),
            (Encoder(vehicle_sysid, mavlink.MAV_COMP_ID_ONBOARD_COMPUTER), mavlink.MAV_TYPE_ONBOARD_CONTROLLER),
            (Encoder(254, 190), mavlink.MAV_TYPE_GCS),
        ]
        self.running = True
        self.received = 0

    def run(self) -> None:
        self.sock.settimeout(0.1)
        while self.running:
            for encoder, kind in self.senders:
                beat = mavlink.MAVLink_heartbeat_message(kind, mavlink.MAV_AUTOPILOT_INVALID, 0, 0, 4, 3)
                self.sock.sendto(encoder.pack(beat), self.target)
            try:
                while self.sock.recv(65535):
                    self.received += 1
            except OSError:
                pass

    def stop(self) -> None:
        self.running = False
        self.join(timeout=5)
        self.sock.close()


def test_a_link_with_other_components_on_it_finds_the_vehicle_and_answers_only_it(vehicle):
    port = free_udp_port()
    others = OtherComponents(port, vehicle_sysid=7)

    async def scenario() -> None:
        link = LinkManager(f"udpin://127.0.0.1:{port}", heartbeat_timeout_s=5.0)
        await link.start()
        others.start()  # heard first: a link that answered its first sender would talk to the camera
        try:
            await asyncio.sleep(1.5)
            assert link.vehicle is None and not link.status.connected
            vehicle("--sysid", "7", "--out", f"127.0.0.1:{port}")
            assert await link.wait_connected(CONNECT_S)
            assert (link.vehicle.sysid, link.vehicle.compid) == (7, 1)
            items = _mission(DEFAULT_HOME)
            await link.upload_mission(items, DEFAULT_HOME)
            assert _same(await link.download_mission(), items)
        finally:
            await link.stop()

    try:
        asyncio.run(scenario())
    finally:
        others.stop()


def test_another_system_id_after_the_vehicle_falls_silent_is_a_different_vehicle(vehicle):
    port = free_udp_port()

    async def scenario() -> None:
        # The vehicles' heartbeats come at 1 Hz of wall clock: a timeout of 2 s was one late heartbeat on a loaded
        # machine from dropping the first vehicle while both stream.
        link = LinkManager(f"udpin://127.0.0.1:{port}", heartbeat_timeout_s=5.0)
        await link.start()
        try:
            first = vehicle("--sysid", "5", "--out", f"127.0.0.1:{port}")
            assert await link.wait_connected(CONNECT_S)
            assert link.vehicle.sysid == 5
            incarnation = link.status.incarnation
            second = vehicle("--sysid", "6", "--out", f"127.0.0.1:{port}")
            await asyncio.sleep(3.0)  # both stream now: the link stays with the vehicle it has
            assert link.vehicle.sysid == 5
            first.stop()
            deadline = time.monotonic() + CONNECT_S
            while link.vehicle.sysid != 6:
                assert time.monotonic() < deadline, "the link never moved to the vehicle still streaming"
                await asyncio.sleep(0.1)
            assert link.status.incarnation > incarnation and link.status.reboots == 0
            assert second.alive()
        finally:
            await link.stop()

    asyncio.run(scenario())


def test_links_made_for_system_ids_share_one_port_as_a_router_delivers_a_fleet(vehicle):
    """Two vehicles stream to one listening port (as mavlink-router hands a fleet to a ground station): a link
    made for system id 6 takes vehicle 6 even while vehicle 5 is heard first, and commands only it."""
    port = free_udp_port()

    async def scenario() -> None:
        link = LinkManager(f"udpin://127.0.0.1:{port}", heartbeat_timeout_s=5.0, sysid=6)
        assert link.target == (6, 1)  # before any heartbeat: commands would already go to system 6
        await link.start()
        try:
            vehicle("--sysid", "5", "--out", f"127.0.0.1:{port}")
            await asyncio.sleep(1.5)
            assert link.vehicle is None  # vehicle 5 streams, and is not taken
            vehicle("--sysid", "6", "--out", f"127.0.0.1:{port}")
            assert await link.wait_connected(CONNECT_S)
            assert link.vehicle.sysid == 6 and link.status.sysid == 6
            items = _mission(DEFAULT_HOME)
            await link.upload_mission(items, DEFAULT_HOME)
            assert _same(await link.download_mission(), items)
        finally:
            await link.stop()

    asyncio.run(scenario())


def test_a_new_boot_is_recognised_by_its_boot_instant_even_when_its_clock_is_ahead():
    """A scripted autopilot: the second boot's time_boot_ms is larger than the first's (a fast lockstep clock
    overtook it), but its SYSTEM_TIME gives another boot instant."""
    sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    sock.bind(("127.0.0.1", 0))
    encoder = Encoder(1, 1)

    def send(port: int, boot_ms: int, unix_s: float) -> None:
        beat = mavlink.MAVLink_heartbeat_message(
            mavlink.MAV_TYPE_QUADROTOR, mavlink.MAV_AUTOPILOT_PX4, mavlink.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED, 0, 3, 3
        )
        clock = mavlink.MAVLink_system_time_message(round(unix_s * 1e6), boot_ms)
        sock.sendto(encoder.pack(beat) + encoder.pack(clock), ("127.0.0.1", port))

    async def scenario() -> None:
        link = LinkManager(f"udpin://127.0.0.1:{free_udp_port()}")
        await link.start()
        port = link._transport.local_port
        try:
            now = time.time()
            for k in range(5):  # first boot: 100 s ago; clock readings consistent with it
                send(port, 100_000 + 200 * k, now + 0.2 * k)
                await asyncio.sleep(0.05)
            assert link.status.connected and link.status.reboots == 0
            for k in range(5):  # second boot 30 s ago whose clock reads further than the first's did
                send(port, 130_000 + 200 * k, now + 100 + 0.2 * k)
                await asyncio.sleep(0.05)
            assert link.status.reboots == 1
            assert link.status.boot_instant_s == pytest.approx(now + 100 - 130, abs=0.01)
        finally:
            await link.stop()

    try:
        asyncio.run(scenario())
    finally:
        sock.close()


# ----- `buoy-gcs up --vehicle URL`: the service alone, for a vehicle it does not start


def test_up_with_a_vehicle_url_starts_only_the_service():
    from gcs.settings import Settings
    from stack.children import children
    from stack.options import UpOptions

    settings = Settings(vehicle_url="udpin://0.0.0.0:14550")
    (service,) = children(UpOptions(settings=settings, simulate=False))
    assert service.name == "gcs"
    assert service.argv[service.argv.index("--vehicle") + 1] == "udpin://0.0.0.0:14550"


def test_up_refuses_the_simulated_demo_with_a_real_vehicle(capsys):
    from stack.cli import main

    assert main(["up", "--vehicle", "udpin://0.0.0.0:14550", "--demo"]) == 2
    assert "--demo" in capsys.readouterr().err


@pytest.mark.slow
def test_up_listens_for_a_vehicle_streaming_to_it(tmp_path, vehicle):
    import json
    import subprocess
    import sys
    import urllib.request

    mavlink_port, http_port = free_udp_port(), free_port(socket.SOCK_STREAM)  # HTTP is TCP: a free TCP port
    env = {k: v for k, v in os.environ.items() if not k.startswith("BUOY_GCS_")}
    up = subprocess.Popen(
        [
            *(sys.executable, "-m", "stack", "up", "--vehicle", f"udpin://127.0.0.1:{mavlink_port}"),
            *("--port", str(http_port), "--data", str(tmp_path)),
        ],
        env=env,
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
    )
    try:
        vehicle("--sysid", "9", "--out", f"127.0.0.1:{mavlink_port}")
        deadline = time.monotonic() + CONNECT_S
        while True:
            try:
                with urllib.request.urlopen(f"http://127.0.0.1:{http_port}/vehicle", timeout=2) as response:
                    state = json.load(response)
                if state.get("connected"):
                    break
            except OSError:
                pass
            assert up.poll() is None, "buoy-gcs up exited"
            assert time.monotonic() < deadline, "the service never heard the vehicle"
            time.sleep(0.2)
        assert state["sysid"] == 9 and state["autopilot"] == "PX4"
    finally:
        stop_process(up, 20)


@pytest.mark.parametrize(
    ("landed_state", "alt_m", "on_ground"),
    [
        (mavlink.MAV_LANDED_STATE_ON_GROUND, 3.0, True),  # the vehicle's word wins
        (mavlink.MAV_LANDED_STATE_IN_AIR, 0.1, False),
        (None, 0.2, True),  # no EXTENDED_SYS_STATE (ArduPilot's stream groups): by altitude above home
        (mavlink.MAV_LANDED_STATE_UNDEFINED, 4.0, False),
        (None, None, False),
    ],
)
def test_on_ground_from_the_landed_state_or_else_the_altitude(landed_state, alt_m, on_ground):
    from gcs.vehicle.link import VehicleStatus

    assert VehicleStatus(landed_state=landed_state, alt_m=alt_m).on_ground is on_ground
