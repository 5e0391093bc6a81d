"""MAVLink FTP (https://mavlink.io/en/services/ftp.html): the payload codec and a read-only server, pure.

FILE_TRANSFER_PROTOCOL carries a 251-byte payload: a 12-byte header (seq_number u16, session u8, opcode u8,
size u8, req_opcode u8, burst_complete u8, padding u8, offset u32, little-endian as every MAVLink field) and up to
239 bytes of data. This module packs and parses that payload, names the opcodes and NAK errors, and answers
requests (`FtpResponder`) for the files a `FileStore` holds; it opens no socket and no file itself, so the vehicle
(`sitl_quad.mavlink.ftp`) and the ground station (`gcs.vehicle.ftp`) share one reading of the protocol.

Semantics follow PX4's server (MavlinkFTP) where the specification is silent, since MAVSDK and QGroundControl
are written against it: a reply's seq_number is the request's + 1; a request whose reply was lost is repeated
with the same seq_number and gets the same reply again; ReadFile or BurstReadFile at or past the end of the
file is NAK EOF; a burst streams ACKs of BurstReadFile with rising seq_number and offset and ends with
burst_complete = 1 after BURST_CHUNK_BYTES or at the end of the file, and the client asks again from where it is.
"""

from __future__ import annotations

import posixpath
import re
import struct
from collections.abc import Hashable
from dataclasses import dataclass, field, replace
from enum import IntEnum
from typing import Protocol

PAYLOAD_LENGTH = 251  # FILE_TRANSFER_PROTOCOL.payload
HEADER = struct.Struct("<HBBBBBBI")  # seq_number, session, opcode, size, req_opcode, burst_complete, padding, offset
MAX_DATA = PAYLOAD_LENGTH - HEADER.size  # 239
# PX4 ends a burst after about 35 kB ("determined empirically") so that a client that lost packets asks for the
# rest soon; 150 packets, as MAVSDK's FtpServer sends, is the same size.
BURST_CHUNK_BYTES = 150 * MAX_DATA
DEFAULT_SESSIONS = 4  # PX4 has one; one per client here, so QGC beside the service downloads meanwhile


class Opcode(IntEnum):
    """MAV_FTP_OPCODE: requests 0-15, replies ACK and NAK."""

    NONE = 0
    TERMINATE_SESSION = 1
    RESET_SESSIONS = 2
    LIST_DIRECTORY = 3
    OPEN_FILE_RO = 4
    READ_FILE = 5
    CREATE_FILE = 6
    WRITE_FILE = 7
    REMOVE_FILE = 8
    CREATE_DIRECTORY = 9
    REMOVE_DIRECTORY = 10
    OPEN_FILE_WO = 11
    TRUNCATE_FILE = 12
    RENAME = 13
    CALC_FILE_CRC32 = 14
    BURST_READ_FILE = 15
    ACK = 128
    NAK = 129


class NakError(IntEnum):
    """MAV_FTP_ERR, spelled as the specification names them (the names people read in error messages)."""

    NoError = 0
    Fail = 1
    FailErrno = 2  # data[1] holds the server's errno
    InvalidDataSize = 3
    InvalidSession = 4
    NoSessionsAvailable = 5
    EOF = 6
    UnknownCommand = 7
    FileExists = 8
    FileProtected = 9
    FileNotFound = 10


class FtpCodecError(ValueError):
    """A payload that cannot be FTP (wrong length) or a field out of its range."""


@dataclass(frozen=True)
class FtpPayload:
    """One FILE_TRANSFER_PROTOCOL payload. `size` is the header's size field: the length of `data` in most
    messages, but the number of bytes wanted in a ReadFile or BurstReadFile request (which carries no data)."""

    seq_number: int
    opcode: int
    session: int = 0
    size: int = 0
    req_opcode: int = 0
    burst_complete: bool = False
    offset: int = 0
    data: bytes = b""

    def encode(self) -> bytes:
        """The 251 bytes of FILE_TRANSFER_PROTOCOL.payload (data zero-padded)."""
        if len(self.data) > MAX_DATA:
            raise FtpCodecError(f"FTP data is at most {MAX_DATA} bytes, got {len(self.data)}")
        try:
            header = HEADER.pack(
                self.seq_number,
                self.session,
                self.opcode,
                self.size,
                self.req_opcode,
                int(self.burst_complete),
                0,
                self.offset,
            )
        except struct.error as error:
            raise FtpCodecError(f"FTP header field out of range: {error}") from error
        return (header + self.data).ljust(PAYLOAD_LENGTH, b"\0")

    @classmethod
    def decode(cls, payload: bytes) -> FtpPayload:
        """Parse FILE_TRANSFER_PROTOCOL.payload. `data` holds `size` bytes (at most MAX_DATA): in a ReadFile
        request, whose size is a byte count and not the length of data, that is padding, which no one reads."""
        if len(payload) != PAYLOAD_LENGTH:
            raise FtpCodecError(f"an FTP payload is {PAYLOAD_LENGTH} bytes, got {len(payload)}")
        seq, session, opcode, size, req_opcode, burst_complete, _padding, offset = HEADER.unpack_from(payload)
        data = payload[HEADER.size : HEADER.size + min(size, MAX_DATA)]
        return cls(seq, opcode, session, size, req_opcode, bool(burst_complete), offset, bytes(data))

    @property
    def path(self) -> str:
        """The data as a path: up to the first NUL (clients send "name\\0" or just "name")."""
        return self.data.split(b"\0", 1)[0].decode("utf-8", "replace")

    @property
    def nak_error(self) -> NakError | int | None:
        """The error of a NAK (an int for a code the specification lacks), None for anything else."""
        if self.opcode != Opcode.NAK or not self.data:
            return None
        code = self.data[0]
        return NakError(code) if code in NakError._value2member_map_ else code

    def reply(self, opcode: Opcode, data: bytes = b"", **fields) -> FtpPayload:
        """The ACK or NAK that answers this request: seq_number + 1, req_opcode = this opcode, same session and
        offset unless `fields` say otherwise."""
        base = FtpPayload(
            (self.seq_number + 1) % 65536, opcode, self.session, len(data), self.opcode, False, self.offset, data
        )
        return replace(base, **fields) if fields else base

    def nak(self, error: NakError, errno: int | None = None) -> FtpPayload:
        data = bytes([error]) if errno is None else bytes([error, errno & 0xFF])
        return self.reply(Opcode.NAK, data)


def nak_name(error: NakError | int | None) -> str:
    if isinstance(error, NakError):
        return error.name
    return "no error code" if error is None else f"error {error}"


_MFTP_URL = re.compile(r"^mftp://(?:\[;comp=(\d+)\])?(.*)$")


def parse_mftp_url(url: str) -> tuple[str, int | None]:
    """(path, component id or None) of a camera's file URL, as CAMERA_IMAGE_CAPTURED.file_url gives it
    ("mftp://[;comp=100]/img_0001.jpg"); a plain path comes back as it is, with None."""
    match = _MFTP_URL.match(url)
    if match is None:
        return url, None
    component, path = match.groups()
    return path or "/", int(component) if component is not None else None


def served_path(requested: str) -> str:
    """The path a request names, inside the served tree: absolute, normalised, and clamped at its root the way
    ".." is at a file system's root ("/../etc/passwd" is "/etc/passwd" of the served tree). So no request can name
    anything outside the root: a name that leaves it lands on a path the tree does not have, FileNotFound."""
    normal = posixpath.normpath("/" + requested.strip())
    return "/" + normal.lstrip("/")  # normpath keeps a leading "//" (POSIX): one root only


# ----- what the responder reads
@dataclass(frozen=True)
class DirEntry:
    name: str
    is_dir: bool
    size: int = 0


class FileStore(Protocol):
    """Read access to a served tree by served path ("/a/b.jpg"). Anything the store will not serve (absent, or a
    link out of its root) is absent: `size` and `entries` return None. May raise OSError on a failing read."""

    def size(self, path: str) -> int | None:
        """The byte size of the regular file at path; None if there is none."""
        ...

    def read(self, path: str, offset: int, length: int) -> bytes:
        """Up to length bytes from offset (fewer at the end of the file)."""
        ...

    def entries(self, path: str) -> list[DirEntry] | None:
        """The directory's entries in a stable order; None if path is no directory."""
        ...


@dataclass
class _Session:
    path: str
    size: int  # at open, as PX4: reads past it are EOF even if the file grew
    client: Hashable = None  # who opened it
    burst_client: Hashable | None = None  # while a burst streams: to whom
    burst_offset: int = 0
    burst_seq: int = 0
    burst_sent: int = 0


@dataclass
class FtpResponder:
    """Answers the read-only subset of MAVLink FTP for the files of `store`; with no store, refuses every request
    with UnknownCommand (a component that serves nothing, answering at once so that clients do not wait for
    their timeouts: MAVProxy's parameter download over FTP falls back to the PARAM protocol on it).

    `handle(client, request)` answers one request; `burst(limit)` yields the next packets of running bursts.
    `client` is whatever identifies the requester to the caller (its address and ids): replies are cached per
    client so that a repeated request is answered with the same reply."""

    store: FileStore | None
    max_sessions: int = DEFAULT_SESSIONS
    sessions: dict[int, _Session] = field(default_factory=dict, init=False)
    # per client: its last request and the reply it got
    _last_reply: dict[Hashable, tuple[FtpPayload, FtpPayload]] = field(default_factory=dict, init=False, repr=False)

    def handle(self, client: Hashable, request: FtpPayload) -> FtpPayload | None:
        """The reply to a request; None for a message that is itself a reply, or a burst that starts streaming
        (its packets come from burst())."""
        if request.opcode in (Opcode.ACK, Opcode.NAK):
            return None
        last = self._last_reply.get(client)
        if last is not None and last[0] == request:  # the reply was lost and the client asks again
            return last[1]
        reply = self._answer(client, request)
        if reply is not None:
            self._last_reply[client] = (request, reply)
        else:
            self._last_reply.pop(client, None)
        return reply

    def burst(self, limit: int) -> list[tuple[Hashable, FtpPayload]]:
        """Up to `limit` packets of the running bursts, in turn across sessions."""
        out: list[tuple[Hashable, FtpPayload]] = []
        streaming = [s for s in self.sessions.values() if s.burst_client is not None]
        while streaming and len(out) < limit:
            for session_id, session in list(self.sessions.items()):
                if session.burst_client is None or len(out) >= limit:
                    continue
                out.append((session.burst_client, self._burst_packet(session_id, session)))
            streaming = [s for s in self.sessions.values() if s.burst_client is not None]
        return out

    @property
    def bursting(self) -> bool:
        return any(s.burst_client is not None for s in self.sessions.values())

    # ----- one request
    def _answer(self, client: Hashable, request: FtpPayload) -> FtpPayload | None:
        if self.store is None:
            return request.nak(NakError.UnknownCommand)
        if request.size > MAX_DATA:
            return request.nak(NakError.InvalidDataSize)
        opcode = request.opcode
        try:
            if opcode == Opcode.NONE:
                return request.reply(Opcode.ACK)
            if opcode == Opcode.RESET_SESSIONS:
                self.sessions.clear()
                return request.reply(Opcode.ACK)
            if opcode == Opcode.TERMINATE_SESSION:
                if self.sessions.pop(request.session, None) is None:
                    return request.nak(NakError.InvalidSession)
                return request.reply(Opcode.ACK)
            if opcode == Opcode.OPEN_FILE_RO:
                return self._open(client, request)
            if opcode == Opcode.READ_FILE:
                return self._read(request)
            if opcode == Opcode.BURST_READ_FILE:
                return self._start_burst(client, request)
            if opcode == Opcode.LIST_DIRECTORY:
                return self._list(request)
        except OSError as error:  # the file went away or the disk failed under an open session
            return request.nak(NakError.FailErrno, error.errno or 0)
        # writing, removing, renaming, CRC: this server is read-only
        return request.nak(NakError.UnknownCommand)

    def _open(self, client: Hashable, request: FtpPayload) -> FtpPayload:
        assert self.store is not None
        path = served_path(request.path)
        size = self.store.size(path)
        if size is None:
            return request.nak(NakError.FileNotFound)
        if size > 0xFFFFFFFF:  # the size travels in 4 bytes: a file over 4 GiB is not served as if it were smaller
            return request.nak(NakError.Fail)
        # A client holds one session, as PX4's server and MAVSDK's have one (MAVSDK's closes the open one when a
        # new open comes): one that opens again has left the last behind. MAVSDK's client asks on session 0
        # whatever id the open returned, so a session a client left open when it exited before its
        # TerminateSession (mavsdk_server ending with its example program) made the next one read the old file.
        for stale in [i for i, session in self.sessions.items() if session.client == client]:
            del self.sessions[stale]
        free = next((i for i in range(self.max_sessions) if i not in self.sessions), None)
        if free is None:
            return request.nak(NakError.NoSessionsAvailable)
        self.sessions[free] = _Session(path, size, client)
        return request.reply(Opcode.ACK, struct.pack("<I", size), session=free, offset=0)

    def _read(self, request: FtpPayload) -> FtpPayload:
        assert self.store is not None
        session = self.sessions.get(request.session)
        if session is None:
            return request.nak(NakError.InvalidSession)
        if request.offset >= session.size:
            return request.nak(NakError.EOF)
        # the size asked for (PX4 ignores it and reads MAX_DATA; MAVSDK asks for exactly what is left)
        wanted = request.size if 0 < request.size <= MAX_DATA else MAX_DATA
        data = self.store.read(session.path, request.offset, min(wanted, session.size - request.offset))
        return request.reply(Opcode.ACK, data)

    def _start_burst(self, client: Hashable, request: FtpPayload) -> FtpPayload | None:
        session = self.sessions.get(request.session)
        if session is None:
            return request.nak(NakError.InvalidSession)
        if request.offset >= session.size:
            return request.nak(NakError.EOF)
        # a new request replaces a burst still running on the session: the client asked again from its offset
        session.burst_client = client
        session.burst_offset = request.offset
        session.burst_seq = (request.seq_number + 1) % 65536
        session.burst_sent = 0
        return None

    def _burst_packet(self, session_id: int, session: _Session) -> FtpPayload:
        assert self.store is not None
        header = FtpPayload(
            session.burst_seq, Opcode.ACK, session_id, req_opcode=Opcode.BURST_READ_FILE, offset=session.burst_offset
        )
        session.burst_seq = (session.burst_seq + 1) % 65536
        try:
            data = self.store.read(
                session.path, session.burst_offset, min(MAX_DATA, session.size - session.burst_offset)
            )
        except OSError as error:
            session.burst_client = None
            errno = (error.errno or 0) & 0xFF
            return replace(header, opcode=Opcode.NAK, size=2, data=bytes([NakError.FailErrno, errno]))
        if not data:  # the file shrank under the session
            session.burst_client = None
            return replace(header, opcode=Opcode.NAK, size=1, data=bytes([NakError.EOF]))
        session.burst_offset += len(data)
        session.burst_sent += len(data)
        done = session.burst_offset >= session.size or session.burst_sent >= BURST_CHUNK_BYTES
        if done:
            session.burst_client = None
        return replace(header, size=len(data), data=data, burst_complete=done)

    def _list(self, request: FtpPayload) -> FtpPayload:
        assert self.store is not None
        entries = self.store.entries(served_path(request.path))
        if entries is None:
            return request.nak(NakError.FileNotFound)
        if request.offset > 0 and request.offset >= len(entries):
            return request.nak(NakError.EOF)
        # as PX4: "F<name>\t<size>\0" for a file, "D<name>\0" for a directory, as many as fit
        data = b""
        for entry in entries[request.offset :]:
            text = f"D{entry.name}" if entry.is_dir else f"F{entry.name}\t{entry.size}"
            encoded = text.encode("utf-8", "replace") + b"\0"
            if len(data) + len(encoded) > MAX_DATA:
                break
            data += encoded
        return request.reply(Opcode.ACK, data)
