"""MAVLink FTP without sockets: the payload codec against pymavlink's packing of FILE_TRANSFER_PROTOCOL, and the
read-only responder (`uavcore.mavftp.FtpResponder`) on an in-memory tree and on a directory
(`sitl_quad.mavlink.ftp.DirectoryStore`)."""

from __future__ import annotations

import struct

import pytest

from sitl_quad.mavlink.ftp import DirectoryStore
from uavcore.mavftp import (
    BURST_CHUNK_BYTES,
    MAX_DATA,
    PAYLOAD_LENGTH,
    DirEntry,
    FtpCodecError,
    FtpPayload,
    FtpResponder,
    NakError,
    Opcode,
    parse_mftp_url,
    served_path,
)
from uavcore.mavlink import Encoder, mavlink, new_parser, parse_datagram

CLIENT = ("127.0.0.1", 14550)


# ----- the codec
def test_payload_layout_is_the_specifications():
    payload = FtpPayload(
        0x1234,
        Opcode.ACK,
        session=7,
        size=3,
        req_opcode=Opcode.READ_FILE,
        burst_complete=True,
        offset=0x0A0B0C0D,
        data=b"abc",
    ).encode()
    assert len(payload) == PAYLOAD_LENGTH == 251 and MAX_DATA == 239
    assert payload[0:2] == b"\x34\x12"  # seq_number, u16 little-endian
    assert payload[2] == 7 and payload[3] == 128 and payload[4] == 3  # session, opcode, size
    assert payload[5] == 5 and payload[6] == 1 and payload[7] == 0  # req_opcode, burst_complete, padding
    assert payload[8:12] == b"\x0d\x0c\x0b\x0a"  # offset, u32 little-endian
    assert payload[12:15] == b"abc" and payload[15:] == bytes(PAYLOAD_LENGTH - 15)


@pytest.mark.parametrize(
    "original",
    [
        FtpPayload(1, Opcode.OPEN_FILE_RO, size=12, data=b"/img_001.jpg"),
        FtpPayload(
            65535,
            Opcode.ACK,
            session=3,
            size=MAX_DATA,
            req_opcode=Opcode.BURST_READ_FILE,
            burst_complete=True,
            offset=2**32 - 1,
            data=bytes(range(MAX_DATA)),
        ),
        FtpPayload(9, Opcode.NAK, size=2, req_opcode=Opcode.OPEN_FILE_RO, data=bytes([NakError.FailErrno, 13])),
        FtpPayload(4, Opcode.TERMINATE_SESSION, session=2),
    ],
    ids=["open", "full-burst-packet", "nak-errno", "terminate"],
)
def test_round_trip_through_pymavlinks_file_transfer_protocol(original):
    """Encoded into FILE_TRANSFER_PROTOCOL, packed into a signed MAVLink 2 frame by pymavlink, parsed back:
    the same payload, byte for byte."""
    encoder = Encoder(255, 190, signing_key=bytes(32))
    message = mavlink.MAVLink_file_transfer_protocol_message(0, 1, 100, list(original.encode()))
    (parsed,) = parse_datagram(new_parser(1, 100, bytes(32)), encoder.pack(message))
    assert parsed.get_type() == "FILE_TRANSFER_PROTOCOL" and (parsed.target_system, parsed.target_component) == (1, 100)
    assert bytes(parsed.payload) == original.encode()
    assert FtpPayload.decode(bytes(parsed.payload)) == original


def test_decode_refuses_what_is_not_a_payload_and_encode_what_does_not_fit():
    with pytest.raises(FtpCodecError):
        FtpPayload.decode(bytes(250))
    with pytest.raises(FtpCodecError):
        FtpPayload(1, Opcode.WRITE_FILE, data=bytes(MAX_DATA + 1)).encode()
    with pytest.raises(FtpCodecError):
        FtpPayload(65536, Opcode.NONE).encode()
    # a size field over 239 (a hostile request) reads no more than the payload holds
    raw = bytearray(FtpPayload(1, Opcode.OPEN_FILE_RO).encode())
    raw[4] = 250
    assert len(FtpPayload.decode(bytes(raw)).data) == MAX_DATA


def test_reply_numbers_and_names():
    request = FtpPayload(65535, Opcode.READ_FILE, session=1, size=10, offset=478)
    nak = request.nak(NakError.EOF)
    assert (nak.seq_number, nak.opcode, nak.req_opcode, nak.session, nak.size) == (
        0,
        Opcode.NAK,
        Opcode.READ_FILE,
        1,
        1,
    )
    assert nak.nak_error is NakError.EOF and nak.nak_error.name == "EOF"
    assert request.nak(NakError.FailErrno, 2).data == bytes([2, 2])
    assert FtpPayload(1, Opcode.NAK, size=1, data=bytes([77])).nak_error == 77  # not in the specification


@pytest.mark.parametrize(
    ("requested", "served"),
    [
        ("img.jpg", "/img.jpg"),
        ("/a//b/./c.jpg", "/a/b/c.jpg"),
        ("/../etc/passwd", "/etc/passwd"),
        ("../../x", "/x"),
        ("//x", "/x"),
        ("", "/"),
        ("/a/../../b", "/b"),
    ],
)
def test_served_path_never_leaves_the_root(requested, served):
    assert served_path(requested) == served


def test_camera_file_urls():
    assert parse_mftp_url("mftp://[;comp=100]/img_0001.jpg") == ("/img_0001.jpg", 100)
    assert parse_mftp_url("mftp:///logs/a.ulg") == ("/logs/a.ulg", None)
    assert parse_mftp_url("/plain.jpg") == ("/plain.jpg", None)


# ----- the responder
class MemoryStore:
    def __init__(self, files: dict[str, bytes], dirs: dict[str, list[str]]) -> None:
        self.files, self.dirs = files, dirs

    def size(self, path: str) -> int | None:
        return len(self.files[path]) if path in self.files else None

    def read(self, path: str, offset: int, length: int) -> bytes:
        return self.files[path][offset : offset + length]

    def entries(self, path: str) -> list[DirEntry] | None:
        if path not in self.dirs:
            return None
        prefix = path.rstrip("/")
        return [
            DirEntry(name, f"{prefix}/{name}" in self.dirs, len(self.files.get(f"{prefix}/{name}", b"")))
            for name in self.dirs[path]
        ]


CONTENT = bytes(range(256)) * 400  # 102400 bytes: three bursts (35850 each) and a bit


@pytest.fixture
def responder() -> FtpResponder:
    files = {"/img.jpg": CONTENT, "/empty": b"", "/sub/a.txt": b"hello"}
    return FtpResponder(MemoryStore(files, {"/": ["empty", "img.jpg", "sub"], "/sub": ["a.txt"]}), max_sessions=2)


class Client:
    """Sends requests with rising sequence numbers, as a client does."""

    def __init__(self, responder: FtpResponder, key: object = CLIENT) -> None:
        self.responder, self.seq, self.key = responder, 0, key

    def ask(self, opcode: Opcode, **fields) -> FtpPayload | None:
        self.seq += 1
        self.last = FtpPayload(self.seq, opcode, **fields)
        return self.responder.handle(self.key, self.last)

    def open(self, path: str) -> FtpPayload:
        reply = self.ask(Opcode.OPEN_FILE_RO, size=len(path), data=path.encode())
        assert reply is not None
        return reply


def test_open_read_terminate(responder):
    client = Client(responder)
    opened = client.open("/img.jpg")
    assert opened.opcode == Opcode.ACK and opened.seq_number == client.seq + 1
    assert struct.unpack("<I", opened.data) == (len(CONTENT),)
    read = client.ask(Opcode.READ_FILE, session=opened.session, size=MAX_DATA, offset=1000)
    assert read is not None and read.data == CONTENT[1000 : 1000 + MAX_DATA] and read.offset == 1000
    short = client.ask(Opcode.READ_FILE, session=opened.session, size=10, offset=len(CONTENT) - 4)
    assert short is not None and short.data == CONTENT[-4:]  # the size asked for, cut at the end of the file
    eof = client.ask(Opcode.READ_FILE, session=opened.session, size=10, offset=len(CONTENT))
    assert eof is not None and eof.nak_error is NakError.EOF
    assert client.ask(Opcode.TERMINATE_SESSION, session=opened.session).opcode == Opcode.ACK
    gone = client.ask(Opcode.READ_FILE, session=opened.session, size=10)
    assert gone is not None and gone.nak_error is NakError.InvalidSession


def test_a_repeated_request_gets_the_same_reply_not_a_second_session(responder):
    client = Client(responder)
    first = client.open("/img.jpg")
    again = responder.handle(CLIENT, client.last)  # the ACK was lost: the client sends the same request
    assert again == first and len(responder.sessions) == 1


def test_sessions_are_limited_and_reset(responder):
    first, second, third = (Client(responder, ("127.0.0.1", port)) for port in (14550, 14551, 14552))
    assert {first.open("/img.jpg").session, second.open("/empty").session} == {0, 1}
    assert third.open("/img.jpg").nak_error is NakError.NoSessionsAvailable
    assert third.ask(Opcode.RESET_SESSIONS).opcode == Opcode.ACK
    assert third.open("/img.jpg").session == 0


def test_a_client_that_opens_again_has_its_last_session_closed_and_others_keep_theirs(responder):
    """MAVSDK's client reads on session 0 whatever the open returned: one that exited without its
    TerminateSession (same address and ids as the next one, a new mavsdk_server on the same port) left session 0
    open on the empty file, and the next client's reads on 0 got EOF instead of its own file."""
    other, left, again = Client(responder, "other"), Client(responder), Client(responder)
    assert left.open("/empty").session == 0
    assert other.open("/sub/a.txt").session == 1
    opened = again.open("/img.jpg")
    assert opened.session == 0 and struct.unpack("<I", opened.data) == (len(CONTENT),)
    read = again.ask(Opcode.READ_FILE, session=0, size=MAX_DATA, offset=0)
    assert read is not None and read.data == CONTENT[:MAX_DATA]
    theirs = other.ask(Opcode.READ_FILE, session=1, size=MAX_DATA, offset=0)
    assert theirs is not None and theirs.data == b"hello"


@pytest.mark.parametrize(
    ("path", "error"),
    [("/missing.jpg", NakError.FileNotFound), ("/sub", NakError.FileNotFound), ("/../img.jpg", None)],
)
def test_open_refusals(responder, path, error):
    # "/../img.jpg" is "/img.jpg": ".." stops at the served root
    assert Client(responder).open(path).nak_error == error


@pytest.mark.parametrize(
    "opcode",
    [
        Opcode.CREATE_FILE,
        Opcode.WRITE_FILE,
        Opcode.REMOVE_FILE,
        Opcode.CREATE_DIRECTORY,
        Opcode.REMOVE_DIRECTORY,
        Opcode.OPEN_FILE_WO,
        Opcode.TRUNCATE_FILE,
        Opcode.RENAME,
        Opcode.CALC_FILE_CRC32,
        99,
    ],
)
def test_anything_but_reading_is_an_unknown_command(responder, opcode):
    reply = Client(responder).ask(opcode, size=8, data=b"/img.jpg")
    assert reply is not None and reply.nak_error is NakError.UnknownCommand and reply.req_opcode == opcode


def test_a_responder_without_files_refuses_everything_at_once():
    reply = Client(FtpResponder(None)).ask(Opcode.OPEN_FILE_RO, size=16, data=b"@PARAM/param.pck")
    assert reply is not None and reply.nak_error is NakError.UnknownCommand


def test_replies_are_not_answered(responder):
    assert Client(responder).ask(Opcode.ACK) is None and Client(responder).ask(Opcode.NAK) is None


def test_burst_streams_chunks_and_completes_at_the_end(responder):
    client = Client(responder)
    session = client.open("/img.jpg").session
    received = bytearray()
    bursts = 0
    while len(received) < len(CONTENT):
        assert client.ask(Opcode.BURST_READ_FILE, session=session, size=MAX_DATA, offset=len(received)) is None
        request_seq, bursts = client.seq, bursts + 1
        packets = []
        while responder.bursting:
            packets += [packet for _, packet in responder.burst(limit=32)]
        assert [p.seq_number for p in packets] == [request_seq + 1 + i for i in range(len(packets))]
        assert all(p.opcode == Opcode.ACK and p.req_opcode == Opcode.BURST_READ_FILE for p in packets)
        assert [p.burst_complete for p in packets] == [False] * (len(packets) - 1) + [True]
        for packet in packets:
            assert packet.offset == len(received)
            received += packet.data
        assert sum(len(p.data) for p in packets) <= BURST_CHUNK_BYTES
    assert bytes(received) == CONTENT and bursts == 3
    at_end = client.ask(Opcode.BURST_READ_FILE, session=session, size=MAX_DATA, offset=len(CONTENT))
    assert at_end is not None and at_end.nak_error is NakError.EOF


def test_list_directory_in_pages(responder):
    client = Client(responder)
    page = client.ask(Opcode.LIST_DIRECTORY, size=1, data=b"/")
    assert page is not None and page.data == b"Fempty\t0\0Fimg.jpg\t102400\0Dsub\0"
    past = client.ask(Opcode.LIST_DIRECTORY, size=1, offset=3, data=b"/")
    assert past is not None and past.nak_error is NakError.EOF
    missing = client.ask(Opcode.LIST_DIRECTORY, size=4, data=b"/nope")
    assert missing is not None and missing.nak_error is NakError.FileNotFound


def test_directory_store_serves_nothing_outside_its_root(tmp_path):
    root, outside = tmp_path / "root", tmp_path / "outside.txt"
    (root / "sub").mkdir(parents=True)
    (root / "img.jpg").write_bytes(b"jpeg")
    outside.write_text("secret")
    (root / "link-out").symlink_to(outside)
    (root / "link-in").symlink_to(root / "img.jpg")
    store = DirectoryStore(root)
    assert store.size("/img.jpg") == 4 and store.read("/img.jpg", 1, 10) == b"peg"
    assert store.size("/link-in") == 4
    assert store.size("/link-out") is None  # a link out of the root is absent: FileNotFound
    assert store.size("/sub") is None and store.entries("/img.jpg") is None
    assert [e.name for e in store.entries("/") or []] == ["img.jpg", "link-in", "sub"]
