"""The buoy register's vocabulary, pure: a register buoy from a charted mark, an import's duplicates, the defects an
inspection record opens, the off-station alarms, which AIS AtoN is which register buoy, where a mission should look
for a buoy, and the documents the /buoys routes answer with.

A register buoy is known by its register id: the chart's LNAM (stable across the cell's editions), or the id a
request gave. Its history is a list of events (registered, charted attributes changed, inspected, a defect opened,
a defect's state set by an operator with a note). A defect is one finding code of an inspection whose verdict was
"defect"; while one of that code is not closed, a new inspection finding the same adds evidence, not a defect.

An AtoN of the AIS feed is a register buoy's by the buoy's MMSI (set by an operator, PATCH /buoys/{id}); a buoy with
no MMSI takes the AtoN that has its name and is within NAME_MATCH_M of its charted position, when exactly one does
and no other buoy claims it (two candidates either way: reported, not guessed). A mission looks for a buoy at its
latest AIS position while that report is current (not stale, not virtual), else at its charted position; the
inspection still judges the station against the chart.
"""

from __future__ import annotations

from collections import Counter
from collections.abc import Sequence
from dataclasses import dataclass, field
from datetime import datetime
from typing import Any, Literal

from pydantic import BaseModel, Field

from gcs.domain.aton_table import distance_m, same_name
from gcs.domain.charted_marks import ChartedMark, ChartImport
from gcs.domain.inspection import Finding, InspectionRecord
from gcs.domain.schemas import Strict
from uavcore.buoy_world import DEFAULT_SWING_RADIUS_M

DefectState = Literal["open", "confirmed", "closed"]
UNCLOSED: tuple[DefectState, ...] = ("open", "confirmed")
EventKind = Literal["registered", "charted", "inspection", "defect_opened", "defect_state"]
# ITU-R M.1371's position accuracy flag: set, the fix is better than 10 m (DGNSS: a metre or two); clear, worse than
# 10 m. A reported position counts as off station only beyond the swing circle by more than this.
AIS_TOLERANCE_M = {True: 2.0, False: 10.0}
CHARTED_FIELDS = ("name", "lat", "lon", "kind", "light", "swing_radius_m", "charted")  # what an import may change
# A buoy with no MMSI is matched to the AtoN of its name within this of its charted position: a nautical mile, wide
# enough for a buoy dragged off station (what the authority wants found), narrow enough that a harbour's "No 1"
# does not match the next harbour's.
NAME_MATCH_M = 1852.0


@dataclass(frozen=True)
class RegisterBuoy:
    """A buoy as the register stores it: identity, charted position and attributes, and where they came from."""

    id: str
    lat: float
    lon: float
    name: str | None = None
    kind: str | None = None
    light: str | None = None
    swing_radius_m: float = DEFAULT_SWING_RADIUS_M
    charted: dict[str, Any] = field(default_factory=dict)  # object class, shape, colours, region, beacon, ...
    source: str = "request"  # "US4MD81M edition 12 update 3", or "request"

    def changes_from(self, stored: RegisterBuoy) -> dict[str, list[Any]]:
        """The charted fields that differ from `stored`'s: field -> [stored value, this value]."""
        return {
            name: [getattr(stored, name), getattr(self, name)]
            for name in CHARTED_FIELDS
            if getattr(stored, name) != getattr(self, name)
        }


@dataclass(frozen=True)
class StoredBuoy:
    """A register buoy as read back: with its MMSI, times, last inspection and open defects count."""

    buoy: RegisterBuoy
    mmsi: int | None
    created_at: str
    updated_at: str
    last_inspected_at: str | None  # the latest inspection whose verdict was ok or defect
    unclosed_defects: int


@dataclass(frozen=True)
class BuoyEvent:
    id: int
    buoy_id: str
    at: str
    kind: EventKind
    mission_id: int | None = None
    defect_id: int | None = None
    verdict: str | None = None
    detail: dict[str, Any] = field(default_factory=dict)
    note: str | None = None


@dataclass(frozen=True)
class Defect:
    id: int
    buoy_id: str
    code: str
    state: DefectState
    mission_id: int
    finding: dict[str, Any]
    opened_at: str
    updated_at: str
    note: str | None = None


@dataclass(frozen=True)
class BuoyFilter:
    """GET /buoys' filters (None: not filtered on)."""

    bbox: tuple[float, float, float, float] | None = None  # west, south, east, north
    kind: str | None = None
    inspected_before: str | None = None  # overdue: not inspected since this ISO time (or never)
    open_defects: bool | None = None


def chart_source(chart: ChartImport) -> str:
    cell = chart.cell
    parts = [cell.name] + [f"{word} {value}" for word, value in (("edition", cell.edition), ("update", cell.update))
                           if value is not None]  # fmt: skip
    return " ".join(parts)


def from_mark(mark: ChartedMark, source: str) -> RegisterBuoy:
    """A charted mark as a register buoy: a beacon stands fixed, a buoy takes the missions' default swing radius
    (the chart gives no mooring)."""
    described = mark.as_dict()
    charted = {name: described[name] for name in ("object_class", "beacon", "preferred_channel", "shape", "colours",
                                                  "colour_pattern", "region", "other_lights")}  # fmt: skip
    radius = DEFAULT_SWING_RADIUS_M if mark.swing_radius_m is None else mark.swing_radius_m
    return RegisterBuoy(mark.id, mark.lat, mark.lon, mark.name, mark.kind, mark.light, radius, charted, source)


def without_duplicates(buoys: Sequence[RegisterBuoy]) -> tuple[list[RegisterBuoy], list[str]]:
    """The buoys whose id is the only one of its kind in the import, and what is reported: an id given several
    times (none of them registered: which would be the buoy?) and a name several buoys share (each registered
    under its own id: the names are reported, never merged)."""
    ids = Counter(b.id for b in buoys)
    names = Counter(b.name for b in buoys if b.name)
    reports = [f"id {i!r} is given {n} times in this import: none of them registered" for i, n in ids.items() if n > 1]
    reports += [
        f"name {name!r} is shared by {n} buoys: each kept under its own id" for name, n in names.items() if n > 1
    ]
    return [b for b in buoys if ids[b.id] == 1], reports


def defect_findings(record: InspectionRecord) -> dict[str, Finding]:
    """The findings of a record that open defects, one per code (the first of a code when several share it)."""
    if record.result.verdict != "defect":
        return {}
    found: dict[str, Finding] = {}
    for finding in record.result.findings:
        found.setdefault(finding.code, finding)
    return found


# ----- AIS AtoNs as register buoys
@dataclass(frozen=True)
class AisMatch:
    """The AtoN report (an AtonOut document) a register buoy is matched to, and how: "mmsi" or "name"."""

    aton: dict[str, Any]
    by: Literal["mmsi", "name"]


def match_atons(
    buoys: Sequence[StoredBuoy], atons: Sequence[dict[str, Any]]
) -> tuple[dict[str, AisMatch], dict[str, str]]:
    """Each register buoy's AtoN, and why a buoy has none for being ambiguous (both by register id). By MMSI: the buoy's
    MMSI's report (the first when several AtoNs share it: the feed reports that conflict). By name and distance,
    for a buoy with no MMSI: the one AtoN of its name within NAME_MATCH_M whose MMSI no register buoy has and no
    other buoy matches by name."""
    by_mmsi: dict[int, list[dict[str, Any]]] = {}
    for aton in atons:
        by_mmsi.setdefault(aton["mmsi"], []).append(aton)
    matches = {b.buoy.id: AisMatch(by_mmsi[b.mmsi][0], "mmsi") for b in buoys if b.mmsi in by_mmsi}
    claimed = {b.mmsi for b in buoys if b.mmsi is not None}
    candidates: dict[str, list[dict[str, Any]]] = {}
    for stored in buoys:
        buoy = stored.buoy
        if stored.mmsi is not None or not buoy.name:
            continue
        candidates[buoy.id] = [
            aton for aton in atons
            if aton["mmsi"] not in claimed and aton["lat"] is not None and same_name(aton["name"], buoy.name)
            and distance_m((buoy.lat, buoy.lon), (aton["lat"], aton["lon"])) <= NAME_MATCH_M
        ]  # fmt: skip
    wanted = Counter(aton["mmsi"] for found in candidates.values() for aton in found)
    ambiguous = {}
    for buoy_id, found in candidates.items():
        if len(found) == 1 and wanted[found[0]["mmsi"]] == 1:
            matches[buoy_id] = AisMatch(found[0], "name")
        elif len(found) > 1:
            mmsis = ", ".join(sorted(str(aton["mmsi"]) for aton in found))
            ambiguous[buoy_id] = f"{len(found)} AtoNs of its name within {NAME_MATCH_M:g} m ({mmsis}): set its MMSI"
        elif found:
            ambiguous[buoy_id] = (f"the AtoN of its name within {NAME_MATCH_M:g} m ({found[0]['mmsi']}) has another "
                                  "buoy's name too: set its MMSI")  # fmt: skip
    return matches, ambiguous


def current_report(match: AisMatch | None) -> dict[str, Any] | None:
    """The matched AtoN report when it gives a current position of a physical buoy (not stale, not virtual)."""
    if match is None:
        return None
    aton = match.aton
    return None if aton["stale"] or aton["virtual"] or aton["lat"] is None or aton["lon"] is None else aton


# ----- the documents
class DefectOut(BaseModel):
    id: int
    code: str = Field(description="the finding's code: off_station, light_out, wrong_character, ...")
    state: DefectState
    mission_id: int = Field(description="the mission whose inspection found it")
    finding: dict[str, Any] = Field(description="the finding with its figures, as the inspection recorded it")
    opened_at: str
    updated_at: str
    note: str | None = Field(description="the operator's note with the latest change of state")


class BuoyEventOut(BaseModel):
    id: int
    at: str
    kind: EventKind
    mission_id: int | None
    defect_id: int | None
    verdict: str | None = Field(description="an inspection's verdict: ok, defect, not_inspected")
    detail: dict[str, Any] = Field(description="an inspection's record, the changed charted fields, a defect's state")
    note: str | None


class BuoyOut(BaseModel):
    """A register buoy: charted attributes (text from the chart is data, shown as text) and its state."""

    id: str = Field(description="register id: the chart's LNAM, or the id given")
    name: str | None
    lat: float = Field(description="charted")
    lon: float
    kind: str | None
    light: str | None
    swing_radius_m: float
    charted: dict[str, Any] = Field(description="object class, beacon, shape, colours, colour pattern, region, ...")
    mmsi: int | None
    source: str = Field(description="the chart cell (name, edition, update) it came from, or 'request'")
    created_at: str
    updated_at: str
    last_inspected_at: str | None = Field(description="the latest inspection with a verdict (ok or defect)")
    open_defects: int = Field(description="defects open or confirmed")


class BuoyDetailOut(BuoyOut):
    latest_inspection: BuoyEventOut | None
    defects: list[DefectOut] = Field(description="open and confirmed defects")
    history: list[BuoyEventOut] = Field(description="every event, oldest first")
    ais: dict[str, Any] | None = Field(
        description="the AIS feed's latest report of its AtoN (GET /ais/atons' row): by its MMSI, else by its name "
        "within a nautical mile of its charted position"
    )
    ais_match: Literal["mmsi", "name"] | None = Field(description="how `ais` was matched to this buoy")
    ais_unmatched: str | None = Field(
        default=None, description="why no AtoN is matched though some transmit its name (ambiguous: never guessed)"
    )


class RegisterImportOut(BaseModel):
    source: str
    created: list[str] = Field(description="register ids new to the register")
    updated: list[str] = Field(description="register ids whose charted attributes changed (history kept)")
    unchanged: int
    duplicates: list[str] = Field(description="ids and names given more than once in the import: not merged")
    warnings: list[str] = Field(description="the chart's own warnings (gcs.charts)")


class DefectPatchIn(Strict):
    state: Literal["confirmed", "closed"]
    note: str = Field(min_length=1, max_length=2000, description="why: what the operator saw or did")


class BuoyPatchIn(Strict):
    mmsi: int | None = Field(ge=100_000_000, le=999_999_999, description="its AIS transmitter's MMSI (null: none)")


class AlarmOut(BaseModel):
    """An off-station alarm with its evidence."""

    buoy: str
    name: str | None
    source: Literal["inspection", "ais"]
    distance_m: float | None = Field(description="from the charted position")
    swing_radius_m: float
    at: str = Field(description="when the evidence was recorded or received")
    mission_id: int | None = Field(description="the inspection's mission (source inspection)")
    defect_id: int | None = Field(description="the off_station defect the inspection opened (closing it ends it)")
    ais: dict[str, Any] | None = Field(description="the AtoN report (source ais)")
    why: str


def buoy_out(stored: StoredBuoy) -> BuoyOut:
    b = stored.buoy
    return BuoyOut(id=b.id, name=b.name, lat=b.lat, lon=b.lon, kind=b.kind, light=b.light,
                   swing_radius_m=b.swing_radius_m, charted=b.charted, mmsi=stored.mmsi, source=b.source,
                   created_at=stored.created_at, updated_at=stored.updated_at,
                   last_inspected_at=stored.last_inspected_at, open_defects=stored.unclosed_defects)  # fmt: skip


def event_out(event: BuoyEvent) -> BuoyEventOut:
    return BuoyEventOut(id=event.id, at=event.at, kind=event.kind, mission_id=event.mission_id,
                        defect_id=event.defect_id, verdict=event.verdict, detail=event.detail,
                        note=event.note)  # fmt: skip


def defect_out(defect: Defect) -> DefectOut:
    return DefectOut(id=defect.id, code=defect.code, state=defect.state, mission_id=defect.mission_id,
                     finding=defect.finding, opened_at=defect.opened_at, updated_at=defect.updated_at,
                     note=defect.note)  # fmt: skip


def inspection_alarm(stored: StoredBuoy, defect: Defect) -> AlarmOut:
    """An unclosed off_station defect as an alarm: the inspection saw the buoy outside its swing circle."""
    offset = defect.finding.get("offset_m")
    return AlarmOut(buoy=stored.buoy.id, name=stored.buoy.name, source="inspection",
                    distance_m=offset if isinstance(offset, int | float) else None,
                    swing_radius_m=stored.buoy.swing_radius_m, at=defect.opened_at, mission_id=defect.mission_id,
                    defect_id=defect.id, ais=None,
                    why=f"mission {defect.mission_id}'s inspection saw it off station ({defect.state})")  # fmt: skip


def ais_alarm(stored: StoredBuoy, aton: dict[str, Any], distance_m: float | None) -> AlarmOut | None:
    """An alarm from the AtoN report of the buoy's MMSI (an AtonOut document), or None: the transmitted
    off-position flag (where it counts), or a reported position outside the swing circle by more than the fix's
    accuracy. A stale report raises none: it is no current position."""
    if aton["stale"] or aton["virtual"]:
        return None
    whys = []
    if aton["off_position"] and aton["off_position_valid"]:
        whys.append("the AtoN reports itself off position")
    limit = stored.buoy.swing_radius_m + AIS_TOLERANCE_M[bool(aton["position_accuracy"])]
    if distance_m is not None and distance_m > limit:
        whys.append(f"its reported position is {distance_m:.1f} m from the charted one (swing circle and fix: "
                    f"{limit:.1f} m)")  # fmt: skip
    if not whys:
        return None
    received = aton["received_at"]
    at = received.isoformat() if isinstance(received, datetime) else str(received)
    return AlarmOut(buoy=stored.buoy.id, name=stored.buoy.name, source="ais",
                    distance_m=None if distance_m is None else round(distance_m, 2),
                    swing_radius_m=stored.buoy.swing_radius_m, at=at, mission_id=None, defect_id=None, ais=aton,
                    why="; ".join(whys))  # fmt: skip
