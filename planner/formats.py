"""Mission files as text -> depot and buoys as WGS84 [lat, lon]: GeoJSON and CSV. Pure parsing, no I/O.

GeoJSON: a FeatureCollection of Point features ([lon, lat] as GeoJSON orders them); the depot is the feature
with property "role": "depot", else the first one. CSV: rows of lat,lon (an optional header naming lat/lon
columns and an optional "role" column); the depot is the row whose role is depot, else the first row.
With an explicit depot (the CLI's --depot) every point in the file is a buoy and a depot in it is an error.
Node 0 of the result is the depot; nodes 1.. are the remaining points in file order.
"""

from __future__ import annotations

import csv
import io
import json
import math

import numpy as np

from planner.errors import InputError
from uavcore.geodesy import CoordinateError, check_lat_lon


def _check_lat_lon(lat: float, lon: float, where: str) -> None:
    """uavcore's coordinate check, raising the planner's InputError (what its callers catch)."""
    try:
        check_lat_lon(lat, lon, where)
    except CoordinateError as error:
        raise InputError(str(error)) from None


def _number(value, where: str) -> float:
    try:
        number = float(value)
    except (TypeError, ValueError):
        raise InputError(f"{where}: {value!r} is not a number") from None
    if not math.isfinite(number):
        raise InputError(f"{where}: {value!r} is not a finite number")
    return number


def _assemble(points: list[tuple[float, float]], roles: list[str], depot) -> np.ndarray:
    """[depot, buoys...] as an (n, 2) array of [lat, lon], checked."""
    depot_rows = [i for i, role in enumerate(roles) if role == "depot"]
    if depot is not None:
        if depot_rows:
            raise InputError("the file marks a depot and a depot was also given; give only one")
        lat, lon = depot
        _check_lat_lon(lat, lon, "depot")
        ordered = [(lat, lon), *points]
    else:
        if len(depot_rows) > 1:
            raise InputError(f"{len(depot_rows)} points are marked as depot; mark exactly one")
        first = depot_rows[0] if depot_rows else 0
        ordered = [points[first], *[p for i, p in enumerate(points) if i != first]] if points else []
    if len(ordered) < 2:
        raise InputError(f"need a depot and at least one buoy; the mission has {len(ordered)} point(s)")
    return np.asarray(ordered, dtype=float)


def parse_geojson(text: str, depot: tuple[float, float] | None = None) -> np.ndarray:
    """A GeoJSON FeatureCollection of Points -> (n, 2) [lat, lon] with the depot first."""
    try:
        data = json.loads(text)
    except json.JSONDecodeError as exc:
        raise InputError(f"not valid JSON: {exc}") from None
    if not isinstance(data, dict) or data.get("type") != "FeatureCollection":
        raise InputError("expected a GeoJSON FeatureCollection")
    features = data.get("features")
    if not isinstance(features, list):
        raise InputError("the FeatureCollection has no 'features' list")
    points, roles = [], []
    for i, feature in enumerate(features):
        geometry = feature.get("geometry") if isinstance(feature, dict) else None
        if not isinstance(geometry, dict) or geometry.get("type") != "Point":
            raise InputError(f"feature {i}: only Point geometries are buoys or a depot")
        coords = geometry.get("coordinates")
        if not isinstance(coords, list) or len(coords) < 2:
            raise InputError(f"feature {i}: a Point needs [lon, lat] coordinates")
        lon = _number(coords[0], f"feature {i} longitude")
        lat = _number(coords[1], f"feature {i} latitude")
        _check_lat_lon(lat, lon, f"feature {i}")
        points.append((lat, lon))
        props = feature.get("properties") or {}
        roles.append(str(props.get("role", "")).lower() if isinstance(props, dict) else "")
    return _assemble(points, roles, depot)


_LAT_NAMES = ("lat", "latitude")
_LON_NAMES = ("lon", "lng", "long", "longitude")


def parse_csv(text: str, depot: tuple[float, float] | None = None) -> np.ndarray:
    """CSV rows of lat,lon (optional header, optional role column) -> (n, 2) [lat, lon] with the depot first."""
    rows = [
        row
        for row in csv.reader(io.StringIO(text))
        if row and any(c.strip() for c in row) and not row[0].lstrip().startswith("#")
    ]
    if not rows:
        raise InputError("the CSV file has no rows")
    lat_col, lon_col, role_col = 0, 1, None
    header = [c.strip().lower() for c in rows[0]]
    try:
        float(header[0])
    except ValueError:
        lat_named = next((i for i, c in enumerate(header) if c in _LAT_NAMES), None)
        lon_named = next((i for i, c in enumerate(header) if c in _LON_NAMES), None)
        if lat_named is None or lon_named is None:
            raise InputError(f"the CSV header {rows[0]} names no lat and lon columns") from None
        lat_col, lon_col = lat_named, lon_named
        role_col = header.index("role") if "role" in header else None
        rows = rows[1:]
    points, roles = [], []
    for number, row in enumerate(rows, start=1):
        if len(row) <= max(lat_col, lon_col):
            raise InputError(f"CSV row {number}: expected lat,lon, got {row}")
        lat = _number(row[lat_col].strip(), f"CSV row {number} latitude")
        lon = _number(row[lon_col].strip(), f"CSV row {number} longitude")
        _check_lat_lon(lat, lon, f"CSV row {number}")
        points.append((lat, lon))
        roles.append(row[role_col].strip().lower() if role_col is not None and role_col < len(row) else "")
    return _assemble(points, roles, depot)


def parse_depot_option(text: str) -> tuple[float, float]:
    """'LAT,LON' -> (lat, lon), checked."""
    parts = text.split(",")
    if len(parts) != 2:
        raise InputError(f"--depot expects LAT,LON, got {text!r}")
    lat, lon = _number(parts[0].strip(), "depot latitude"), _number(parts[1].strip(), "depot longitude")
    _check_lat_lon(lat, lon, "depot")
    return lat, lon
