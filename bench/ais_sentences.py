"""NMEA AIS sentences for the AIS bench and tests: real-world message 21s, other message types, noise, and helpers
that frame payloads (sentence level only: pyais encodes the bits)."""

from __future__ import annotations

from pyais import encode_dict
from pyais.util import checksum, compute_checksum

from uavcore.ais import AtonReport, encode_aton_report

# Real-world message 21s, with where they were published and what they decode to:
# - a virtual AtoN on the San Francisco-Oakland Bay Bridge: the example of the Rust crate `ais` (its lib.rs
#   documentation); MMSI 993692028, "SF OAK BAY BR VAIS E", beacon special mark, virtual, timestamp 61
SF_BAY_BRIDGE_VIRTUAL = b"!AIVDM,1,1,,B,E>kb9O9aS@7PUh10dh19@;0Tah2cWrfP:l?M`00003vP100,0*01"
# - a two-part report of a Canadian reference point, off position: pyais's tests/test_decode.py
#   (test_msg_type_21); MMSI 316021442, "DFO2", 48.65457 N 123.429155 W, DGNSS accuracy, second 18
DFO2_PARTS = (
    b"!AIVDM,2,1,7,B,E4eHJhPR37q0000000000000000KUOSc=rq4h00000a,0*4A",
    b"!AIVDM,2,2,7,B,@20,4*54",
)
# Other message types, as a receiver hears them among the AtoNs (pyais's tests/test_decode.py)
POSITION_REPORT_1 = b"!AIVDM,1,1,,B,15M67FC000G?ufbE`FepT@3n00Sa,0*5C"
POSITION_REPORT_3 = b"!AIVDM,1,1,,A,35NSH95001G?wopE`beasVk@0E5:,0*6F"
STATIC_DATA_5_PARTS = (
    b"!AIVDM,2,1,1,A,55?MbV02;H;s<HtKR20EHE:0@T4@Dn2222222216L961O5Gf0NSQEp6ClRp8,0*1C",
    b"!AIVDM,2,2,1,A,88888888880,2*25",
)


def sentence(
    payload: str, fill_bits: int = 0, parts: tuple[int, int] = (1, 1), seq_id: str = "", channel: str = "A"
) -> str:
    """One !AIVDM sentence around an armoured payload, with its checksum."""
    body = f"!AIVDM,{parts[0]},{parts[1]},{seq_id},{channel},{payload},{fill_bits}"
    return f"{body}*{compute_checksum(body):02X}"


def fragments(line: str, count: int, seq_id: int, channel: str = "A") -> list[bytes]:
    """A single-sentence message's payload re-framed as `count` parts (sequential id seq_id), in order."""
    fields = line.split(",")
    payload, fill_bits = fields[5], int(fields[6].split("*")[0])
    size = -(-len(payload) // count)
    chunks = [payload[i : i + size] for i in range(0, len(payload), size)]
    return [
        sentence(chunk, fill_bits if n == len(chunks) else 0, (len(chunks), n), str(seq_id), channel).encode()
        for n, chunk in enumerate(chunks, start=1)
    ]


def tag_block(text: str) -> str:
    """An NMEA 4.10 tag block, backslashes included, with its checksum."""
    return f"\\{text}*{checksum(text.encode()):02X}\\"


def aton_line(report: AtonReport, channel: str = "A") -> bytes:
    return encode_aton_report(report, channel)[0].encode()


def bad_checksum(line: bytes) -> bytes:
    """The line with its checksum's last digit changed."""
    last = line[-1:]
    return line[:-1] + (b"0" if last != b"0" else b"1")


def message_type_line(msg_type: int, mmsi: int) -> bytes:
    """A short position report of another type (1, 3, ...) as pyais encodes it."""
    return encode_dict({"msg_type": msg_type, "mmsi": mmsi, "lat": 55.0, "lon": 12.0}, sentence_type="VDM")[0].encode()


def static_data_parts(mmsi: int, seq_id: int, channel: str = "A") -> list[bytes]:
    """A vessel's static and voyage data (message 5: two sentences), as pyais encodes it."""
    fields = {"msg_type": 5, "mmsi": mmsi, "shipname": f"VESSEL {mmsi % 1000}", "callsign": "CALL", "ship_type": 70}
    return [line.encode() for line in encode_dict(fields, sentence_type="VDM", radio_channel=channel, seq_id=seq_id)]
