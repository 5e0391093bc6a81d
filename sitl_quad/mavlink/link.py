"""UDP transport: live peers, per-peer parsing, routing between peers, drop counters.

Every address that sends the vehicle a datagram becomes a live peer and receives the telemetry, like PX4's
UDP "remote" behaviour; `--out` targets are peers from the start. Messages from one peer that are not
addressed to this vehicle alone are forwarded to the other peers, the way an autopilot's MAVLink router
lets the GCS see what the onboard computer publishes.
"""

from __future__ import annotations

import logging
import select
import socket
import struct
import sys
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import NamedTuple

from uavcore.mavlink import VEHICLE_UDP_PORT, Encoder, mavlink, new_parser, parse_datagram

log = logging.getLogger(__name__)

PEER_TIMEOUT_S = 10.0  # a peer silent this long (wall clock) stops receiving telemetry
MAX_DATAGRAM = 65535
MAX_BATCH_BYTES = 1200  # stays under a 1500-byte Ethernet MTU when a peer is on another host
TIMESPEC = struct.Struct("@qq")  # SCM_TIMESTAMPNS: struct timespec, seconds and nanoseconds (CLOCK_REALTIME)
ANCILLARY_SPACE = socket.CMSG_SPACE(TIMESPEC.size)
# Linux's SO_TIMESTAMPNS (asm-generic/socket.h, x86 and ARM), which Python's socket module does not name;
# elsewhere a message's arrival is when it is read
SO_TIMESTAMPNS = 35 if sys.platform == "linux" else None
SCM_TIMESTAMPNS = SO_TIMESTAMPNS


@dataclass
class Peer:
    address: tuple[str, int]
    parser: mavlink.MAVLink
    last_seen: float = 0.0
    sysid: int | None = None
    compid: int | None = None
    permanent: bool = False  # an --out target: never expires
    onboard: bool = False  # an onboard controller: gets the state messages at the outer-loop rate


@dataclass
class LinkStats:
    datagrams: int = 0
    messages: int = 0
    malformed: int = 0  # bad CRC, bad prefix, truncated, unparsable
    unsigned_rejected: int = 0
    wrong_target: int = 0  # addressed to another system and nowhere to route it
    unknown: int = 0  # valid frame, message id outside the dialect
    forwarded: int = 0
    sent: int = 0
    send_errors: int = 0
    silenced: int = 0  # datagrams not sent, or messages ignored, while the MAVLink signal is failed (injected)
    by_type: dict[str, int] = field(default_factory=dict)

    @property
    def dropped(self) -> int:
        return self.malformed + self.unsigned_rejected + self.unknown


class Received(NamedTuple):
    """A message for this vehicle, the peer it came from, and when the kernel received its datagram
    (time.monotonic()): a process the machine did not schedule for a while reads it later than that."""

    peer: Peer
    msg: object
    at: float


def _arrival_time(ancillary: list[tuple[int, int, bytes]]) -> float:
    """The datagram's kernel receive time (SO_TIMESTAMPNS) on the monotonic clock; now when it has none."""
    now = time.monotonic()
    for level, kind, data in ancillary:
        if level == socket.SOL_SOCKET and kind == SCM_TIMESTAMPNS and len(data) >= TIMESPEC.size:
            seconds, nanoseconds = TIMESPEC.unpack_from(data)
            return min(now, now - (time.time() - (seconds + nanoseconds * 1e-9)))
    return now


def _target_of(msg) -> tuple[int, int] | None:
    """(target_system, target_component) of a message, or None for a broadcast-type message."""
    target_system = getattr(msg, "target_system", None)
    if target_system is None:
        return None
    return target_system, getattr(msg, "target_component", 0)


class UdpLink:
    """One UDP socket bound to host:port, talking MAVLink 2 to any number of peers."""

    def __init__(
        self,
        host: str = "127.0.0.1",
        port: int = VEHICLE_UDP_PORT,
        out_targets: list[tuple[str, int]] | None = None,
        sysid: int = 1,
        compid: int = 1,
        signing_key: bytes | None = None,
    ) -> None:
        self.sysid, self.compid = sysid, compid
        self.sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self.sock.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 1 << 20)
        if SO_TIMESTAMPNS is not None:
            self.sock.setsockopt(socket.SOL_SOCKET, SO_TIMESTAMPNS, 1)  # see Received.at
        self.sock.bind((host, port))
        self.sock.setblocking(False)
        self.address = self.sock.getsockname()
        self.signing_key = signing_key
        self.encoder = Encoder(sysid, compid, signing_key)
        # Other components of this vehicle that the link answers for (a camera's FTP server, 100): messages to
        # them are handled here, not forwarded, and what they send goes out under their own component id.
        self.encoders: dict[int, Encoder] = {compid: self.encoder}
        self.peers: dict[tuple[str, int], Peer] = {}
        for target in out_targets or []:
            peer = self._new_peer(target)
            peer.permanent = True
        self.stats = LinkStats()
        # An injected MAVLink signal failure (sitl_quad.mavlink.failure_injection): None while the link works;
        # else the only messages still heard (a predicate), and nothing goes out
        self.signal_failed: Callable[[object], bool] | None = None

    def close(self) -> None:
        self.sock.close()

    def add_component(self, compid: int) -> None:
        """Answer for another component of this vehicle: messages addressed to it are this link's to handle, and
        what is sent with `compid=` goes out under its id (signed with the link's key, its own timestamps)."""
        if compid not in self.encoders:
            self.encoders[compid] = Encoder(self.sysid, compid, self.signing_key)

    # ----- sending
    def pack(self, msg, compid: int | None = None) -> bytes:
        return self.encoders[self.compid if compid is None else compid].pack(msg)

    def send(self, msg, peer: Peer | None = None, compid: int | None = None) -> None:
        """Send to one peer, or to every live peer (from the autopilot, or from another component of ours)."""
        self.send_to(msg, [peer] if peer is not None else self.live_peers(), compid)

    def send_to(self, msg, peers: list[Peer], compid: int | None = None) -> None:
        if not peers:
            return
        buf = self.pack(msg, compid)
        for p in peers:
            self._sendto(buf, p.address)

    def send_batch(self, msgs: list, peers: list[Peer], compid: int | None = None) -> None:
        """Several messages in as few datagrams as fit under MAX_BATCH_BYTES (every MAVLink parser reads
        all the frames of a datagram): a loopback datagram costs a context switch, a frame almost nothing."""
        if not peers or not msgs:
            return
        datagrams, current = [], b""
        for msg in msgs:
            frame = self.pack(msg, compid)
            if current and len(current) + len(frame) > MAX_BATCH_BYTES:
                datagrams.append(current)
                current = b""
            current += frame
        datagrams.append(current)
        for buf in datagrams:
            for p in peers:
                self._sendto(buf, p.address)

    def _sendto(self, buf: bytes, address: tuple[str, int]) -> None:
        if self.signal_failed is not None:
            self.stats.silenced += 1
            return
        try:
            self.sock.sendto(buf, address)
            self.stats.sent += 1
        except OSError as exc:  # a vanished peer or a full buffer must not stop the vehicle
            self.stats.send_errors += 1
            log.debug("send to %s failed: %s", address, exc)

    def live_peers(self) -> list[Peer]:
        now = time.monotonic()
        expired = [a for a, p in self.peers.items() if not p.permanent and now - p.last_seen > PEER_TIMEOUT_S]
        for address in expired:
            log.info("peer %s silent for %.0f s: dropped", address, PEER_TIMEOUT_S)
            del self.peers[address]
        return list(self.peers.values())

    # ----- receiving
    def wait(self, timeout: float) -> bool:
        """Block up to timeout seconds for a datagram; True if one is ready."""
        ready, _, _ = select.select([self.sock], [], [], max(0.0, timeout))
        return bool(ready)

    def receive(self) -> list[Received]:
        """Drain the socket: parsed messages addressed to (or broadcast for) this vehicle, with their peer."""
        out: list[Received] = []
        while True:
            try:
                data, ancillary, _, address = self.sock.recvmsg(MAX_DATAGRAM, ANCILLARY_SPACE)
            except (BlockingIOError, InterruptedError):
                return out
            except OSError as exc:  # e.g. ICMP port unreachable reported on the socket
                log.debug("recvfrom: %s", exc)
                continue
            self.stats.datagrams += 1
            if self.signal_failed is not None:
                out.extend(self._heard_while_failed(address, data, at=_arrival_time(ancillary)))
                continue
            peer = self.peers.get(address) or self._new_peer(address)
            peer.last_seen = time.monotonic()
            at = _arrival_time(ancillary)
            for msg in self._parse(peer, data):
                if self._accept(peer, msg):
                    out.append(Received(peer, msg, at))

    def _heard_while_failed(self, address: tuple[str, int], data: bytes, at: float) -> list[Received]:
        """The messages a failed signal still lets through (the command that restores it); the rest is counted as
        silenced, and the peer is not refreshed: to the vehicle it has gone quiet."""
        assert self.signal_failed is not None
        peer = self.peers.get(address) or Peer(
            address=address, parser=new_parser(self.sysid, self.compid, self.signing_key)
        )
        heard = []
        for msg in self._parse(peer, data):
            if self.signal_failed(msg):
                heard.append(Received(peer, msg, at))
            else:
                self.stats.silenced += 1
        return heard

    def _new_peer(self, address: tuple[str, int]) -> Peer:
        parser = new_parser(self.sysid, self.compid, self.signing_key)
        peer = Peer(address=address, parser=parser, last_seen=time.monotonic())
        self.peers[address] = peer
        log.info("new peer %s:%d", *address)
        return peer

    def _parse(self, peer: Peer, data: bytes) -> list:
        try:
            messages = parse_datagram(peer.parser, data)
        except Exception as exc:  # pymavlink raises a zoo of errors on hostile input; none may escape
            self.stats.malformed += 1
            log.debug("unparsable datagram from %s: %s", peer.address, exc)
            return []
        good = []
        for msg in messages:
            if isinstance(msg, mavlink.MAVLink_bad_data):
                if "signature" in str(getattr(msg, "reason", "")).lower():
                    self.stats.unsigned_rejected += 1
                else:
                    self.stats.malformed += 1
            elif isinstance(msg, mavlink.MAVLink_unknown):
                self.stats.unknown += 1
            else:
                good.append(msg)
        return good

    def _accept(self, peer: Peer, msg) -> bool:
        """Route the message onwards and say whether this vehicle should handle it."""
        self.stats.messages += 1
        kind = msg.get_type()
        self.stats.by_type[kind] = self.stats.by_type.get(kind, 0) + 1
        if kind == "HEARTBEAT" or peer.sysid is None:
            peer.sysid, peer.compid = msg.get_srcSystem(), msg.get_srcComponent()
        if kind == "SET_ATTITUDE_TARGET" or peer.compid == mavlink.MAV_COMP_ID_ONBOARD_COMPUTER:
            peer.onboard = True
        target = _target_of(msg)
        for_us = target is None or (target[0] in (0, self.sysid) and (target[1] == 0 or target[1] in self.encoders))
        for_others = target is None or target[0] != self.sysid or (target[1] != 0 and target[1] not in self.encoders)
        if for_others:
            self._forward(peer, msg)
        if not for_us:
            self.stats.wrong_target += 1
        return for_us

    def _forward(self, source: Peer, msg) -> None:
        buf = bytes(msg.get_msgbuf())
        for p in self.live_peers():
            if p is not source:
                self._sendto(buf, p.address)
                self.stats.forwarded += 1
