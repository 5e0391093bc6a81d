"""The vehicle's UDP side: --out push targets, routing between peers, and signing."""

from __future__ import annotations

import socket
import time

import pytest
from sitl_process import WAIT_S, GroundStation

from bench.processes import free_udp_port
from sitl_quad.mavlink.link import UdpLink
from uavcore.mavlink import mavlink

pytestmark = pytest.mark.integration


def test_out_target_receives_telemetry_without_asking(start_sitl):
    port = free_udp_port()
    listener = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    listener.bind(("127.0.0.1", port))
    listener.settimeout(1.0)
    start_sitl(speed=5.0, extra_args=("--out", f"127.0.0.1:{port}"))
    parser = mavlink.MAVLink(None)
    kinds = set()
    deadline = time.monotonic() + WAIT_S
    try:
        while time.monotonic() < deadline and not {"HEARTBEAT", "GLOBAL_POSITION_INT"} <= kinds:
            try:
                data = listener.recv(65535)
            except TimeoutError:
                continue
            kinds.update(m.get_type() for m in parser.parse_buffer(data) or [])
    finally:
        listener.close()
    assert {"HEARTBEAT", "GLOBAL_POSITION_INT"} <= kinds


def test_vehicle_routes_messages_between_peers(start_sitl):
    sitl = start_sitl(speed=5.0)
    gcs = GroundStation(sitl.port)
    onboard = GroundStation(sitl.port, sysid=1, compid=mavlink.MAV_COMP_ID_ONBOARD_COMPUTER)
    try:
        gcs.connect()
        onboard.connect()
        # broadcast messages from the onboard computer reach the ground station through the vehicle
        seen = None
        deadline = time.monotonic() + WAIT_S
        while seen is None and time.monotonic() < deadline:
            onboard.mav.debug_vect_send(b"ESO_Z3", 0, 1.0, 2.0, 3.0)
            msg = gcs.conn.recv_match(type="DEBUG_VECT", blocking=True, timeout=0.5)
            if msg is not None and msg.get_srcComponent() == mavlink.MAV_COMP_ID_ONBOARD_COMPUTER:
                seen = msg
        assert seen is not None and (seen.x, seen.y, seen.z) == (1.0, 2.0, 3.0)
        # a command for the vehicle itself is answered by the vehicle and not echoed to the other peer
        ack = onboard.command(mavlink.MAV_CMD_REQUEST_MESSAGE, mavlink.MAVLINK_MSG_ID_AUTOPILOT_VERSION)
        assert ack.result == mavlink.MAV_RESULT_ACCEPTED
        # The vehicle handles one peer's datagrams in order: a DEBUG_VECT sent after the command reaches the ground
        # station after any echo of it would have (was: nothing within 1 s, which a slow machine passes by luck).
        onboard.mav.debug_vect_send(b"MARKER", 0, 4.0, 5.0, 6.0)

        def echo_or_marker(m) -> bool:
            return m.get_type() == "COMMAND_LONG" or m.name == "MARKER"

        after = gcs.recv(["COMMAND_LONG", "DEBUG_VECT"], timeout=WAIT_S, condition=echo_or_marker)
        assert after is not None and after.get_type() == "DEBUG_VECT"
    finally:
        gcs.close()
        onboard.close()


def test_signed_vehicle_refuses_unsigned_commands_and_obeys_the_keyed_station(start_sitl):
    key = bytes(range(32))
    vehicle = start_sitl(speed=5.0, extra_args=("--signing-key", key.hex()))
    keyed = GroundStation(vehicle.port)
    keyed.conn.setup_signing(key, sign_outgoing=True)
    stranger = GroundStation(vehicle.port, sysid=254)
    try:
        keyed.connect()
        assert stranger.command(mavlink.MAV_CMD_COMPONENT_ARM_DISARM, 1, timeout=3) is None  # silently refused
        while keyed.conn.recv_match(blocking=False) is not None:
            pass  # 3 s of unread telemetry at 5x can fill the socket buffer; start from a drained socket
        heartbeat = keyed.recv("HEARTBEAT", timeout=5)
        assert not heartbeat.base_mode & mavlink.MAV_MODE_FLAG_SAFETY_ARMED
        assert keyed.command(mavlink.MAV_CMD_COMPONENT_ARM_DISARM, 1).result == mavlink.MAV_RESULT_ACCEPTED
        status = keyed.recv("SYS_STATUS", timeout=5)
        assert status.errors_count4 > 0  # the refused unsigned messages are counted
    finally:
        keyed.close()
        stranger.close()


def test_a_message_read_late_carries_the_time_it_reached_the_socket():
    """The vehicle reads the kernel's receive timestamp: a setpoint that waited 0.3 s in the socket (a process the
    machine did not schedule) is known to be 0.3 s old, not as fresh as the moment it was read."""
    link = UdpLink(port=0)
    sender = GroundStation(link.address[1])
    try:
        sent_before = time.monotonic()
        sender.send_heartbeat()
        sent_after = time.monotonic()
        time.sleep(0.3)
        read_at = time.monotonic()
        received = link.receive()
    finally:
        sender.close()
        link.close()
    assert [r.msg.get_type() for r in received] == ["HEARTBEAT"]
    # the two clocks (the kernel stamps CLOCK_REALTIME) are compared to the microsecond; 1 ms leaves room for that
    assert sent_before - 0.001 <= received[0].at <= sent_after + 0.001 < read_at - 0.25
