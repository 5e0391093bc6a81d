"""`sitl-quad --ais-out HOST:PORT`: the world's AIS reports (sitl_quad.ais_station) sent as an AIS receiver ashore
would pass them on, NMEA 0183 `!AIVDM` sentences in UDP datagrams, one report per datagram, channels A and B in
turn (AtoN stations alternate them). Sending never blocks the vehicle's loop: a datagram the socket cannot take now
is dropped and counted."""

from __future__ import annotations

import logging
import socket

from sitl_quad.ais_station import AisStation
from uavcore.ais import encode_aton_report

log = logging.getLogger(__name__)


class AisOut:
    def __init__(self, address: tuple[str, int], station: AisStation) -> None:
        self.address = address
        self.station = station
        self.sent = 0
        self.send_errors = 0
        self._channel = 0
        family = socket.getaddrinfo(*address, type=socket.SOCK_DGRAM)[0][0]
        self._sock = socket.socket(family, socket.SOCK_DGRAM)
        self._sock.setblocking(False)

    def poll(self, t_s: float, unix_s: float, *environment: float) -> None:
        """Send the reports due at simulated time t_s (cheap when none is: every tick calls it)."""
        for report in self.station.due(t_s, unix_s, *environment):
            channel = "AB"[self._channel]
            self._channel ^= 1
            datagram = "".join(line + "\r\n" for line in encode_aton_report(report, channel)).encode()
            try:
                self._sock.sendto(datagram, self.address)
                self.sent += 1
            except OSError as error:  # nobody listening (ICMP refused), a full buffer: the next report goes on
                self.send_errors += 1
                log.debug("AIS datagram to %s:%d not sent: %s", *self.address, error)

    def stats(self) -> dict[str, int]:
        return {"transmitters": self.station.transmitters, "sent": self.sent, "send_errors": self.send_errors}

    def close(self) -> None:
        self._sock.close()
