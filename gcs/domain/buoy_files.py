"""Buoys from files: GeoJSON (FeatureCollection of Points) or CSV. Pure: text in, buoys out.

GeoJSON: a feature's properties `id` (or `name`), and the charted `kind`, `light`, `swing_radius_m` and `region` (the
contract of a uavcore.buoy_world world file, whose fault properties are left out).

CSV: with a header, the columns named lat/latitude, lon/lng/longitude and optionally id/name are used, in any
order; without a header every row is `lat,lon` (the planner CLI's format) with an optional third column id.

Either may mark one point as the depot, as the planner CLI reads them (planner.formats): a feature's property
`role: "depot"`, or a CSV column `role` saying depot; `role: "buoy"` or none is a buoy, any other role an error (a
point silently taken as a buoy would be flown to). Unlike the planner CLI, a file without a depot has none (the
request's, or the vehicle's home, is used): the first point is a buoy.
"""

from __future__ import annotations

import csv
import io
import json
import math
from collections.abc import Callable
from dataclasses import dataclass, field, replace
from typing import Any

from uavcore.geodesy import CoordinateError, check_lat_lon


class BuoyFileError(ValueError):
    """The file or document cannot be read as buoys; the message names the place and the reason."""


CHARTED_PROPERTIES = ("kind", "light", "swing_radius_m", "region")  # a GeoJSON feature's, passed on as they are


@dataclass(frozen=True)
class ImportedBuoy:
    lat: float
    lon: float
    id: str | None = None
    charted: dict[str, Any] = field(default_factory=dict)  # CHARTED_PROPERTIES the file gives, checked by the request

    def as_dict(self) -> dict[str, Any]:
        return {"id": self.id, "lat": self.lat, "lon": self.lon} | self.charted


@dataclass(frozen=True)
class BuoyFile:
    buoys: list[ImportedBuoy]
    depot: tuple[float, float] | None = None  # (lat, lon) of the point whose role is depot, if one is

    def depot_as_dict(self) -> dict[str, float] | None:
        """The depot as a request or an answer gives it, {lat, lon} (None: the file has none)."""
        return None if self.depot is None else {"lat": self.depot[0], "lon": self.depot[1]}


ROLES = ("buoy", "depot")


def _role(value: Any, where: str) -> str:
    """A point's role (absent or empty: a buoy), or BuoyFileError naming the place."""
    role = "buoy" if value in (None, "") else str(value).strip().lower()
    if role not in ROLES:
        raise BuoyFileError(f"{where}: role {str(value)[:40]!r} is neither depot nor buoy")
    return role


def _assemble(points: list[tuple[ImportedBuoy, str]], where: Callable[[int], str]) -> BuoyFile:
    """The points with their roles -> the buoys and the depot; at most one depot."""
    depots = [i for i, (_, role) in enumerate(points) if role == "depot"]
    if len(depots) > 1:
        raise BuoyFileError(f"{where(depots[1])}: a second depot (the first is {where(depots[0])})")
    depot = points[depots[0]][0] if depots else None
    return BuoyFile(
        [buoy for buoy, role in points if role == "buoy"], None if depot is None else (depot.lat, depot.lon)
    )


def _checked(lat: Any, lon: Any, ident: Any, where: str) -> ImportedBuoy:
    if isinstance(lat, bool) or isinstance(lon, bool):
        raise BuoyFileError(f"{where}: coordinates must be numbers")
    try:
        lat_f, lon_f = float(lat), float(lon)
    except (TypeError, ValueError):
        raise BuoyFileError(f"{where}: coordinates must be numbers, got ({lat!r}, {lon!r})") from None
    try:
        check_lat_lon(lat_f, lon_f, where)
    except CoordinateError as error:
        raise BuoyFileError(str(error)) from None
    return ImportedBuoy(lat_f, lon_f, None if ident in (None, "") else str(ident)[:64])


def buoys_from_geojson(document: Any) -> BuoyFile:
    """A FeatureCollection of Point features (or a single Point Feature) -> buoys, ids from properties, and the
    depot if a feature's role says so."""
    if not isinstance(document, dict):
        raise BuoyFileError("GeoJSON: expected an object")
    kind = document.get("type")
    features: object  # whatever the document holds, until checked to be a list
    if kind == "Feature":
        features = [document]
    elif kind == "FeatureCollection":
        features = document.get("features")
        if not isinstance(features, list):
            raise BuoyFileError("GeoJSON: FeatureCollection.features must be a list")
    else:
        raise BuoyFileError(f"GeoJSON: expected a FeatureCollection of Points, got type {kind!r}")
    points = []
    for i, feature in enumerate(features):
        where = f"features[{i}]"
        if not isinstance(feature, dict) or feature.get("type") != "Feature":
            raise BuoyFileError(f"{where}: not a GeoJSON Feature")
        geometry = feature.get("geometry")
        if not isinstance(geometry, dict) or geometry.get("type") != "Point":
            raise BuoyFileError(f"{where}.geometry: must be a Point")
        coords = geometry.get("coordinates")
        if not isinstance(coords, list) or len(coords) not in (2, 3):
            raise BuoyFileError(f"{where}.geometry.coordinates: must be [lon, lat] or [lon, lat, alt]")
        properties = feature.get("properties") or {}
        if not isinstance(properties, dict):
            raise BuoyFileError(f"{where}.properties: must be an object")
        # GeoJSON order is [lon, lat]
        buoy = _checked(
            coords[1], coords[0], properties.get("id", properties.get("name")), f"{where}.geometry.coordinates"
        )
        # the chart's kind, light and swing radius (a world file's faults are not)
        buoy = replace(buoy, charted={k: properties[k] for k in CHARTED_PROPERTIES if k in properties})
        points.append((buoy, _role(properties.get("role"), f"{where}.properties.role")))
    return _assemble(points, lambda i: f"features[{i}]")


_LAT_NAMES = ("lat", "latitude")
_LON_NAMES = ("lon", "lng", "long", "longitude")
_ID_NAMES = ("id", "name")
_ROLE_NAMES = ("role",)


def _column(header: list[str], names: tuple[str, ...]) -> int | None:
    for i, column in enumerate(header):
        if column.strip().lower() in names:
            return i
    return None


def _is_number(text: str) -> bool:
    try:
        return math.isfinite(float(text))
    except ValueError:
        return False


def buoys_from_csv(text: str) -> BuoyFile:
    """CSV text -> buoys (see the module docstring for the accepted layouts)."""
    # newline="": the csv module's own line handling (a lone CR ends a line, as in old Mac files) instead of
    # StringIO's, which leaves a CR inside a field and makes the reader raise
    try:
        rows = [row for row in csv.reader(io.StringIO(text, newline="")) if row and any(c.strip() for c in row)]
    except csv.Error as error:  # e.g. a field longer than the csv module takes
        raise BuoyFileError(f"CSV: {error}") from None
    if not rows:
        raise BuoyFileError("CSV: no rows")
    first = rows[0]
    has_header = not (len(first) >= 2 and _is_number(first[0]) and _is_number(first[1]))
    if has_header:
        columns = (_LAT_NAMES, _LON_NAMES, _ID_NAMES, _ROLE_NAMES)
        lat_col, lon_col, id_col, role_col = (_column(first, n) for n in columns)
        if lat_col is None or lon_col is None:
            raise BuoyFileError("CSV: the header needs columns named lat and lon")
        data, first_line = rows[1:], 2
    else:
        lat_col, lon_col, id_col, role_col = 0, 1, 2, None
        data, first_line = rows, 1
    points = []
    for line, row in enumerate(data, start=first_line):
        where = f"CSV line {line}"
        if len(row) <= max(lat_col, lon_col):
            raise BuoyFileError(f"{where}: expected lat and lon columns")
        ident, role = (row[c].strip() if c is not None and c < len(row) else None for c in (id_col, role_col))
        points.append((_checked(row[lat_col].strip(), row[lon_col].strip(), ident, where), _role(role, where)))
    if not points:
        raise BuoyFileError("CSV: a header but no buoys")
    return _assemble(points, lambda i: f"CSV line {first_line + i}")


def buoys_from_file(data: bytes, filename: str = "", content_type: str = "") -> BuoyFile:
    """Choose the reader from the name or content type, falling back to sniffing the first character."""
    try:
        text = data.decode("utf-8-sig")
    except UnicodeDecodeError:
        raise BuoyFileError("the file is not UTF-8 text") from None
    name, ctype = filename.lower(), content_type.lower()
    looks_json = text.lstrip().startswith("{")
    if name.endswith((".geojson", ".json")) or "json" in ctype or (looks_json and not name.endswith(".csv")):
        try:
            document = json.loads(text)
        except json.JSONDecodeError as error:
            raise BuoyFileError(f"GeoJSON: not valid JSON ({error.msg} at line {error.lineno})") from None
        return buoys_from_geojson(document)
    return buoys_from_csv(text)
