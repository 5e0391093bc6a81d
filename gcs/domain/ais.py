"""The AIS feed in the service's vocabulary, pure: where a feed comes from (`parse_ais_source`) and what the API shows
of it (GET /ais/atons: `AtonsOut`, GET /ais/sources: `AisSourceOut`). The table of AtoNs is gcs.domain.aton_table;
the sockets are gcs.ais.

Names and station names come from the air: they are data, passed as JSON strings and shown as text, never markup.
"""

from __future__ import annotations

from dataclasses import dataclass
from datetime import datetime
from typing import Literal

from pydantic import BaseModel, Field

AisSourceKind = Literal["udp", "tcp"]
AIS_EXAMPLES = "udp://0.0.0.0:10110 (listen for a receiver's datagrams), tcp://HOST:PORT (connect to a shore station)"


class AisSourceError(ValueError):
    """An AIS source this service cannot use (the message says why and shows the forms it takes)."""


@dataclass(frozen=True)
class AisSource:
    """A parsed `--ais` source: listen on UDP host:port, or connect to a TCP server at host:port."""

    kind: AisSourceKind
    host: str
    port: int

    def __str__(self) -> str:
        host = f"[{self.host}]" if ":" in self.host else self.host
        return f"{self.kind}://{host}:{self.port}"


def parse_ais_source(text: str) -> AisSource:
    """`udp://[HOST]:PORT` (HOST defaults to 0.0.0.0, every interface) or `tcp://HOST:PORT`; raises AisSourceError."""

    def fail(why: str) -> AisSourceError:
        return AisSourceError(f"AIS source {text!r}: {why}; expected {AIS_EXAMPLES}")

    scheme, sep, rest = text.strip().partition("://")
    if not sep or scheme.lower() not in ("udp", "tcp"):
        raise fail(f"unknown scheme {scheme!r}" if sep else "no scheme")
    host, colon, port = rest.rpartition(":")
    if not colon or not port.isdigit() or not 0 < int(port) < 65536:
        raise fail("the port must be a number from 1 to 65535")
    host = host.removeprefix("[").removesuffix("]")
    kind: AisSourceKind = "udp" if scheme.lower() == "udp" else "tcp"
    if not host:
        if kind == "tcp":
            raise fail("tcp needs a host to connect to")
        host = "0.0.0.0"
    if any(c in host for c in "/?#@ "):
        raise fail(f"{host!r} is no host name or address")
    return AisSource(kind, host, int(port))


# ----- what the API shows
class AtonOut(BaseModel):
    """One AtoN's latest report (GET /ais/atons), with when and where it was heard."""

    mmsi: int
    name: str = Field(description="the name and its extension as transmitted (text from the air: shown as text)")
    aid_type: int = Field(description="ITU-R M.1371 type of aid to navigation, 0-31")
    aid_type_name: str = Field(description="e.g. port_hand_mark, cardinal_mark_n, safe_water")
    lat: float | None = Field(description="reported latitude, degrees; null: the station has no position")
    lon: float | None
    position_accuracy: bool = Field(description="true: better than 10 m")
    off_position: bool = Field(description="the transmitted off-position flag: a floating aid off its charted position")
    off_position_valid: bool = Field(
        description="the flag counts: a floating aid whose timestamp is a second (ITU-R M.1371); else ignore it"
    )
    virtual: bool = Field(description="a virtual AtoN: nothing physical is at that position")
    second: int = Field(description="UTC second of the position; 60 none, 61 manual, 62 dead reckoning, 63 no fix")
    dimensions_m: tuple[int, int, int, int] = Field(description="to bow, stern, port, starboard of the reference point")
    station: str | None = Field(description="the shore station that relayed it (NMEA 4.10 tag block s:)")
    station_time: datetime | None = Field(description="when that station received it (tag block c:)")
    source: str = Field(description="the feed it came in on (an --ais source)")
    received_at: datetime = Field(description="when this service received it")
    age_s: float = Field(description="seconds since it was received")
    stale: bool = Field(description="older than stale_after_s: its position is not a current one")
    reports: int = Field(description="reports of this AtoN heard since the service started")
    conflict: bool = Field(description="another AtoN reports the same MMSI with another name or position")


class AisConflictOut(BaseModel):
    """An MMSI that more than one AtoN reports (each a row of atons): not merged, shown side by side."""

    mmsi: int
    atons: list[AtonOut]


class AtonsOut(BaseModel):
    """GET /ais/atons."""

    stale_after_s: float = Field(description="a report older than this is stale")
    atons: list[AtonOut] = Field(description="each AtoN's latest report, by MMSI (an MMSI in conflict: each AtoN)")
    conflicts: list[AisConflictOut] = Field(description="MMSIs that several AtoNs report, none of them stale")


class AisCountsOut(BaseModel):
    """What became of a source's lines (uavcore.ais_stream.StreamCounts, plus datagrams the kernel dropped)."""

    lines: int
    decoded: int = Field(description="AtoN reports (message 21) decoded")
    other_type: int = Field(description="well-formed AIS messages of other types (1, 3, 5, ...): not used")
    unknown_type: int = Field(description="message types AIS does not define")
    bad_checksum: int
    malformed: int = Field(description="lines that are no AIS sentence")
    too_long: int
    rate_dropped: int = Field(description="lines beyond the source's rate bound, dropped unparsed")
    parts: int = Field(description="lines that were parts of multi-part messages")
    parts_dropped: int = Field(description="parts of messages never completed")
    kernel_dropped: int = Field(description="UDP datagrams the kernel dropped while reading was paused (Linux)")


class AisSourceOut(BaseModel):
    """One --ais source's state (GET /ais/sources)."""

    url: str
    kind: AisSourceKind
    connected: bool = Field(description="udp: listening; tcp: connected to the server")
    error: str | None = Field(description="why it is not connected, when it is not")
    connections: int = Field(description="tcp: connections made (a reconnect adds one); udp: times bound")
    last_line_at: datetime | None = Field(description="when its last line came")
    last_line_age_s: float | None = Field(description="seconds since; grows while the feed is silent")
    silent: bool = Field(description="no line for stale_after_s (or none yet)")
    counts: AisCountsOut
