"""The one MAVLink codec of the project: dialect, ids, framing and parsing, signing, mission-item conversion.

Every process (vehicle, offboard controller, ground station, test harnesses) packs and parses through this
module, so they agree on the wire format: MAVLink 2, pymavlink's `common` dialect, the same signing rules.
pymavlink is only a codec here; sockets belong to each process's link module.
"""

from __future__ import annotations

import hashlib
import math
import os
import time
from typing import Any

# pymavlink picks its wire protocol at import time: speak MAVLink 2 everywhere.
os.environ.setdefault("MAVLINK20", "1")

from pymavlink.dialects.v20 import common as mavlink

from uavcore.mission import MissionItem, MissionType

__all__ = [
    "AUTOPILOT_COMPID",
    "GCS_COMPID",
    "GCS_SYSID",
    "MAV_CMD_BATTERY_RESET",
    "ONBOARD_COMPUTER_COMPID",
    "VEHICLE_SYSID",
    "Encoder",
    "item_from_message",
    "item_message",
    "mavlink",
    "new_parser",
    "parse_datagram",
    "parse_signing_key",
    "result_name",
    "signing_timestamp",
    "statustext",
]

# System and component ids, as MAVLink's MAV_COMPONENT enum and QGC/MAVSDK use them.
VEHICLE_SYSID = 1  # the default autopilot system id (a vehicle may be given another)
AUTOPILOT_COMPID = mavlink.MAV_COMP_ID_AUTOPILOT1  # 1
ONBOARD_COMPUTER_COMPID = mavlink.MAV_COMP_ID_ONBOARD_COMPUTER  # 191: the offboard controller
GCS_SYSID = 255  # QGroundControl's and MAVProxy's default ground-station system id
GCS_COMPID = mavlink.MAV_COMP_ID_MISSIONPLANNER  # 190

# Command ids the common dialect lacks. MAV_CMD_BATTERY_RESET is ardupilotmega.xml's (PX4 and ArduPilot both accept
# it): param1 the mask of batteries to reset (bit 0: the first battery, BATTERY_STATUS id 0), param2 the percentage
# remaining to set.
MAV_CMD_BATTERY_RESET = 42651

# Ports, as PX4 SITL uses them: the vehicle's API/offboard port (our vehicle listens here by default) and the
# ground-control port vehicles and radios send to.
VEHICLE_UDP_PORT = 14540
GCS_UDP_PORT = 14550
# The vehicle and the offboard controller read their signing key from here when no --signing-key is given: a
# command line is shown by ps and written to logs, the environment is not.
SIGNING_KEY_ENV = "MAVLINK_SIGNING_KEY"

SIGNING_EPOCH_S = 1420070400  # MAVLink signing timestamps count 10 us units from 2015-01-01 00:00 UTC
# Messages a keyed endpoint still accepts unsigned: radio status only, as PX4 does.
_UNSIGNED_ALLOWED = {mavlink.MAVLINK_MSG_ID_RADIO_STATUS}
_INT32_MAX = 2**31 - 1  # MISSION_ITEM_INT's "no position" marker


def signing_timestamp() -> int:
    """MAVLink signing time now: 10 us units since 2015-01-01."""
    return int((time.time() - SIGNING_EPOCH_S) * 100_000)


def parse_signing_key(text: str) -> bytes:
    """A signing key as people type it: 64 hex digits as is; anything else is a passphrase hashed with SHA-256,
    as MAVProxy's `signing setup` does."""
    try:
        key = bytes.fromhex(text)
        if len(key) == 32:
            return key
    except ValueError:
        pass
    return hashlib.sha256(text.encode()).digest()


class Encoder:
    """Packs messages from one sysid/compid, signing them when a key is set.

    `encoder.mav` is pymavlink's MAVLink object: its `*_encode` methods build messages to pack.
    """

    def __init__(self, sysid: int, compid: int, signing_key: bytes | None = None) -> None:
        self.mav = mavlink.MAVLink(None, srcSystem=sysid, srcComponent=compid)
        self.signed = signing_key is not None
        if self.signed:
            self.mav.signing.secret_key = signing_key
            self.mav.signing.sign_outgoing = True
            self.mav.signing.timestamp = signing_timestamp()

    def pack(self, msg: Any) -> bytes:
        if self.signed:
            # timestamps must rise for every signed frame of a link, and never fall behind the wall clock, so a
            # restarted process is not taken for a replay
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


def item_message(item: MissionItem, target_system: int, target_component: int, integer: bool = True) -> Any:
    """The MISSION_ITEM_INT that carries a `MissionItem` verbatim; with integer=False the legacy MISSION_ITEM
    (lat/lon as float degrees) that answers a plain MISSION_REQUEST."""
    x: float  # int (degrees * 1e7) in MISSION_ITEM_INT, float degrees in MISSION_ITEM
    y: float
    if integer:
        message, x, y = mavlink.MAVLink_mission_item_int_message, item.x, item.y
    else:
        message, x, y = mavlink.MAVLink_mission_item_message, item.lat, item.lon
    return message(
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
        x,
        y,
        item.z,
        item.mission_type,
    )


def item_from_message(msg: Any) -> MissionItem:
    """MISSION_ITEM_INT verbatim, or a legacy float MISSION_ITEM converted to the _INT form."""
    if msg.get_type() == "MISSION_ITEM_INT":
        x, y = msg.x, msg.y
    else:
        x = round(msg.x * 1e7) if math.isfinite(msg.x) else _INT32_MAX
        y = round(msg.y * 1e7) if math.isfinite(msg.y) else _INT32_MAX
    return MissionItem(
        seq=msg.seq,
        frame=msg.frame,
        command=msg.command,
        current=msg.current,
        autocontinue=msg.autocontinue,
        param1=msg.param1,
        param2=msg.param2,
        param3=msg.param3,
        param4=msg.param4,
        x=x,
        y=y,
        z=msg.z,
        mission_type=getattr(msg, "mission_type", MissionType.MISSION),
    )


def result_name(enum: str, value: int) -> str:
    """MAV_RESULT / MAV_MISSION_RESULT number -> its name, for messages people read."""
    entry = mavlink.enums.get(enum, {}).get(value)
    return entry.name if entry is not None else f"{enum} {value}"


def param_id(message: Any) -> str:
    """A parameter message's param_id as text (PARAM_VALUE, PARAM_SET, PARAM_REQUEST_READ: pymavlink gives str or
    bytes, NUL-padded)."""
    name = message.param_id
    if isinstance(name, bytes):
        name = name.decode("ascii", errors="replace")
    return name.rstrip("\x00")


def statustext(message: Any) -> str:
    """A STATUSTEXT's text (pymavlink gives str or bytes, NUL-padded)."""
    text = message.text
    if isinstance(text, bytes):
        text = text.decode("utf-8", "replace")
    return text.rstrip("\x00").strip()
