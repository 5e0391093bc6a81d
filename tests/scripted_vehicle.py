"""A tiny scripted in-test vehicle (sysid 1 / compid 1 on a loopback UDP port) for the link's failure paths:
it scripts only the MAVLink exchanges a test needs (refusals, silences, lost requests, a reboot). The real
vehicle (sitl_quad) is flown in test_gcs_integration.py."""

import os
import socket
import threading
import time

os.environ["MAVLINK20"] = "1"
from pymavlink.dialects.v20 import common as mavlink

from uavcore.mavlink import item_message


class ScriptedVehicle(threading.Thread):
    """sysid 1 / compid 1 on a UDP port: heartbeats, ATTITUDE with time_boot_ms, a full battery (SYS_STATUS),
    commands, mission transfer."""

    def __init__(self) -> None:
        super().__init__(daemon=True)
        self.sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self.sock.bind(("127.0.0.1", 0))
        self.sock.settimeout(0.05)
        self.port = self.sock.getsockname()[1]
        self.mav = mavlink.MAVLink(None, srcSystem=1, srcComponent=1)
        self.parser = mavlink.MAVLink(None)
        self.peer = None
        self.running = True
        self.silent = False  # no heartbeats, no answers
        self.command_results: dict[int, int | None] = {}  # None: never acknowledge
        self.refusal_texts: dict[int, str] = {}  # a STATUSTEXT sent just after a command's refusal, as PX4 does
        self.commands_seen: list[int] = []
        self.mission_result = mavlink.MAV_MISSION_ACCEPTED
        self.drop_first_request_of: set[int] = set()
        self.ignore_mission = False
        self.stored: list = []
        self.expected = 0
        self.landed_state: int | None = None  # sent in EXTENDED_SYS_STATE when set (MAV_LANDED_STATE_*)
        self.gcs_heartbeats: list = []
        self.gcs_heartbeat_times: list[float] = []  # time.monotonic() at each GCS heartbeat's arrival
        self.boot_start = time.monotonic()
        self.last_periodic = 0.0

    def boot_ms(self) -> int:
        # never below 0: a test moving boot_start while this thread computes would otherwise pack a negative
        # uint32, kill the thread, and leave the link nothing to detect a reboot from
        return max(0, int((time.monotonic() - self.boot_start) * 1000) + 60_000)

    def send(self, message) -> None:
        if self.peer is not None and not self.silent:
            self.sock.sendto(message.pack(self.mav), self.peer)

    def run(self) -> None:
        while self.running:
            now = time.monotonic()
            if now - self.last_periodic > 0.1:
                self.last_periodic = now
                self.send(self.mav.heartbeat_encode(2, 12, 1, 0, mavlink.MAV_STATE_STANDBY))
                self.send(self.mav.attitude_encode(self.boot_ms(), 0.0, 0.0, 0.5, 0.0, 0.0, 0.0))
                # a full pack (12.6 V, 100 %): the service's pre-flight check refuses to arm one reporting no charge
                self.send(self.mav.sys_status_encode(0, 0, 0, 0, 12600, 0, 100, 0, 0, 0, 0, 0, 0))
                if self.landed_state is not None:
                    self.send(self.mav.extended_sys_state_encode(0, self.landed_state))
            try:
                data, self.peer = self.sock.recvfrom(65535)
            except TimeoutError:
                continue
            for message in self.parser.parse_buffer(data) or []:
                self.handle(message)

    def request(self, seq: int) -> None:
        if seq in self.drop_first_request_of:
            self.drop_first_request_of.discard(seq)
            return
        self.send(self.mav.mission_request_int_encode(255, 190, seq, 0))

    def handle(self, m) -> None:
        kind = m.get_type()
        if kind == "HEARTBEAT":
            self.gcs_heartbeats.append((m.get_srcSystem(), m.get_srcComponent(), m.type))
            self.gcs_heartbeat_times.append(time.monotonic())
        elif kind == "COMMAND_LONG":
            self.commands_seen.append(m.command)
            result = self.command_results.get(m.command, mavlink.MAV_RESULT_ACCEPTED)
            if result is not None:
                self.send(self.mav.command_ack_encode(m.command, result))
            if result != mavlink.MAV_RESULT_ACCEPTED and m.command in self.refusal_texts:
                text = self.refusal_texts[m.command].encode()
                self.send(self.mav.statustext_encode(mavlink.MAV_SEVERITY_CRITICAL, text))
        elif kind == "MISSION_COUNT" and not self.ignore_mission:
            if self.mission_result != mavlink.MAV_MISSION_ACCEPTED:
                self.send(self.mav.mission_ack_encode(255, 190, self.mission_result, 0))
                return
            self.expected, self.stored = m.count, []
            self.request(0)
        elif kind == "MISSION_ITEM_INT" and m.seq == len(self.stored):
            self.stored.append(m)
            if len(self.stored) < self.expected:
                self.request(len(self.stored))
            else:
                self.send(self.mav.mission_ack_encode(255, 190, mavlink.MAV_MISSION_ACCEPTED, 0))
        elif kind == "MISSION_ITEM_INT" and m.seq < len(self.stored) < self.expected:
            self.request(len(self.stored))  # a repeated item: the GCS missed our request, ask again
        elif kind == "MISSION_REQUEST_LIST":
            self.send(self.mav.mission_count_encode(255, 190, len(self.stored), 0))
        elif kind == "MISSION_REQUEST_INT" and m.seq < len(self.stored):
            item = self.stored[m.seq]
            self.send(item_message(item, 255, 190))

    def stop(self) -> None:
        self.running = False
        self.join(2)
        self.sock.close()
