"""MAVLink FTP, client side: download a file from a component of the vehicle (its camera's images), as MAVSDK's
Ftp plugin and QGroundControl do.

OpenFileRO names the file and gets a session and the file's size; a file over `max_bytes` is refused there,
before any of it is read. The bytes then come by BurstReadFile (the server streams ACKs until burst_complete,
the client asks again from where it is) or by ReadFile, one request per 239 bytes; a hole a lost burst packet
left is filled by ReadFile. TerminateSession closes the session, also when the download fails.

Every request waits `timeout_s` (wall clock) for its answer (seq_number + 1, req_opcode the request's) and is
sent again, unchanged, up to `retries` times, as the specification asks: the server answers a repeated request
with its previous reply. A NAK ends the download with `FtpError` naming the specification's error and the path
("FileNotFound: /missing.jpg"); silence with `FtpTimeoutError`. The codec is `uavcore.mavftp`.
"""

from __future__ import annotations

import asyncio
import logging
import struct
from typing import TYPE_CHECKING, Any

from gcs.vehicle.errors import LinkError
from uavcore.mavftp import MAX_DATA, FtpCodecError, FtpPayload, NakError, Opcode, nak_name, parse_mftp_url
from uavcore.mavlink import GCS_COMPID, GCS_SYSID, mavlink

if TYPE_CHECKING:
    from gcs.vehicle.link import LinkManager

log = logging.getLogger(__name__)

CAMERA_COMPID = mavlink.MAV_COMP_ID_CAMERA  # 100: where the images are
DEFAULT_MAX_BYTES = 16 * 1024 * 1024  # a camera's JPEG is a few MB; anything far larger is not what was asked for
REQUEST_TIMEOUT_S = 0.5  # per try; the specification suggests 50 ms on a radio link, a loaded machine needs more
REQUEST_RETRIES = 5
MESSAGE = "FILE_TRANSFER_PROTOCOL"


class FtpError(LinkError):
    """The download failed: `error` is the NAK's error (a `NakError`, or the int of a code the specification
    lacks; None when the server did not answer or the file is too large), `path` the file asked for."""

    def __init__(self, error: NakError | int | None, path: str, detail: str = "") -> None:
        self.error = error
        self.path = path
        name = nak_name(error) if error is not None else type(self).__name__.removesuffix("Error")
        super().__init__(f"{name}: {path}" + (f" ({detail})" if detail else ""))


class FtpTimeoutError(FtpError):
    def __init__(self, path: str, detail: str) -> None:
        super().__init__(None, path, detail)


class FileTooLargeError(FtpError):
    def __init__(self, path: str, size: int, max_bytes: int) -> None:
        self.size = size
        super().__init__(None, path, f"{size} bytes, over the limit of {max_bytes}")


class FtpClient:
    """MAVLink FTP over a started `LinkManager`. One transfer at a time per client: a server answers a repeated
    request by its seq_number, so two transfers interleaving on one client would confuse it."""

    def __init__(self, link: LinkManager, timeout_s: float = REQUEST_TIMEOUT_S, retries: int = REQUEST_RETRIES) -> None:
        self.link = link
        self.timeout_s = timeout_s
        self.retries = retries
        self._seq = 0
        self._lock = asyncio.Lock()

    async def download(
        self,
        path: str,
        target_component: int = CAMERA_COMPID,
        max_bytes: int = DEFAULT_MAX_BYTES,
        burst: bool = True,
    ) -> bytes:
        """The file at `path` on component `target_component` of the vehicle's system. `path` may also be a
        camera's file URL ("mftp://[;comp=100]/img_0001.jpg"), whose component then wins."""
        path, url_component = parse_mftp_url(path)
        component = url_component if url_component is not None else target_component
        async with self._lock:
            with self.link.subscribe({MESSAGE}, component=component) as inbox:
                transfer = _Transfer(self, inbox, component, path)
                return await transfer.run(max_bytes, burst)

    def next_seq(self) -> int:
        self._seq = (self._seq + 1) % 65536
        return self._seq


class _Transfer:
    """One download: the requests of one session, their answers from one component."""

    def __init__(self, client: FtpClient, inbox: asyncio.Queue, component: int, path: str) -> None:
        self.client = client
        self.link = client.link
        self.inbox = inbox
        self.component = component
        self.path = path
        self.session: int | None = None

    async def run(self, max_bytes: int, burst: bool) -> bytes:
        opened = await self.request(Opcode.OPEN_FILE_RO, data=self.path.encode() + b"\0")
        if len(opened.data) < 4:
            raise FtpError(NakError.Fail, self.path, "OpenFileRO's ACK carries no file size")
        self.session = opened.session
        size = struct.unpack_from("<I", opened.data)[0]
        try:
            if size > max_bytes:
                raise FileTooLargeError(self.path, size, max_bytes)
            content = await (self._read_bursts(size) if burst else self._read_each(size))
        except Exception:  # a refusal, silence, a too large file; a cancelled download does not wait on the link
            await self._terminate(quiet=True)
            raise
        await self._terminate(quiet=False)
        return content

    # ----- reading
    async def _read_each(self, size: int) -> bytes:
        content = bytearray()
        while len(content) < size:
            reply = await self.request(Opcode.READ_FILE, size=min(MAX_DATA, size - len(content)), offset=len(content))
            self._check_chunk(reply, len(content), size)
            content += reply.data
        return bytes(content)

    async def _read_bursts(self, size: int) -> bytes:
        chunks: dict[int, bytes] = {}
        tries_left = self.client.retries
        while (gap := _first_gap(chunks, size)) is not None:
            start, end = gap
            if end < size:  # a hole a lost packet left behind the burst: ask for it alone
                reply = await self.request(Opcode.READ_FILE, size=min(MAX_DATA, end - start), offset=start)
                self._check_chunk(reply, start, size)
                chunks[start] = reply.data
                continue
            if await self._burst(start, size, chunks):
                tries_left = self.client.retries
            elif tries_left == 0:
                raise FtpTimeoutError(
                    self.path, f"no BurstReadFile data at offset {start} ({self.client.retries} retries)"
                )
            else:
                tries_left -= 1
        content = bytearray(size)
        for offset, data in chunks.items():  # by offset: a packet of an earlier burst may overlap a later one
            content[offset : offset + len(data)] = data
        return bytes(content)

    async def _burst(self, offset: int, size: int, chunks: dict[int, bytes]) -> bool:
        """One BurstReadFile from offset, its packets put in chunks until burst_complete, EOF or silence; True if
        it brought any data. Packets still in flight from an earlier burst of the session carry the file's bytes
        at their offsets too, and are kept."""
        self._send(self._payload(Opcode.BURST_READ_FILE, size=MAX_DATA, offset=offset))
        progressed = False
        while (reply := await self._next(self.client.timeout_s)) is not None:
            if reply.req_opcode != Opcode.BURST_READ_FILE or reply.session != self.session:
                continue
            if reply.opcode == Opcode.NAK:
                if reply.nak_error == NakError.EOF:  # PX4 ends a burst that reached the end of the file so
                    break
                raise FtpError(reply.nak_error, self.path, f"BurstReadFile at offset {offset}")
            self._check_chunk(reply, reply.offset, size)
            chunks[reply.offset] = reply.data
            progressed = True
            if reply.burst_complete:
                break
        return progressed

    def _check_chunk(self, reply: FtpPayload, offset: int, size: int) -> None:
        if reply.offset != offset or offset + len(reply.data) > size or (not reply.data and offset < size):
            raise FtpError(
                NakError.Fail, self.path, f"{len(reply.data)} bytes at offset {reply.offset} of a {size}-byte file"
            )

    async def _terminate(self, quiet: bool) -> None:
        """Close the session; a server that does not answer keeps it only until its next ResetSessions, so a
        silent terminate does not fail a download that has its bytes."""
        if self.session is None:
            return
        try:
            await self.request(Opcode.TERMINATE_SESSION)
        except FtpError as error:
            if not quiet:
                log.warning("FTP: closing the session of %s: %s", self.path, error)

    # ----- one request, its answer
    async def request(self, opcode: Opcode, size: int | None = None, offset: int = 0, data: bytes = b"") -> FtpPayload:
        """Send until the answer comes (the same payload each time: a repeat, not a new request); a NAK raises."""
        request = self._payload(opcode, size=len(data) if size is None else size, offset=offset, data=data)
        for _ in range(self.client.retries + 1):
            self._send(request)
            loop = asyncio.get_running_loop()
            deadline = loop.time() + self.client.timeout_s
            while (remaining := deadline - loop.time()) > 0:
                reply = await self._next(remaining)
                if reply is None:
                    break
                if reply.req_opcode != opcode or reply.seq_number != (request.seq_number + 1) % 65536:
                    continue  # a late answer to an earlier try or request
                if reply.opcode == Opcode.NAK:
                    raise FtpError(reply.nak_error, self.path, f"{opcode.name} refused")
                return reply
        raise FtpTimeoutError(
            self.path, f"no answer to {opcode.name} ({self.client.retries} retries, {self.link.connection})"
        )

    def _payload(self, opcode: Opcode, size: int = 0, offset: int = 0, data: bytes = b"") -> FtpPayload:
        session = self.session if self.session is not None else 0
        return FtpPayload(self.client.next_seq(), opcode, session, size, offset=offset, data=data)

    def _send(self, request: FtpPayload) -> None:
        sysid = self.link.target[0]
        self.link.send(mavlink.MAVLink_file_transfer_protocol_message(0, sysid, self.component, list(request.encode())))

    async def _next(self, timeout_s: float) -> FtpPayload | None:
        """The next FTP payload addressed to this ground station, or None after timeout_s."""
        loop = asyncio.get_running_loop()
        deadline = loop.time() + timeout_s
        while (remaining := deadline - loop.time()) > 0:
            try:
                async with asyncio.timeout(remaining):
                    message: Any = await self.inbox.get()
            except TimeoutError:
                return None
            if message.target_system not in (0, GCS_SYSID) or message.target_component not in (0, GCS_COMPID):
                continue
            try:
                return FtpPayload.decode(bytes(message.payload))
            except FtpCodecError:
                continue
        return None


def _first_gap(chunks: dict[int, bytes], size: int) -> tuple[int, int] | None:
    """The first [start, end) of the file not yet received, None once all of it is."""
    position = 0
    for offset in sorted(chunks):
        if offset > position:
            return position, offset
        position = max(position, offset + len(chunks[offset]))
    return (position, size) if position < size else None
