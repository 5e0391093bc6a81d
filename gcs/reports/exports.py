"""Mission and flight files (formats: mavlink-conformance.md, "Mission files"). Pure: data in, text out.

- track.geojson: a Feature whose LineString holds the flown [lon, lat, alt].
- QGC .plan (JSON) and QGC WPL 110 `.waypoints` (tab separated, line 0 is home), with readers for both so a
  mission round-trips and can be re-flown by QGroundControl or MAVProxy (`wp load`).
- inspections.csv and inspections.geojson: the per-buoy verdicts and findings (a spreadsheet or a GIS opens them).
- buoys.csv and buoys.geojson: the buoy register's buoys (GET /buoys.csv, /buoys.geojson).
"""

from __future__ import annotations

import csv
import io
import json
import math
from collections.abc import Sequence
from typing import Any

from gcs.domain.register import BuoyOut
from gcs.domain.schemas import FenceZoneIn, InspectionOut
from uavcore.mission import MavCmd, MavFrame, MissionItem

FIRMWARE_PX4 = 12
VEHICLE_QUADROTOR = 2


class MissionFileError(ValueError):
    """A .plan or .waypoints file that cannot be read; the message says where and why."""


def track_geojson(samples: Sequence[dict[str, Any]], properties: dict[str, Any]) -> dict[str, Any]:
    """The flown track as a GeoJSON Feature (samples without a position fix are skipped)."""
    coordinates = [
        [s["lon"], s["lat"], s.get("alt_m") or 0.0]
        for s in samples
        if s.get("lat") is not None and s.get("lon") is not None
    ]
    return {"type": "Feature", "geometry": {"type": "LineString", "coordinates": coordinates}, "properties": properties}


def _has_position(item: MissionItem) -> bool:
    return item.frame != MavFrame.MISSION


def _params(item: MissionItem) -> list[float]:
    lat = item.x * 1e-7 if _has_position(item) else 0.0
    lon = item.y * 1e-7 if _has_position(item) else 0.0
    return [item.param1, item.param2, item.param3, item.param4, lat, lon, item.z]


def _null_nan(value: float) -> float | None:
    return None if math.isnan(value) else value


def qgc_plan(
    items: Sequence[MissionItem],
    home: tuple[float, float, float],
    cruise_speed: float,
    hover_speed: float,
    fence: Sequence[FenceZoneIn] = (),
    rally_points: Sequence[Sequence[float]] = (),
) -> dict[str, Any]:
    """A QGroundControl .plan document (NaN parameters are written as null, as QGC does), with the fence zones
    and rally points ([lat, lon, altitude above home m]) uploaded with the mission, so a plan opened in
    QGroundControl carries what the vehicle was given."""
    return {
        "fileType": "Plan",
        "version": 1,
        "groundStation": "buoy-gcs",
        "mission": {
            "version": 2,
            "firmwareType": FIRMWARE_PX4,
            "vehicleType": VEHICLE_QUADROTOR,
            "cruiseSpeed": cruise_speed,
            "hoverSpeed": hover_speed,
            "plannedHomePosition": list(home),
            "items": [
                {
                    "type": "SimpleItem",
                    "command": item.command,
                    "frame": item.frame,
                    "params": [_null_nan(p) for p in _params(item)],
                    "autoContinue": bool(item.autocontinue),
                    "doJumpId": item.seq + 1,
                }
                for item in items
            ],
        },
        "geoFence": {
            "version": 2,
            "circles": [_qgc_circle(zone) for zone in fence if zone.kind == "circle"],
            "polygons": [_qgc_polygon(zone) for zone in fence if zone.kind == "polygon"],
        },
        "rallyPoints": {"version": 2, "points": [[float(v) for v in point] for point in rally_points]},
    }


def _qgc_circle(zone: FenceZoneIn) -> dict[str, Any]:
    """QGroundControl's fence circle (QGCFenceCircle: version 1, inclusion, circle {center [lat, lon], radius})."""
    assert zone.center is not None and zone.radius_m is not None  # FenceZoneIn's validator: a circle has both
    circle = {"center": [zone.center.lat, zone.center.lon], "radius": zone.radius_m}
    return {"version": 1, "inclusion": zone.inclusion, "circle": circle}


def _qgc_polygon(zone: FenceZoneIn) -> dict[str, Any]:
    """QGroundControl's fence polygon (QGCFencePolygon: version 1, inclusion, polygon [[lat, lon], ...])."""
    assert zone.vertices is not None  # FenceZoneIn's validator: a polygon has its vertices
    return {"version": 1, "inclusion": zone.inclusion, "polygon": [[v.lat, v.lon] for v in zone.vertices]}


def read_qgc_fence_and_rally(text: str) -> tuple[list[FenceZoneIn], list[list[float]]]:
    """The fence zones and rally points of a .plan file (none where it has no geoFence or rallyPoints)."""
    try:
        document = json.loads(text)
        fence = document.get("geoFence") or {}
        zones = [
            FenceZoneIn(kind="circle", inclusion=bool(c["inclusion"]), radius_m=float(c["circle"]["radius"]),
                        center={"lat": c["circle"]["center"][0], "lon": c["circle"]["center"][1]})
            for c in fence.get("circles", [])
        ]  # fmt: skip
        zones += [
            FenceZoneIn(kind="polygon", inclusion=bool(p["inclusion"]),
                        vertices=[{"lat": lat, "lon": lon} for lat, lon in p["polygon"]])
            for p in fence.get("polygons", [])
        ]  # fmt: skip
        points = [[float(v) for v in point] for point in (document.get("rallyPoints") or {}).get("points", [])]
    except (json.JSONDecodeError, KeyError, TypeError, ValueError, IndexError, AttributeError) as error:
        raise MissionFileError(
            f".plan: cannot read the fence or rally points ({type(error).__name__}: {error})"
        ) from None
    if any(len(point) != 3 for point in points):
        raise MissionFileError(".plan: a rally point is [lat, lon, alt]")
    return zones, points


def _item_from_params(seq: int, frame: int, command: int, params: Sequence[float], autocontinue: int) -> MissionItem:
    p1, p2, p3, p4, lat, lon, alt = (math.nan if p is None else float(p) for p in params)
    positioned = frame != MavFrame.MISSION
    return MissionItem(
        seq=seq,
        frame=frame,
        command=command,
        current=1 if seq == 0 else 0,
        autocontinue=autocontinue,
        param1=p1,
        param2=p2,
        param3=p3,
        param4=p4,
        x=round(lat * 1e7) if positioned and math.isfinite(lat) else 0,
        y=round(lon * 1e7) if positioned and math.isfinite(lon) else 0,
        z=alt if math.isfinite(alt) else 0.0,
    )


def read_qgc_plan(text: str) -> tuple[tuple[float, float, float], list[MissionItem]]:
    """Home and mission items of a .plan file (SimpleItems only)."""
    try:
        document = json.loads(text)
        mission = document["mission"]
        home = tuple(float(v) for v in mission["plannedHomePosition"])
        items = [
            _item_from_params(seq, int(raw["frame"]), int(raw["command"]), raw["params"], int(raw["autoContinue"]))
            for seq, raw in enumerate(mission["items"])
        ]
    except (json.JSONDecodeError, KeyError, TypeError, ValueError) as error:
        raise MissionFileError(f".plan: cannot read the mission ({type(error).__name__}: {error})") from None
    if document.get("fileType") != "Plan" or len(home) != 3:
        raise MissionFileError(".plan: fileType must be 'Plan' and plannedHomePosition [lat, lon, alt]")
    return home, items


def _number(value: float) -> str:
    return "nan" if math.isnan(value) else repr(float(value))


def waypoints_text(items: Sequence[MissionItem], home: tuple[float, float, float]) -> str:
    """QGC WPL 110: line 0 is home (MAVProxy sends it as item 0), then the mission items."""
    lines = ["QGC WPL 110"]
    home_line = [0, 1, 0, MavCmd.NAV_WAYPOINT, 0.0, 0.0, 0.0, 0.0, home[0], home[1], home[2], 1]
    lines.append("\t".join(_format(home_line)))
    for item in items:
        p1, p2, p3, p4, lat, lon, alt = _params(item)
        row = [item.seq + 1, 0, item.frame, item.command, p1, p2, p3, p4, lat, lon, alt, item.autocontinue]
        lines.append("\t".join(_format(row)))
    return "\n".join(lines) + "\n"


def _format(row: list) -> list[str]:
    out = []
    for column, value in enumerate(row):
        if column in (8, 9):  # lat, lon: 7 decimals is exactly degE7
            out.append(f"{value:.7f}")
        elif isinstance(value, int):
            out.append(str(value))
        else:
            out.append(_number(value))
    return out


def read_waypoints(text: str) -> tuple[tuple[float, float, float], list[MissionItem]]:
    """Home and mission items of a WPL 110 file; items are renumbered from 0 after the home line."""
    lines = [line for line in text.splitlines() if line.strip()]
    if not lines or not lines[0].startswith("QGC WPL 110"):
        raise MissionFileError(".waypoints: the first line must be 'QGC WPL 110'")
    rows = []
    for number, line in enumerate(lines[1:], start=2):
        fields = line.split("\t")
        if len(fields) != 12:
            raise MissionFileError(f".waypoints line {number}: expected 12 tab-separated fields, got {len(fields)}")
        try:
            rows.append((int(fields[2]), int(fields[3]), [float(f) for f in fields[4:11]], int(fields[11])))
        except ValueError as error:
            raise MissionFileError(f".waypoints line {number}: {error}") from None
    if not rows:
        raise MissionFileError(".waypoints: no home line")
    home_params = rows[0][2]
    home = (home_params[4], home_params[5], home_params[6])
    items = [
        _item_from_params(seq, frame, command, params, auto)
        for seq, (frame, command, params, auto) in enumerate(rows[1:])
    ]
    return home, items


INSPECTION_COLUMNS = ("buoy", "index", "verdict", "findings", "offset_m", "charted_kind", "charted_light",
                      "light_seen", "observed_lat", "observed_lon", "reason", "details")  # fmt: skip


def _cell(value: Any) -> str:
    """A CSV cell that a spreadsheet shows as the text it is: a leading =, +, - or @ would make it a formula."""
    text = "" if value is None else str(value)
    return "'" + text if text[:1] in ("=", "+", "-", "@") and not _is_number(text) else text


def _is_number(text: str) -> bool:
    try:
        float(text)
    except ValueError:
        return False
    return True


def inspections_csv(inspections: Sequence[InspectionOut]) -> str:
    """The findings as CSV, a row per buoy (details: the findings with their figures, as JSON)."""
    out = io.StringIO()
    writer = csv.writer(out, lineterminator="\n")
    writer.writerow(INSPECTION_COLUMNS)
    for i in inspections:
        row = [i.buoy, i.index, i.verdict, ";".join(f["code"] for f in i.findings), i.offset_m, i.charted.kind,
               i.charted.light, i.light_seen, i.observed and i.observed.lat, i.observed and i.observed.lon, i.reason,
               json.dumps(i.findings) if i.findings else ""]  # fmt: skip
        writer.writerow([_cell(value) for value in row])
    return out.getvalue()


def inspections_geojson(inspections: Sequence[InspectionOut], properties: dict[str, Any]) -> dict[str, Any]:
    """The findings as GeoJSON: a Point per buoy where it was observed (else where it is charted)."""
    features = []
    for i in inspections:
        at = i.observed or i.charted
        props = i.model_dump(mode="json", exclude={"observed", "frames"}) | {
            "located": "observed" if i.observed else "charted"
        }
        features.append({"type": "Feature", "geometry": {"type": "Point", "coordinates": [at.lon, at.lat]},
                         "properties": props})  # fmt: skip
    return {"type": "FeatureCollection", "properties": properties, "features": features}


BUOY_COLUMNS = ("id", "name", "lat", "lon", "kind", "light", "swing_radius_m", "mmsi", "source", "last_inspected_at",
                "open_defects", "charted")  # fmt: skip


def buoys_csv(buoys: Sequence[BuoyOut]) -> str:
    """The register's buoys as CSV, a row per buoy (charted: the chart's other attributes, as JSON). Text from
    the chart is formula-safe (_cell)."""
    out = io.StringIO()
    writer = csv.writer(out, lineterminator="\n")
    writer.writerow(BUOY_COLUMNS)
    for buoy in buoys:
        document = buoy.model_dump(mode="json")
        writer.writerow([_cell(json.dumps(document[c]) if c == "charted" else document[c]) for c in BUOY_COLUMNS])
    return out.getvalue()


def buoys_geojson(buoys: Sequence[BuoyOut]) -> dict[str, Any]:
    """The register's buoys as GeoJSON Points at their charted positions, every attribute a property."""
    features = [
        {"type": "Feature", "geometry": {"type": "Point", "coordinates": [b.lon, b.lat]},
         "properties": b.model_dump(mode="json", exclude={"lat", "lon"})}
        for b in buoys
    ]  # fmt: skip
    return {"type": "FeatureCollection", "features": features}
