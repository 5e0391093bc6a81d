"""AIS Aid-to-Navigation reports (ITU-R M.1371 message 21): what one says, and the NMEA 0183 sentences that carry it.
Pure computation; pyais does the bit-level work (the 6-bit armour, the fields), this module only names the result.

An AtoN station (a buoy carrying a transponder, or a shore station reporting for it: a "synthetic" AtoN) broadcasts
message 21 every 3 minutes (IALA A-126): its MMSI, name (20 characters, up to 14 more in the name extension), type
(IALA kind: port hand mark, north cardinal, ...), position, the off-position flag (a floating aid that left its
charted position) and the virtual flag (a "virtual AtoN": a mark that exists only in AIS, nothing is in the water).
The line-level handling (multi-part assembly, checksums, counts, the rate bound) is `uavcore.ais_stream`.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from pyais import encode_dict
from pyais.constants import NavAid
from pyais.messages import MessageType21

ATON_MESSAGE_TYPE = 21
REPORT_INTERVAL_S = 180.0  # IALA A-126: an AtoN reports every 3 minutes
NAME_CHARS, NAME_EXTENSION_CHARS = 20, 14  # 120 bits and up to 88 bits of 6-bit characters
# The characters AIS text can carry (ITU-R M.1371 Table 47): upper case, digits and some signs; "@" pads
SIX_BIT_CHARACTERS = "@ABCDEFGHIJKLMNOPQRSTUVWXYZ[\\]^_ !\"#$%&'()*+,-./0123456789:;<=>?"
POSITION_NOT_AVAILABLE = (91.0, 181.0)  # (lat, lon) as transmitted when the station has no fix
# A 6-bit timestamp's values above 59 say why there is no second: 60 not available, 61 manual input, 62 dead
# reckoning, 63 positioning system inoperative
TIMESTAMP_NOT_AVAILABLE = 60
FLOATING_AID_TYPES = range(20, 32)  # 20-31: the floating marks (cardinals, lateral, ..., light vessel / LANBY)
# The 5-bit "type of aid to navigation", by pyais's names in lower case ("port_hand_mark", "cardinal_mark_n", ...)
AID_TYPE_NAMES: dict[int, str] = {aid.value: aid.name.lower() for aid in NavAid if aid.value < 32}
# What a floating buoy of each of uavcore.buoy_world's kinds reports as its type
AID_TYPE_OF_KIND: dict[str, int] = {
    kind: aid.value
    for kind, aid in {
        "north": NavAid.CARDINAL_MARK_N,
        "east": NavAid.CARDINAL_MARK_E,
        "south": NavAid.CARDINAL_MARK_S,
        "west": NavAid.CARDINAL_MARK_W,
        "port": NavAid.PORT_HAND_MARK,
        "starboard": NavAid.STARBOARD_HAND_MARK,
        "isolated_danger": NavAid.ISOLATED_DANGER,
        "safe_water": NavAid.SAFE_WATER,
        "special": NavAid.SPECIAL_MARK,
    }.items()
}


@dataclass(frozen=True)
class AtonReport:
    """One message 21 as decoded. Text fields are data from the air: shown as text, never as markup."""

    mmsi: int
    name: str  # the name and its extension, joined, without the "@" padding and trailing blanks
    aid_type: int  # 0-31, AID_TYPE_NAMES
    lat: float | None  # degrees; None when the station says it has no position (91, 181)
    lon: float | None
    position_accuracy: bool  # True: better than 10 m (DGNSS)
    off_position: bool  # as transmitted; meaningful only where off_position_valid
    virtual: bool  # a virtual AtoN: nothing physical at that position
    second: int  # UTC second of the position (0-59), or 60-63 (TIMESTAMP_NOT_AVAILABLE and beyond)
    dimensions_m: tuple[int, int, int, int] = (0, 0, 0, 0)  # to bow, stern, port, starboard of the reference point
    epfd: int = 0  # the position fixing device (1 GPS, 7 surveyed, ...)
    raim: bool = False
    assigned: bool = False  # assigned mode (a competent authority set it), else autonomous
    station_time: float | None = None  # unix seconds a shore station received it (NMEA 4.10 tag block "c:")
    station: str | None = None  # the shore station's name (tag block "s:")

    @property
    def aid_type_name(self) -> str:
        return AID_TYPE_NAMES.get(self.aid_type, f"type_{self.aid_type}")

    @property
    def floating(self) -> bool:
        return self.aid_type in FLOATING_AID_TYPES

    @property
    def off_position_valid(self) -> bool:
        """ITU-R M.1371: the off-position flag counts only for a floating aid whose timestamp is a second (<= 59)."""
        return self.floating and self.second < TIMESTAMP_NOT_AVAILABLE

    @classmethod
    def from_message(
        cls, msg: MessageType21, station_time: float | None = None, station: str | None = None
    ) -> AtonReport:
        """The report a pyais message 21 carries; ValueError when a required field is missing (a truncated payload)."""
        if msg.mmsi is None or msg.aid_type is None or msg.lat is None or msg.lon is None or msg.second is None:
            raise ValueError("message 21 truncated: no MMSI, type, position or timestamp")
        has_position = abs(msg.lat) <= 90 and abs(msg.lon) <= 180
        # an extension follows a full name (20 characters): pyais strips the name's trailing blanks, put them back
        name = (msg.name or "").ljust(NAME_CHARS) + msg.name_ext if msg.name_ext else msg.name or ""
        return cls(
            mmsi=int(msg.mmsi),
            name=name.rstrip("@ ").strip(),
            aid_type=int(msg.aid_type),
            lat=float(msg.lat) if has_position else None,
            lon=float(msg.lon) if has_position else None,
            position_accuracy=bool(msg.accuracy),
            off_position=bool(msg.off_position),
            virtual=bool(msg.virtual_aid),
            second=int(msg.second),
            dimensions_m=(msg.to_bow or 0, msg.to_stern or 0, msg.to_port or 0, msg.to_starboard or 0),
            epfd=int(msg.epfd or 0),
            raim=bool(msg.raim),
            assigned=bool(msg.assigned),
            station_time=station_time,
            station=station,
        )


def ais_text(text: str, length: int = NAME_CHARS + NAME_EXTENSION_CHARS) -> str:
    """text as AIS can carry it: upper case, characters outside SIX_BIT_CHARACTERS as "?", at most length of them."""
    return "".join(c if c in SIX_BIT_CHARACTERS[1:] else "?" for c in text.upper()[:length])


def encode_aton_report(report: AtonReport, channel: str = "A", talker: str = "AI", sentence: str = "VDM") -> list[str]:
    """The NMEA 0183 sentences (without line ends) of a report, as an AtoN station's or a receiver's output (VDM;
    "VDO" is a station's own). One sentence: message 21 is at most 360 bits, 60 armoured characters."""
    name = ais_text(report.name)
    lat, lon = POSITION_NOT_AVAILABLE if report.lat is None or report.lon is None else (report.lat, report.lon)
    bow, stern, port, starboard = report.dimensions_m
    fields: dict[str, Any] = {
        "msg_type": ATON_MESSAGE_TYPE,
        "mmsi": report.mmsi,
        "aid_type": report.aid_type,
        "name": name[:NAME_CHARS],
        # no extension: left out, so the message is the 272 bits a short name takes, not 360 with "@" padding
        "name_ext": name[NAME_CHARS:] or None,
        "accuracy": report.position_accuracy,
        "lat": lat,
        "lon": lon,
        "to_bow": bow,
        "to_stern": stern,
        "to_port": port,
        "to_starboard": starboard,
        "epfd": report.epfd,
        "second": report.second,
        "off_position": report.off_position,
        "raim": report.raim,
        "virtual_aid": report.virtual,
        "assigned": report.assigned,
    }
    return encode_dict(fields, talker_id=talker, sentence_type=sentence, radio_channel=channel)
