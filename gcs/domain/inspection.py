"""A buoy's inspection from a burst of frames: where it floats, whether it is on station, what its body and light
show, and the verdict with its evidence. Pure computation: the frames come already analysed (buoy_detection).

Verdict: "not_inspected" when the frames cannot tell (none, none looking where the buoy should be, or its light
unreadable and nothing else wrong), "defect" with at least one finding, else "ok". Findings:
- off_station: the observed position (the median of the frames' waterline geolocations: a few bad frames do not
  move it) farther from the charted one than the swing radius plus POSITION_TOLERANCE_M;
- light_out, wrong_character, wrong_period, wrong_colour: uavcore.light_character.matches of the charted light
  against the burst's reading (light_reading.read_light);
- wrong_body_colour: the bands most frames show differ from the kind's in its IALA region (buoy_world.appearance);
- not_found: the search area was in view but the buoy was in none of the frames.

A fleet mission stores no record of its own: each part stores its buoys' records, and `gather_fleet_inspections`
gathers them by the fleet's input index (what the API lists and the fleet report shows).
"""

from __future__ import annotations

import math
from collections import Counter
from collections.abc import Iterable, Sequence
from typing import Any, NamedTuple

import numpy as np
from pydantic import BaseModel, ConfigDict

from gcs.domain.aton_table import distance_m
from gcs.domain.buoy_detection import BuoyDetection, ChartedBuoy
from gcs.domain.camera_geometry import FrameGeotag
from gcs.domain.light_reading import read_light
from gcs.domain.planning import Plan
from uavcore.buoy_world import appearance
from uavcore.geodesy import LocalFrame
from uavcore.light_character import ObservedLight, longest_phases, matches, parse

# The station's position error budget: the waterline's geolocation (~0.2 m RMS in the benchmark) plus the
# camera's GNSS and attitude errors. A buoy this far beyond its swing circle is reported off station.
POSITION_TOLERANCE_M = 1.5
LIGHT_FINDINGS = ("light_out", "wrong_character", "wrong_period", "wrong_colour")


class Finding(BaseModel):
    """One defect: its code and its figures (extra fields, e.g. offset_m and swing_radius_m for off_station)."""

    model_config = ConfigDict(frozen=True, extra="allow")
    code: str


class LatLon(BaseModel):
    model_config = ConfigDict(frozen=True)
    lat: float
    lon: float


class InspectedBuoy(BaseModel):
    """The buoy as charted."""

    model_config = ConfigDict(frozen=True)
    lat: float
    lon: float
    kind: str
    light: str | None
    swing_radius_m: float
    region: str = "A"  # the IALA region its colours are checked in


class BuoyInspection(BaseModel):
    """The inspection's result: verdict, findings and what was observed; frames: the image indices the buoy was
    found in; reason: why it was not inspected (None otherwise)."""

    model_config = ConfigDict(frozen=True)
    buoy: InspectedBuoy
    verdict: str  # "ok" | "defect" | "not_inspected"
    findings: list[Finding]
    observed: LatLon | None
    offset_m: float | None
    light_seen: str | None
    frames: list[int]
    reason: str | None = None
    # when the mission looked for the buoy elsewhere than its charted position (its latest AIS report): that
    # position and the observed position's distance from it
    target: LatLon | None = None
    offset_from_target_m: float | None = None


def against_target(result: BuoyInspection, target: Sequence[float]) -> BuoyInspection:
    """The inspection with the position the mission looked for the buoy at, and the observed one's distance from it
    (the station is judged against the chart either way)."""
    at, seen = LatLon(lat=target[0], lon=target[1]), result.observed
    offset = None if seen is None else round(distance_m((at.lat, at.lon), (seen.lat, seen.lon)), 2)
    return result.model_copy(update={"target": at, "offset_from_target_m": offset})


def describe_light(observed: ObservedLight) -> str:
    """A reading as text: "dark", "fixed W", "flashing .. W 5.0s" (pattern: "." short, "-" long flashes)."""
    if observed.rhythm in ("dark", "unreadable"):
        return observed.rhythm
    parts = [observed.rhythm, observed.pattern, "".join(observed.colours) or "?"]
    if observed.period_s is not None:
        parts.append(f"{observed.period_s:.1f}s")
    return " ".join(p for p in parts if p)


def _median_position(charted: ChartedBuoy, positions: Sequence[tuple[float, float]]) -> tuple[LatLon, float, float]:
    """The per-axis median of the positions (metres on the charted position's tangent plane), its distance and
    bearing (deg) from the charted position."""
    frame = LocalFrame(charted.lat, charted.lon)
    east, north = np.median(frame.project(np.array(positions)), axis=0)
    lat, lon = frame.unproject(np.array([[east, north]]))[0]
    bearing = math.degrees(math.atan2(east, north)) % 360.0
    return LatLon(lat=float(lat), lon=float(lon)), float(math.hypot(east, north)), bearing


def _light_findings(charted: ChartedBuoy, observed: ObservedLight) -> list[Finding]:
    """Findings of the light (LIGHT_FINDINGS); "unreadable" among them when the burst could not be read."""
    if charted.light is None:
        return []
    character = parse(charted.light)
    seen = describe_light(observed)
    if observed.rhythm == "unreadable" and observed.longest_dark_s is not None:
        # too short a burst for this light's rhythm: what it did show (matches() judges by it)
        dark, lit = longest_phases(character)
        seen = (
            f"dark up to {observed.longest_dark_s:.1f} s and lit up to {observed.longest_lit_s or 0.0:.1f} s at a "
            f"stretch (the chart's longest: {dark:.1f} s dark, {lit:.1f} s lit)"
        )
    findings = []
    for code in matches(character, observed):
        figures: dict[str, float | str | None] = {"charted": character.abbreviation(), "seen": seen}
        if code == "wrong_period":
            figures |= {"charted_period_s": character.period_s, "seen_period_s": observed.period_s}
        findings.append(Finding(code=code, **figures))
    return findings


def _body_findings(charted: ChartedBuoy, detections: Sequence[BuoyDetection]) -> list[Finding]:
    """wrong_body_colour when the bands most frames show are not the kind's (as a set for vertical stripes)."""
    look = appearance(charted.kind, charted.region)
    seen_counts = Counter(d.colours for d in detections if d.colours)
    if not seen_counts:
        return []
    seen = seen_counts.most_common(1)[0][0]
    same = set(seen) == set(look.colours) if look.pattern == "vertical" else seen == look.colours
    return [] if same else [Finding(code="wrong_body_colour", expected=list(look.colours), seen=list(seen))]


def inspect_buoy(
    charted: ChartedBuoy | tuple[float, float, str, str | None, float],
    frames: Sequence[tuple[FrameGeotag, BuoyDetection]],
) -> BuoyInspection:
    """The inspection of one buoy from its burst: (geotag, detection) per frame, in any order."""
    buoy = ChartedBuoy(*charted)
    record = InspectedBuoy(**buoy._asdict())

    def result(verdict: str, findings: list[Finding], reason: str | None = None, **seen: Any) -> BuoyInspection:
        fields: dict[str, Any] = {"observed": None, "offset_m": None, "light_seen": None, "frames": []} | seen
        return BuoyInspection(buoy=record, verdict=verdict, findings=findings, reason=reason, **fields)

    if not frames:
        return result("not_inspected", [], "no frames")
    found = sorted(((g, d) for g, d in frames if d.found), key=lambda frame: frame[0].t_s)
    if not found:
        reasons = Counter(d.why.split(":")[0] for _, d in frames)
        if set(reasons) == {"out_of_view"}:
            return result("not_inspected", [], f"the buoy's search area was in none of the {len(frames)} frames")
        not_found = Finding(code="not_found", frames=len(frames), why=reasons.most_common(1)[0][0])
        return result("defect", [not_found])
    findings: list[Finding] = []
    # a body cut by the frame's side is placed less well: its frames count only when no whole one was seen
    whole = [d.position for _, d in found if d.position is not None and not d.cut]
    positions = whole or [d.position for _, d in found if d.position is not None]
    observed = offset = None
    if positions:
        observed, offset, bearing = _median_position(buoy, positions)
        if offset > buoy.swing_radius_m + POSITION_TOLERANCE_M:
            figures = {
                "offset_m": round(offset, 2),
                "swing_radius_m": buoy.swing_radius_m,
                "bearing_deg": round(bearing),
            }
            findings.append(Finding(code="off_station", **figures))
    spotted = [(g.t_s, d.light) for g, d in found if d.light is not None]
    light = read_light([t for t, _ in spotted], [s for _, s in spotted if s is not None])
    light_findings = _light_findings(buoy, light)
    findings += [f for f in light_findings if f.code != "unreadable"] + _body_findings(buoy, [d for _, d in found])
    seen: dict[str, Any] = {
        "observed": observed,
        "offset_m": None if offset is None else round(offset, 2),
        "light_seen": describe_light(light),
        "frames": [g.image_index for g, _ in found],
    }
    if findings:
        return result("defect", findings, **seen)
    if light_findings or not positions:  # only "unreadable" is left among them
        why = "its light could not be read" if light_findings else "its waterline was in no frame (cut by the edge)"
        return result("not_inspected", [], f"found in {len(found)} frames, but {why}", **seen)
    return result("ok", [], **seen)


class StoredFrame(BaseModel):
    """A camera frame as stored beside its bytes: the buoy it was taken for (input index), what the camera said
    of it (geotag, file URL) and what was found in it. `id` is the storage's (None before it is stored)."""

    model_config = ConfigDict(frozen=True)
    id: int | None = None
    buoy: int
    image_index: int
    t_s: float
    lat: float
    lon: float
    height_m: float
    q: tuple[float, float, float, float]
    file_url: str
    found: bool = False
    light_on: bool | None = None
    note: str = ""  # why the buoy was not found in it, or what failed


class InspectionRecord(BaseModel):
    """One buoy's inspection as the mission stores it: which buoy (input index and id), the result, and the
    frames (storage ids, capture order) of its burst, the best one first among those the buoy was found in."""

    model_config = ConfigDict(frozen=True)
    buoy: int
    buoy_id: str
    result: BuoyInspection
    frame_ids: list[int] = []
    best_frame: int | None = None


class HeldInspection(NamedTuple):
    """A record and the mission holding its frames (for a fleet mission's record: its part's)."""

    mission_id: int
    record: InspectionRecord


def gather_fleet_inspections(
    plan: Plan, parts: Iterable[tuple[int, Plan, Sequence[InspectionRecord]]]
) -> list[HeldInspection]:
    """A fleet mission's records from its parts ((part mission id, part plan, its records) each), re-indexed to the
    fleet plan's input indices, in that order. A part's record is buoy `buoy` of its own plan: it is found in the
    fleet's by id and position (ids need not be unique). A buoy re-shared in flight has a record in several parts:
    one whose verdict is not not_inspected (the vehicle that inspected it) wins over the lost vehicle's."""
    index_of = {
        (buoy_id, tuple(at)): i for i, (buoy_id, at) in enumerate(zip(plan.buoy_ids, plan.buoys_lat_lon, strict=True))
    }
    found: dict[int, HeldInspection] = {}
    for part_id, part_plan, records in parts:
        for record in records:
            index = index_of.get((record.buoy_id, tuple(part_plan.buoys_lat_lon[record.buoy])))
            if index is not None and (index not in found or found[index].record.result.verdict == "not_inspected"):
                found[index] = HeldInspection(part_id, record.model_copy(update={"buoy": index}))
    return [found[i] for i in sorted(found)]
