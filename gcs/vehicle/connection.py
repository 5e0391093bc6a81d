"""Byte transports to a vehicle, from connection strings as MAVSDK and pymavlink users write them.

| string                            | what it does                                                               |
| --------------------------------- | -------------------------------------------------------------------------- |
| `udpin://[HOST]:PORT`             | listen (PX4 SITL, radios and companions send to the ground port, 14550);   |
|                                   | replies go to the vehicle's address once it has been heard                 |
| `udpout://HOST:PORT`              | send to a listening vehicle (our sitl_quad, PX4 SITL's 14580)              |
| `tcp://HOST:PORT`                 | connect to a TCP server (ArduPilot SITL's 5760, mavlink-router); reconnects |
| `serial:///dev/ttyUSB0[:BAUD]`    | a serial port or telemetry radio, raw 8N1, default 57600 baud              |

pymavlink's `udpin:HOST:PORT` / `udpout:HOST:PORT` / `tcp:HOST:PORT` (no `//`) and MAVSDK's `udp://[HOST]:PORT`
(= udpin) are accepted too. A transport only moves bytes; `datagrams` tells the link whether each chunk holds
whole MAVLink frames (UDP) or is a slice of a byte stream (TCP, serial).
"""

from __future__ import annotations

import asyncio
import contextlib
import os
import select
import socket
import termios
from collections.abc import Callable
from dataclasses import dataclass
from typing import Literal

UDP_CLOSE_WAIT_S = 1.0
RECEIVE_BUFFER_BYTES = 4 << 20  # a vehicle in lockstep sends bursts faster than real time
TCP_RETRY_S = 1.0
DEFAULT_BAUD = 57600
EXAMPLES = "udpin://0.0.0.0:14550, udpout://127.0.0.1:14540, tcp://127.0.0.1:5760, serial:///dev/ttyUSB0:57600"

Kind = Literal["udpin", "udpout", "tcp", "serial"]
DataCallback = Callable[[bytes, object], None]  # (data, source address or None)


class ConnectionStringError(ValueError):
    """A connection string this service cannot use (the message says why and shows the forms it takes)."""


@dataclass(frozen=True)
class Connection:
    """A parsed connection string."""

    kind: Kind
    host: str = ""
    port: int = 0
    device: str = ""
    baud: int = DEFAULT_BAUD

    def __str__(self) -> str:
        if self.kind == "serial":
            return f"serial://{self.device}:{self.baud}"
        return f"{self.kind}://{self.host}:{self.port}"


_SCHEMES: dict[str, Kind] = {"udpin": "udpin", "udp": "udpin", "udpout": "udpout", "tcp": "tcp", "serial": "serial"}


def parse_connection(url: str) -> Connection:
    """Parse a connection string; raise ConnectionStringError naming what is wrong."""

    def fail(why: str) -> ConnectionStringError:
        return ConnectionStringError(f"vehicle connection {url!r}: {why}; expected one of {EXAMPLES}")

    scheme, sep, rest = url.strip().partition(":")
    if not sep or scheme.lower() not in _SCHEMES:
        raise fail(f"unknown scheme {scheme!r}" if sep else "no scheme")
    kind = _SCHEMES[scheme.lower()]
    rest = rest.removeprefix("//")
    if kind == "serial":
        device, _, baud = rest.rpartition(":") if rest.rpartition(":")[2].isdigit() else (rest, "", "")
        if not device.startswith("/") and not device.upper().startswith("COM"):
            raise fail("a serial connection names a device path, e.g. /dev/ttyUSB0")
        if baud and not 50 <= int(baud) <= 4_000_000:
            raise fail(f"baud rate {baud} is out of range")
        return Connection("serial", device=device, baud=int(baud) if baud else DEFAULT_BAUD)
    host, colon, port = rest.rpartition(":")
    if not colon or not port.isdigit() or not 0 < int(port) < 65536:
        raise fail("the port must be a number from 1 to 65535")
    host = host.strip("[]")
    if kind == "udpin":
        host = host or "0.0.0.0"
    elif not host:
        raise fail(f"{kind} needs a host to connect to")
    return Connection(kind, host=host, port=int(port))


def parse_vehicle(text: str) -> tuple[int | None, str]:
    """A fleet's vehicle as `[SYSID=]URL`: (its MAVLink system id or None for the first autopilot heard, the
    connection string), e.g. `2=udpin://:14550` (system 2 among those a router delivers to port 14550). Raises
    ConnectionStringError naming what is wrong."""
    head, sep, rest = text.partition("=")
    if sep and head.strip().isdigit():
        sysid, url = int(head), rest
        if not 1 <= sysid <= 255:
            raise ConnectionStringError(f"vehicle {text!r}: a system id is 1 to 255, got {sysid}")
    else:
        sysid, url = None, text
    parse_connection(url)
    return sysid, url.strip()


class Transport:
    """Moves bytes to and from one vehicle link. `open(on_data)`, `send(data)`, `close()`."""

    datagrams = True

    def __init__(self, connection: Connection) -> None:
        self.connection = connection
        self._on_data: DataCallback | None = None

    async def open(self, on_data: DataCallback) -> None:
        self._on_data = on_data

    def send(self, data: bytes) -> None:
        raise NotImplementedError

    async def close(self) -> None:
        pass

    def backlogged(self) -> bool:
        """Whether data has arrived that has not been read yet (a stream transport reads what is there at once)."""
        return False

    def _received(self, data: bytes, source: object = None) -> None:
        if self._on_data is not None:
            self._on_data(data, source)


class _DatagramProtocol(asyncio.DatagramProtocol):
    def __init__(self, transport: UdpTransport) -> None:
        self.owner = transport
        self.closed = asyncio.get_running_loop().create_future()

    def connection_lost(self, exc: Exception | None) -> None:
        if not self.closed.done():
            self.closed.set_result(None)

    def datagram_received(self, data: bytes, addr: tuple[str, int]) -> None:
        self.owner._from(data, addr)

    def error_received(self, exc: Exception) -> None:
        # ICMP port unreachable while no vehicle listens: expected; the heartbeat watchdog reports the silence
        pass


class UdpTransport(Transport):
    """udpout: a socket connected to the vehicle's address. udpin: a bound socket that answers whoever the link
    says is the vehicle (`reply_to`), by default the first sender heard."""

    def __init__(self, connection: Connection) -> None:
        super().__init__(connection)
        self._socket: asyncio.DatagramTransport | None = None
        self._protocol: _DatagramProtocol | None = None
        self.peer: tuple[str, int] | None = None

    async def open(self, on_data: DataCallback) -> None:
        await super().open(on_data)
        loop = asyncio.get_running_loop()
        address = (self.connection.host, self.connection.port)
        if self.connection.kind == "udpout":
            self._socket, self._protocol = await loop.create_datagram_endpoint(
                lambda: _DatagramProtocol(self), remote_addr=address
            )
        else:
            self._socket, self._protocol = await loop.create_datagram_endpoint(
                lambda: _DatagramProtocol(self), local_addr=address, reuse_port=False
            )
        sock = self._socket.get_extra_info("socket")
        sock.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, RECEIVE_BUFFER_BYTES)

    @property
    def local_port(self) -> int:
        return self._socket.get_extra_info("sockname")[1] if self._socket is not None else 0

    def backlogged(self) -> bool:
        """Datagrams wait in the socket: asyncio reads one per turn of its loop, so on a busy service a heartbeat can
        wait there behind a burst of telemetry and file data for longer than the link's timeout."""
        sock = self._socket.get_extra_info("socket") if self._socket is not None else None
        if sock is None:
            return False
        readable, _, _ = select.select([sock], [], [], 0.0)
        return bool(readable)

    def reply_to(self, address: object) -> None:
        if self.connection.kind == "udpin" and isinstance(address, tuple):
            self.peer = address

    def _from(self, data: bytes, addr: tuple[str, int]) -> None:
        if self.connection.kind == "udpin" and self.peer is None:
            self.peer = addr
        self._received(data, addr)

    def send(self, data: bytes) -> None:
        self.send_to(data, self.peer)

    def send_to(self, data: bytes, peer: tuple[str, int] | None) -> None:
        """udpout: to the vehicle; udpin: to `peer` (nobody until a vehicle has been heard)."""
        if self._socket is None:
            return
        if self.connection.kind == "udpout":
            self._socket.sendto(data)
        elif peer is not None:
            self._socket.sendto(data, peer)

    async def close(self) -> None:
        if self._socket is not None:
            self._socket.close()
            assert self._protocol is not None  # open() sets it with the socket
            # asyncio closes the socket on a later turn of the loop: wait, so its port is free on return
            with contextlib.suppress(TimeoutError):
                async with asyncio.timeout(UDP_CLOSE_WAIT_S):
                    await self._protocol.closed
            self._socket = None


class TcpTransport(Transport):
    """A TCP client that reconnects every TCP_RETRY_S while the server is away."""

    datagrams = False

    def __init__(self, connection: Connection) -> None:
        super().__init__(connection)
        self._writer: asyncio.StreamWriter | None = None
        self._task: asyncio.Task | None = None

    async def open(self, on_data: DataCallback) -> None:
        await super().open(on_data)
        self._task = asyncio.create_task(self._run(), name=f"tcp {self.connection}")

    async def _run(self) -> None:
        while True:
            try:
                reader, self._writer = await asyncio.open_connection(self.connection.host, self.connection.port)
            except OSError:
                await asyncio.sleep(TCP_RETRY_S)
                continue
            try:
                while data := await reader.read(65536):
                    self._received(data)
            except OSError:
                pass
            finally:
                writer, self._writer = self._writer, None
                with contextlib.suppress(Exception):
                    writer.close()
            await asyncio.sleep(TCP_RETRY_S)

    def send(self, data: bytes) -> None:
        if self._writer is not None and not self._writer.is_closing():
            self._writer.write(data)

    async def close(self) -> None:
        if self._task is not None:
            self._task.cancel()
            with contextlib.suppress(asyncio.CancelledError):
                await self._task
            self._task = None
        if self._writer is not None:
            self._writer.close()
            self._writer = None


_BAUDS = {int(name[1:]): getattr(termios, name) for name in dir(termios) if name[:1] == "B" and name[1:].isdigit()}


class SerialTransport(Transport):
    """A serial device (or a pty, in the tests) in raw 8N1 mode, read by the event loop."""

    datagrams = False

    def __init__(self, connection: Connection) -> None:
        super().__init__(connection)
        self._fd: int | None = None
        self._pending = bytearray()

    async def open(self, on_data: DataCallback) -> None:
        await super().open(on_data)
        if self.connection.baud not in _BAUDS:
            raise ConnectionStringError(f"serial baud rate {self.connection.baud} is not one termios supports")
        fd = os.open(self.connection.device, os.O_RDWR | os.O_NOCTTY | os.O_NONBLOCK)
        try:
            attrs = termios.tcgetattr(fd)
            attrs[0] = 0  # iflag: no input processing
            attrs[1] = 0  # oflag: no output processing
            attrs[2] = termios.CS8 | termios.CREAD | termios.CLOCAL  # 8 data bits, no parity, 1 stop bit
            attrs[3] = 0  # lflag: raw, no echo
            attrs[4] = attrs[5] = _BAUDS[self.connection.baud]
            termios.tcsetattr(fd, termios.TCSANOW, attrs)
        except termios.error:
            os.close(fd)
            raise
        self._fd = fd
        asyncio.get_running_loop().add_reader(fd, self._readable)

    def _readable(self) -> None:
        assert self._fd is not None  # registered only while the device is open (close() unregisters first)
        try:
            data = os.read(self._fd, 65536)
        except (BlockingIOError, InterruptedError):
            return
        except OSError:
            data = b""
        if data:
            self._received(data)

    def send(self, data: bytes) -> None:
        if self._fd is None:
            return
        self._pending += data
        self._flush()

    def _flush(self) -> None:
        assert self._fd is not None  # called by send() on an open device, or as its writer until close()
        loop = asyncio.get_running_loop()
        try:
            written = os.write(self._fd, self._pending)
        except (BlockingIOError, InterruptedError):
            written = 0
        del self._pending[:written]
        if self._pending:
            loop.add_writer(self._fd, self._flush)
        else:
            loop.remove_writer(self._fd)

    async def close(self) -> None:
        if self._fd is not None:
            loop = asyncio.get_running_loop()
            loop.remove_reader(self._fd)
            loop.remove_writer(self._fd)
            os.close(self._fd)
            self._fd = None


def open_transport(connection: Connection) -> Transport:
    """The transport for a parsed connection string (not yet opened)."""
    if connection.kind in ("udpin", "udpout"):
        return UdpTransport(connection)
    if connection.kind == "tcp":
        return TcpTransport(connection)
    return SerialTransport(connection)


class TransportHub:
    """Transports shared by connection: the links of a fleet's vehicles that arrive on one connection (a MAVLink
    router's port, or several vehicles streaming to one ground port) read one socket or stream. Each link gets a
    view that receives every chunk; on udpin a view answers its own vehicle's address."""

    def __init__(self) -> None:
        self._shared: dict[Connection, tuple[Transport, list[SharedTransport]]] = {}

    def open_transport(self, connection: Connection) -> Transport:
        return SharedTransport(connection, self)

    async def _attach(self, view: SharedTransport) -> Transport:
        entry = self._shared.get(view.connection)
        if entry is None:
            inner: Transport = open_transport(view.connection)
            entry = self._shared[view.connection] = (inner, [])
            views = entry[1]

            def fan_out(data: bytes, source: object) -> None:
                for v in list(views):  # a copy: a view may attach or detach while a chunk is handed out
                    v._received(data, source)

            try:
                await inner.open(fan_out)
            except BaseException:
                del self._shared[view.connection]
                raise
        entry[1].append(view)
        return entry[0]

    async def _detach(self, view: SharedTransport) -> None:
        entry = self._shared.get(view.connection)
        if entry is None or view not in entry[1]:
            return
        entry[1].remove(view)
        if not entry[1]:
            del self._shared[view.connection]
            await entry[0].close()


class SharedTransport(Transport):
    """One link's view of a transport its hub shares (see TransportHub)."""

    def __init__(self, connection: Connection, hub: TransportHub) -> None:
        super().__init__(connection)
        # as the transport it shares; set once (the connection is frozen), an attribute like the other transports'
        self.datagrams = connection.kind in ("udpin", "udpout")
        self._hub = hub
        self._inner: Transport | None = None
        self.peer: tuple[str, int] | None = None

    async def open(self, on_data: DataCallback) -> None:
        await super().open(on_data)
        self._inner = await self._hub._attach(self)

    def reply_to(self, address: object) -> None:
        if self.connection.kind == "udpin" and isinstance(address, tuple):
            self.peer = address

    def send(self, data: bytes) -> None:
        if isinstance(self._inner, UdpTransport):
            self._inner.send_to(data, self.peer or self._inner.peer)
        elif self._inner is not None:
            self._inner.send(data)

    async def close(self) -> None:
        self._inner = None
        await self._hub._detach(self)
