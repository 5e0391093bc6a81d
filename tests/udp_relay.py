"""A lossy UDP relay for tests: forwards datagrams between one client and the vehicle, dropping a fraction.

The client sends to `relay.port`; the relay forwards from its own socket to the vehicle, and the vehicle's
datagrams back to the last client address it heard from. Drops are drawn from a seeded RNG, independently
in each direction, so a run is repeatable up to thread timing. `drop_to_client` names MAVLink message ids the
relay never passes to the client (every datagram from the vehicle carrying one is dropped): the loss of one kind
of message on purpose, as a radio might lose every one of a few.
"""

from __future__ import annotations

import random
import select
import socket
import threading
from dataclasses import dataclass


@dataclass
class RelayCounts:
    forwarded: int = 0
    dropped: int = 0


MAVLINK2_MAGIC, MAVLINK1_MAGIC = 0xFD, 0xFE


def frames(datagram: bytes) -> list[tuple[int | None, bytes]]:
    """The MAVLink frames of a datagram (a vehicle may send several in one), each with its message id; what is
    not a frame comes as one piece with id None."""
    out, at = [], 0
    while at < len(datagram):
        rest = datagram[at:]
        if len(rest) >= 10 and rest[0] == MAVLINK2_MAGIC:
            size = 12 + rest[1] + (13 if rest[2] & 1 else 0)  # header 10, checksum 2, signature 13 when signed
            out.append((int.from_bytes(rest[7:10], "little"), rest[:size]))
        elif len(rest) >= 6 and rest[0] == MAVLINK1_MAGIC:
            size = 8 + rest[1]
            out.append((rest[5], rest[:size]))
        else:
            size = len(rest)
            out.append((None, rest))
        at += size
    return out


class LossyUdpRelay:
    def __init__(
        self, vehicle_port: int, drop_fraction: float, seed: int = 0, drop_to_client: frozenset[int] = frozenset()
    ) -> None:
        if not 0.0 <= drop_fraction < 1.0:
            raise ValueError(f"drop_fraction must be in [0, 1), got {drop_fraction}")
        self.vehicle_address = ("127.0.0.1", vehicle_port)
        self.drop_fraction = drop_fraction
        self.drop_to_client = drop_to_client
        self.dropped_on_purpose = 0
        self.rng = random.Random(seed)
        self.client_side = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self.client_side.bind(("127.0.0.1", 0))
        self.vehicle_side = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self.vehicle_side.bind(("127.0.0.1", 0))
        self.port = self.client_side.getsockname()[1]
        self.client_address: tuple[str, int] | None = None
        self.to_vehicle = RelayCounts()
        self.to_client = RelayCounts()
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, name="lossy-udp-relay", daemon=True)

    def __enter__(self) -> LossyUdpRelay:
        self._thread.start()
        return self

    def __exit__(self, *exc) -> None:
        self._stop.set()
        self._thread.join(timeout=5)
        self.client_side.close()
        self.vehicle_side.close()

    def _run(self) -> None:
        sockets = [self.client_side, self.vehicle_side]
        while not self._stop.is_set():
            ready, _, _ = select.select(sockets, [], [], 0.05)
            for sock in ready:
                try:
                    data, address = sock.recvfrom(65535)
                except OSError:  # e.g. ICMP port unreachable from a client that went away
                    continue
                if sock is self.client_side:
                    self.client_address = address
                    self._pass(data, self.vehicle_side, self.vehicle_address, self.to_vehicle)
                elif self.client_address is not None:
                    kept = [frame for kind, frame in frames(data) if kind not in self.drop_to_client]
                    self.dropped_on_purpose += len(frames(data)) - len(kept)
                    if not kept:
                        continue
                    data = b"".join(kept)
                    self._pass(data, self.client_side, self.client_address, self.to_client)

    def _pass(self, data: bytes, out: socket.socket, address: tuple[str, int], counts: RelayCounts) -> None:
        if self.rng.random() < self.drop_fraction:
            counts.dropped += 1
            return
        try:
            out.sendto(data, address)
            counts.forwarded += 1
        except OSError:
            counts.dropped += 1
