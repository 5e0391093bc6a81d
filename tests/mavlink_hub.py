"""A MAVLink UDP hub for tests: every datagram one endpoint sends goes to every other endpoint, as mavlink-router
(or PX4's forwarding) joins an autopilot, its camera and a ground station into one network.

Endpoints are of two kinds:
- `listen()`: a port the hub binds; a peer (MAVSDK's `udpout://127.0.0.1:PORT`) sends to it and the hub sends that
  endpoint's share back to the address it last heard the peer from (nothing until the peer is heard);
- `connect(port)`: the hub sends to 127.0.0.1:port, a peer listening there (a ground station's `udpin`), from a
  socket of its own: the peer answers to that socket.

The hub does not parse the traffic to route it. It notes the MAVLink frames named in `watch` (message ids), each
decoded, with the endpoint it came from: the test asks afterwards who commanded the camera and what it answered.
"""

from __future__ import annotations

import contextlib
import select
import socket
import threading
import time
from dataclasses import dataclass
from typing import Any

from udp_relay import frames

from uavcore.mavlink import mavlink


@dataclass
class _Endpoint:
    name: str
    sock: socket.socket
    peer: tuple[str, int] | None  # None until heard (a listen() endpoint)


@dataclass(frozen=True)
class Heard:
    """A watched message that passed the hub: when (time.monotonic()), from which endpoint, decoded."""

    t: float
    endpoint: str
    message: Any


class MavlinkHub:
    def __init__(self, watch: frozenset[int] = frozenset()) -> None:
        self.watch = watch
        self.heard: list[Heard] = []
        self._endpoints: list[_Endpoint] = []
        self._parser = mavlink.MAVLink(None)
        self._parser.robust_parsing = True
        self._lock = threading.Lock()
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, name="mavlink-hub", daemon=True)

    def listen(self, name: str) -> int:
        """A port for a peer that sends first (udpout); returns it."""
        return self._add(name, None).getsockname()[1]

    def connect(self, name: str, port: int) -> None:
        """Send this endpoint's share to a peer listening on 127.0.0.1:port (udpin)."""
        self._add(name, ("127.0.0.1", port))

    def _add(self, name: str, peer: tuple[str, int] | None) -> socket.socket:
        assert not self._thread.is_alive(), "endpoints are added before the hub starts"
        sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        sock.bind(("127.0.0.1", 0))
        self._endpoints.append(_Endpoint(name, sock, peer))
        return sock

    def messages(self, name: str, endpoint: str | None = None) -> list[Heard]:
        """The watched messages of this type seen so far (from `endpoint` only, if given)."""
        with self._lock:
            return [h for h in self.heard if h.message.get_type() == name and endpoint in (None, h.endpoint)]

    def __enter__(self) -> MavlinkHub:
        self._thread.start()
        return self

    def __exit__(self, *exc: object) -> None:
        self._stop.set()
        self._thread.join(timeout=5)
        for endpoint in self._endpoints:
            endpoint.sock.close()

    def _run(self) -> None:
        by_socket = {e.sock: e for e in self._endpoints}
        while not self._stop.is_set():
            ready, _, _ = select.select(list(by_socket), [], [], 0.05)
            for sock in ready:
                source = by_socket[sock]
                try:
                    data, address = sock.recvfrom(65535)
                except OSError:  # ICMP port unreachable: a peer that is not (or no longer) listening
                    continue
                source.peer = address
                if self.watch:
                    self._note(source.name, data)
                for endpoint in self._endpoints:
                    if endpoint is not source and endpoint.peer is not None:
                        with contextlib.suppress(OSError):  # a peer gone: the others still get theirs
                            endpoint.sock.sendto(data, endpoint.peer)

    def _note(self, name: str, data: bytes) -> None:
        for kind, frame in frames(data):
            if kind not in self.watch:
                continue
            try:
                message = self._parser.decode(bytearray(frame))
            except Exception:  # a frame pymavlink cannot decode is only not noted; it was passed on as it came
                continue
            with self._lock:
                self.heard.append(Heard(time.monotonic(), name, message))
