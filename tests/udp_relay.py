"""A lossy UDP relay for tests: forwards datagrams between one client and the vehicle, dropping a fraction.

The client sends to `relay.port`; the relay forwards from its own socket to the vehicle, and the vehicle's
datagrams back to the last client address it heard from. Drops are drawn from a seeded RNG, independently
in each direction, so a run is repeatable up to thread timing.
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


class LossyUdpRelay:
    def __init__(self, vehicle_port: int, drop_fraction: float, seed: int = 0) -> None:
        if not 0.0 <= drop_fraction < 1.0:
            raise ValueError(f"drop_fraction must be in [0, 1), got {drop_fraction}")
        self.vehicle_address = ("127.0.0.1", vehicle_port)
        self.drop_fraction = drop_fraction
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
