"""The AIS feed's transports: a UDP listener (AIS receivers send or broadcast their sentences as datagrams, to port
10110 by custom) and a TCP client (shore stations and receivers serve NMEA over TCP) that reconnects with back-off.
Each hands what it reads to its source's decoder (uavcore.ais_stream: assembly, counts, the rate bound) and every AtoN
report to a callback; none of them raises into the event loop.

The rate bound, on the loop that also runs the vehicle links: lines beyond the source's token bucket are dropped
before parsing. UDP: while the bucket is empty the socket is not read at all (the kernel drops the excess, counted by
SO_RXQ_OVFL on Linux); TCP: chunks read while it is empty are dropped whole, their lines counted, never split.
"""

from __future__ import annotations

import asyncio
import contextlib
import errno
import logging
import random
import socket
import struct
import sys
import time
from collections.abc import Callable

from gcs.domain.ais import AisSource
from uavcore.ais import AtonReport
from uavcore.ais_stream import AisStreamDecoder, StreamLimits

log = logging.getLogger(__name__)

RECONNECT_FIRST_S = 1.0  # the first retry after a failed or lost connection (or bind); doubled up to the max
RECONNECT_MAX_S = 30.0
CONNECT_TIMEOUT_S = 10.0
READ_CHUNK_BYTES = 64 << 10
MAX_DATAGRAM_BYTES = 65535
DATAGRAMS_PER_WAKE = 64  # at most this many read per wake-up: other work on the loop gets its turn
# Linux's SO_RXQ_OVFL (asm-generic/socket.h), which Python's socket module does not name: each datagram then
# carries the count of datagrams the kernel dropped on this socket so far (a full receive buffer)
SO_RXQ_OVFL = 40 if sys.platform == "linux" else None
OVERFLOW_COUNT = struct.Struct("@I")

ReportCallback = Callable[[AtonReport], None]


class AisReceiver:
    """One --ais source: its decoder, its state (connected, last line, error) and its task."""

    def __init__(self, source: AisSource, limits: StreamLimits, on_report: ReportCallback) -> None:
        self.source = source
        self.decoder = AisStreamDecoder(limits, time.monotonic())
        self.on_report = on_report
        self.connected = False
        self.error: str | None = None
        self.connections = 0
        self.last_line_at: float | None = None  # wall clock (shown)
        self.last_line_mono: float | None = None  # monotonic (ages)
        self.kernel_dropped = 0
        self._task: asyncio.Task[None] | None = None

    async def start(self) -> None:
        self._task = asyncio.create_task(self._run(), name=f"ais {self.source}")

    async def stop(self) -> None:
        if self._task is not None:
            self._task.cancel()
            with contextlib.suppress(asyncio.CancelledError):
                await self._task
            self._task = None
        self.connected = False

    async def _run(self) -> None:
        """Connect (or bind), receive until it fails, wait, again; until cancelled."""
        delay = RECONNECT_FIRST_S
        while True:
            try:
                await self._receive()
                delay = RECONNECT_FIRST_S  # it worked for a while: the next failure retries soon
            except asyncio.CancelledError:
                raise
            except Exception as error:  # a socket error, or a bug: logged, never the end of the feed
                self.error = str(error) or type(error).__name__
                log.warning("AIS %s: %s; retrying in %.0f s", self.source, self.error, delay)
            self.connected = False
            # jitter: receivers restarted together do not all knock on a shore station at the same instant
            await asyncio.sleep(delay * random.uniform(0.8, 1.2))
            delay = min(2 * delay, RECONNECT_MAX_S)

    async def _receive(self) -> None:
        raise NotImplementedError

    def _heard(self, reports: list[AtonReport]) -> None:
        self.last_line_at, self.last_line_mono = time.time(), time.monotonic()
        for report in reports:
            self.on_report(report)


class UdpReceiver(AisReceiver):
    """Listens on the source's address; each peer's multi-part messages are assembled apart (origin host:port)."""

    async def _receive(self) -> None:
        loop = asyncio.get_running_loop()
        family, kind, proto, _, address = (
            await loop.getaddrinfo(self.source.host, self.source.port, type=socket.SOCK_DGRAM, flags=socket.AI_PASSIVE)
        )[0]
        sock = socket.socket(family, kind, proto)
        stopped = loop.create_future()
        try:
            sock.setblocking(False)
            sock.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
            if SO_RXQ_OVFL is not None:
                sock.setsockopt(socket.SOL_SOCKET, SO_RXQ_OVFL, 1)
            sock.bind(address)
            self.connected, self.error = True, None
            self.connections += 1
            loop.add_reader(sock.fileno(), self._readable, sock, loop, stopped)
            await stopped  # only a socket error ends it (its exception); cancelling stop() ends it too
        finally:
            loop.remove_reader(sock.fileno())
            sock.close()

    def _readable(self, sock: socket.socket, loop: asyncio.AbstractEventLoop, stopped: asyncio.Future[None]) -> None:
        now = time.monotonic()
        ancillary_size = socket.CMSG_SPACE(OVERFLOW_COUNT.size) if SO_RXQ_OVFL is not None else 0
        reports: list[AtonReport] = []
        read = 0
        for _ in range(DATAGRAMS_PER_WAKE):
            try:
                data, ancillary, _, peer = sock.recvmsg(MAX_DATAGRAM_BYTES, ancillary_size)
            except (BlockingIOError, InterruptedError):
                break
            except OSError as error:
                # a peer's ICMP "port unreachable" comes back as ECONNREFUSED on the socket: nothing wrong here
                if not stopped.done() and error.errno != errno.ECONNREFUSED:
                    stopped.set_exception(error)  # anything else: reopen the socket (AisReceiver._run)
                break
            read += 1
            self._count_overflow(ancillary)
            origin = f"{peer[0]}:{peer[1]}" if isinstance(peer, tuple) else str(peer)
            reports += self.decoder.feed_datagram(data, now, origin)
            if self.decoder.throttled(now):
                self._pause(sock, loop, stopped)
                break
        if read:
            self._heard(reports)

    def _count_overflow(self, ancillary: list[tuple[int, int, bytes]]) -> None:
        for level, kind, data in ancillary:
            if level == socket.SOL_SOCKET and kind == SO_RXQ_OVFL and len(data) >= OVERFLOW_COUNT.size:
                self.kernel_dropped = OVERFLOW_COUNT.unpack_from(data)[0]  # the socket's running total

    def _pause(self, sock: socket.socket, loop: asyncio.AbstractEventLoop, stopped: asyncio.Future[None]) -> None:
        """Stop reading until the bucket has a token again: a flood then costs the kernel, not this loop."""
        loop.remove_reader(sock.fileno())

        def resume() -> None:
            if not stopped.done() and sock.fileno() >= 0:
                loop.add_reader(sock.fileno(), self._readable, sock, loop, stopped)

        loop.call_later(self.decoder.retry_after_s(time.monotonic()), resume)


class TcpReceiver(AisReceiver):
    """Connects to the source's server and reads its byte stream; reconnects with back-off when it fails, closes
    or stays silent longer than idle_timeout_s (a half-open connection looks like a silent feed)."""

    def __init__(
        self, source: AisSource, limits: StreamLimits, on_report: ReportCallback, idle_timeout_s: float = 600.0
    ) -> None:
        super().__init__(source, limits, on_report)
        self.idle_timeout_s = idle_timeout_s

    async def _receive(self) -> None:
        async with asyncio.timeout(CONNECT_TIMEOUT_S):
            reader, writer = await asyncio.open_connection(self.source.host, self.source.port)
        try:
            sock = writer.get_extra_info("socket")
            if sock is not None:  # a vanished server (a host down, a cable cut) is found out by the kernel
                sock.setsockopt(socket.SOL_SOCKET, socket.SO_KEEPALIVE, 1)
            self.connected, self.error = True, None
            self.connections += 1
            log.info("AIS %s: connected", self.source)
            while True:
                try:
                    async with asyncio.timeout(self.idle_timeout_s):
                        chunk = await reader.read(READ_CHUNK_BYTES)
                except TimeoutError:
                    raise ConnectionError(f"silent for {self.idle_timeout_s:g} s: reconnecting") from None
                if not chunk:
                    raise ConnectionError("the server closed the connection")
                self._heard(self.decoder.feed_stream(chunk, time.monotonic()))
        finally:
            self.connected = False
            writer.close()
            with contextlib.suppress(Exception):
                await writer.wait_closed()
