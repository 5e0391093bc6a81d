"""Areas a request or a command names: a bbox or a GeoJSON polygon, as shapely geometry in [lon, lat] degrees.
Pure."""

from __future__ import annotations

import json
import math

import shapely
from shapely.geometry import box, shape
from shapely.geometry.base import BaseGeometry
from shapely.validation import explain_validity


class AreaError(ValueError):
    """An area that cannot be read (the message says what an area looks like)."""


def bounds_text(geometry: BaseGeometry) -> str:
    """A geometry's bounds as west,south,east,north (what parse_area reads back)."""
    west, south, east, north = geometry.bounds
    return f"{west:.5f},{south:.5f},{east:.5f},{north:.5f}"


def _number(text: str) -> float | None:
    try:
        number = float(text)
    except ValueError:
        return None
    return number if math.isfinite(number) else None


def parse_area(text: str) -> BaseGeometry:
    """An area: a bbox "west,south,east,north" in degrees (GeoJSON's bbox order, brackets allowed), or a GeoJSON
    Polygon or MultiPolygon ([lon, lat] positions), alone or as a Feature's geometry. AreaError if it is neither."""
    text = text.strip()
    if text.startswith("{"):
        return _polygon(text)
    return _bbox(text.strip("[]"))


def parse_bbox(text: str) -> tuple[float, float, float, float]:
    """A bbox "west,south,east,north" in degrees as those four numbers; AreaError if it is not one."""
    west, south, east, north = _bbox(text.strip().strip("[]")).bounds
    return west, south, east, north


def _bbox(text: str) -> BaseGeometry:
    numbers = [_number(part) for part in text.split(",")]
    if len(numbers) != 4 or None in numbers:
        raise AreaError(f"{text!r}: expected west,south,east,north in degrees, or a GeoJSON Polygon")
    west, south, east, north = (n for n in numbers if n is not None)
    _check_degrees(west, south)
    _check_degrees(east, north)
    if not (west < east and south < north):
        raise AreaError(f"{text!r}: west,south,east,north needs west < east and south < north")
    return box(west, south, east, north)


def _check_degrees(lon: float, lat: float) -> None:
    if not (-180.0 <= lon <= 180.0 and -90.0 <= lat <= 90.0):
        raise AreaError(f"[{lon}, {lat}] is not a [lon, lat] position in degrees")


def _polygon(text: str) -> BaseGeometry:
    try:
        document = json.loads(text)
    except json.JSONDecodeError as error:
        raise AreaError(f"not JSON ({error.msg} at character {error.pos})") from None
    geometry = (
        document.get("geometry") if isinstance(document, dict) and document.get("type") == "Feature" else document
    )
    if not isinstance(geometry, dict) or geometry.get("type") not in ("Polygon", "MultiPolygon"):
        raise AreaError("expected a GeoJSON Polygon or MultiPolygon (or a Feature of one), or west,south,east,north")
    try:
        polygon = shape(geometry)
    except (TypeError, ValueError, IndexError, AttributeError, shapely.errors.ShapelyError) as error:
        raise AreaError(f"the {geometry['type']}'s coordinates cannot be read: {error}") from None
    if polygon.is_empty or not all(math.isfinite(value) for value in polygon.bounds):
        raise AreaError(f"the {geometry['type']} is empty or not finite")
    west, south, east, north = polygon.bounds
    _check_degrees(west, south)
    _check_degrees(east, north)
    if not polygon.is_valid:
        raise AreaError(f"the {geometry['type']} is not a valid area: {explain_validity(polygon)}")
    return polygon
