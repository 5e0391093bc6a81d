"""MAVLink 2 framing shared by every process here: packing (with optional signing) and datagram parsing."""

from __future__ import annotations

import time

from sitl_quad.mavlink import mavlink

# Messages a keyed endpoint still accepts unsigned: radio status only, as PX4 does.
_UNSIGNED_ALLOWED = {mavlink.MAVLINK_MSG_ID_RADIO_STATUS}


def signing_timestamp() -> int:
    """MAVLink signing time: 10 us units since 2015-01-01."""
    return int((time.time() - 1420070400) * 100_000)


class Encoder:
    """Packs messages from one sysid/compid, signing them when a key is set."""

    def __init__(self, sysid: int, compid: int, signing_key: bytes | None = None) -> None:
        self.mav = mavlink.MAVLink(None, srcSystem=sysid, srcComponent=compid)
        self.signed = signing_key is not None
        if self.signed:
            self.mav.signing.secret_key = signing_key
            self.mav.signing.sign_outgoing = True
            self.mav.signing.timestamp = signing_timestamp()

    def pack(self, msg) -> bytes:
        if self.signed:  # timestamps must rise for every signed frame of a link
            self.mav.signing.timestamp = max(self.mav.signing.timestamp + 1, signing_timestamp())
        buf = msg.pack(self.mav)
        self.mav.seq = (self.mav.seq + 1) % 256
        return buf


def new_parser(sysid: int, compid: int, signing_key: bytes | None = None) -> mavlink.MAVLink:
    """A robust parser (bad frames come back as MAVLink_bad_data); with a key, unsigned frames are refused."""
    parser = mavlink.MAVLink(None, srcSystem=sysid, srcComponent=compid)
    parser.robust_parsing = True
    if signing_key is not None:
        parser.signing.secret_key = signing_key
        parser.signing.allow_unsigned_callback = lambda _mav, msg_id: msg_id in _UNSIGNED_ALLOWED
    return parser


def parse_datagram(parser: mavlink.MAVLink, data: bytes) -> list:
    """Every frame of one UDP datagram. A datagram carries whole frames, so a truncated tail is dropped
    rather than left to corrupt the next datagram. pymavlink may raise on hostile input: callers catch."""
    parser.buf, parser.buf_index = bytearray(), 0
    parser.expected_length = mavlink.HEADER_LEN_V1 + 2
    return parser.parse_buffer(data) or []


def item_message(item, target_system: int, target_component: int):
    """The MISSION_ITEM_INT that carries a stored `sitl_quad.mission_items.MissionItem`, verbatim."""
    return mavlink.MAVLink_mission_item_int_message(
        target_system,
        target_component,
        item.seq,
        item.frame,
        item.command,
        item.current,
        item.autocontinue,
        item.param1,
        item.param2,
        item.param3,
        item.param4,
        item.x,
        item.y,
        item.z,
        item.mission_type,
    )
