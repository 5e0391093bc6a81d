"""MAVLink FTP, server side: the vehicle serves a directory read-only, as PX4 serves its SD card.

The protocol itself (payload, opcodes, sessions, bursts) is `uavcore.mavftp.FtpResponder`; this module is its
I/O: the files under `--ftp-root` (`DirectoryStore`), the FILE_TRANSFER_PROTOCOL messages addressed to the
serving component, and the burst packets streamed a few per loop pass.

Components: the directory is served by one component of the vehicle's system, the camera's
(MAV_COMP_ID_CAMERA, 100) by default since the files are its images, or the autopilot's (1). The autopilot
always answers FTP: when it serves nothing, every request is NAKed UnknownCommand at once, so that MAVProxy and
QGroundControl, which ask for "@PARAM/param.pck" over FTP first, fall back to the PARAM protocol without waiting
out their FTP timeouts. Without `--ftp-root` the camera component does not exist (its requests are forwarded to
the other peers like any message for a component the vehicle does not have).
"""

from __future__ import annotations

import logging
import os
from pathlib import Path

from sitl_quad.mavlink.link import Peer, UdpLink
from uavcore.mavftp import DEFAULT_SESSIONS, DirEntry, FtpCodecError, FtpPayload, FtpResponder
from uavcore.mavlink import AUTOPILOT_COMPID, mavlink

log = logging.getLogger(__name__)

CAMERA_COMPID = mavlink.MAV_COMP_ID_CAMERA  # 100
# Burst packets sent per loop pass (the loop passes at least every 5 ms): 32 packets, 7.6 kB, fit a socket
# buffer however slowly the client reads, and still stream about 1.5 MB/s.
BURST_PACKETS_PER_PASS = 32


class DirectoryStore:
    """The regular files and directories under `root`, by served path ("/" is root). A symbolic link that leads
    out of the root is treated as absent, like a path that climbs out of it (`uavcore.mavftp.served_path`):
    the client learns FileNotFound, never that something exists outside the served tree."""

    def __init__(self, root: Path) -> None:
        self.root = root.resolve()

    def _local(self, path: str) -> Path | None:
        local = (self.root / path.lstrip("/")).resolve()
        return local if local == self.root or local.is_relative_to(self.root) else None

    def size(self, path: str) -> int | None:
        local = self._local(path)
        if local is None or not local.is_file():
            return None
        return local.stat().st_size

    def read(self, path: str, offset: int, length: int) -> bytes:
        local = self._local(path)
        if local is None:
            raise FileNotFoundError(path)
        with open(local, "rb") as file:
            file.seek(offset)
            return file.read(length)

    def entries(self, path: str) -> list[DirEntry] | None:
        local = self._local(path)
        if local is None or not local.is_dir():
            return None
        out = []
        for entry in sorted(os.scandir(local), key=lambda e: e.name):
            inside = self._local(f"{path.rstrip('/')}/{entry.name}")
            if inside is None:
                continue  # a link out of the root
            if inside.is_dir():
                out.append(DirEntry(entry.name, True))
            elif inside.is_file():
                out.append(DirEntry(entry.name, False, inside.stat().st_size))
        return out


class FileTransfer:
    """FILE_TRANSFER_PROTOCOL for the vehicle: `root` served by `component`, refusals from the autopilot when it
    is not the one serving."""

    def __init__(
        self,
        link: UdpLink,
        root: Path | None = None,
        component: int = CAMERA_COMPID,
        max_sessions: int = DEFAULT_SESSIONS,
    ) -> None:
        self.link = link
        self.responders: dict[int, FtpResponder] = {AUTOPILOT_COMPID: FtpResponder(None)}
        if root is not None:
            self.responders[component] = FtpResponder(DirectoryStore(root), max_sessions)
            link.add_component(component)
        self._clients: dict[tuple, Peer] = {}  # client key (address, sysid, compid) -> the peer it came from

    def handlers(self) -> dict:
        return {"FILE_TRANSFER_PROTOCOL": self.handle}

    def handle(self, peer: Peer, msg) -> None:
        if msg.target_system not in (0, self.link.sysid):
            return
        # a broadcast (component 0) is the autopilot's to answer, as every request has one reply
        component = msg.target_component or AUTOPILOT_COMPID
        responder = self.responders.get(component)
        if responder is None:
            return
        try:
            request = FtpPayload.decode(bytes(msg.payload))
        except FtpCodecError as error:
            log.debug("FTP: %s", error)
            return
        client = (peer.address, msg.get_srcSystem(), msg.get_srcComponent())
        self._clients[client] = peer
        reply = responder.handle(client, request)
        if reply is not None:
            self._send(component, client, [reply])

    def poll(self) -> None:
        """Stream the next packets of running bursts (called on every loop pass)."""
        for component, responder in self.responders.items():
            if not responder.bursting:
                continue
            by_client: dict[tuple, list[FtpPayload]] = {}
            for client, packet in responder.burst(BURST_PACKETS_PER_PASS):
                by_client.setdefault(client, []).append(packet)
            for client, packets in by_client.items():
                self._send(component, client, packets)

    def _send(self, component: int, client: tuple, replies: list[FtpPayload]) -> None:
        _, sysid, compid = client
        messages = [mavlink.MAVLink_file_transfer_protocol_message(0, sysid, compid, list(r.encode())) for r in replies]
        self.link.send_batch(messages, [self._clients[client]], compid=component)
