"""Buoys and beacons as an S-57 chart encodes them, in this project's vocabulary. Pure: the cell's objects in,
charted marks and warnings out (gcs.charts reads the objects from a cell with GDAL).

The S-57 codes read (IHO S-57 3.1, Appendix A, the object and attribute catalogues):
- the object class names the mark: BOYLAT/BCNLAT lateral, BOYCAR/BCNCAR cardinal, BOYISD/BCNISD isolated danger,
  BOYSAW/BCNSAW safe water, BOYSPP/BCNSPP special purpose. BOY* float on a mooring (the mission's default swing
  radius); BCN* stand fixed on the seabed or a pile (swing radius 0).
- CATLAM 1 port, 2 starboard, 3 preferred channel to starboard, 4 preferred channel to port. 3 and 4 are IALA's
  modified lateral marks where a channel forks; "preferred channel to starboard" is a port-hand mark with a band
  of the other colour (the main channel lies to starboard: keep the mark to port), so 3 -> port and 4 ->
  starboard, and `preferred_channel` says which channel is preferred. (IALA lights them Fl(2+1), which
  uavcore.buoy_world.check_kind_light finds odd for a plain lateral mark: the inspection's business, not ours.)
  Without CATLAM the side is read from a lateral mark's one colour in its region (region A: port red, starboard
  green; region B the other way round), and the warning says so.
- CATCAM 1-4 north, east, south, west.
- COLOUR (1 white, 2 black, 3 red, 4 green, 5 blue, 6 yellow, 7 grey, 8 brown, 9 amber, 10 violet, 11 orange,
  12 magenta, 13 pink), COLPAT (1 horizontal bands, 2 vertical stripes, 3 diagonal, 4 squared, 5 stripes of
  unknown direction, 6 border), BOYSHP and BCNSHP: kept as words, the colours as charted (not the region-A look
  uavcore.buoy_world.APPEARANCE gives a kind).
- MARSYS on the mark, else on the M_NSYS area holding it: 1 IALA region A, 2 region B; any other system (9 none,
  10 other, 11 CEVNI, ...) is no IALA region. A chart that says nothing takes the region the caller gives.
- LIGHTS: LITCHR, SIGGRP, SIGPER and COLOUR become chart text by uavcore.light_character.from_s57.

A light belongs to the mark it is linked to (the cell's master-slave link, LNAM_REFS) or, unlinked, to the nearest
mark within COLOCATED_M of it. Several lights on one mark: the main one is the mark's `light`, the others' text is
kept in `other_lights` (see _main_light_rank). An attribute value that cannot be mapped never stops an import: the
mark keeps what is known and the warning names the mark, the attribute and the value.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any, Literal

import numpy as np
import shapely
from shapely.geometry import Point
from shapely.geometry.base import BaseGeometry

from gcs.domain.areas import bounds_text
from gcs.domain.buoy_files import BuoyFileError
from gcs.domain.chart_basemap import BasemapFeature
from uavcore.buoy_world import DEFAULT_SWING_RADIUS_M, World, WorldBuoy
from uavcore.light_character import LightCharacterError, from_s57, parse

Region = Literal["A", "B"]
REGIONS: tuple[Region, ...] = ("A", "B")

BUOY_CLASSES = ("BOYLAT", "BOYCAR", "BOYISD", "BOYSAW", "BOYSPP")
BEACON_CLASSES = ("BCNLAT", "BCNCAR", "BCNISD", "BCNSAW", "BCNSPP")
MARK_CLASSES = BUOY_CLASSES + BEACON_CLASSES
COLOCATED_M = 1.0  # a light this close to a mark is on it (charts place a mark's light on the mark's own point)
MAX_LIGHT_TEXT = 40  # BuoyIn.light's limit

_KIND_OF_CLASS = {"ISD": "isolated_danger", "SAW": "safe_water", "SPP": "special"}  # the class's last letters
_CATLAM: dict[int, tuple[str, str | None]] = {
    1: ("port", None),
    2: ("starboard", None),
    3: ("port", "starboard"),
    4: ("starboard", "port"),
}
_CATCAM = {1: "north", 2: "east", 3: "south", 4: "west"}
_MARSYS: dict[int, Region] = {1: "A", 2: "B"}
_LATERAL_COLOUR: dict[Region, dict[str, str]] = {
    "A": {"red": "port", "green": "starboard"},
    "B": {"green": "port", "red": "starboard"},
}
COLOURS = {
    1: "white", 2: "black", 3: "red", 4: "green", 5: "blue", 6: "yellow", 7: "grey", 8: "brown", 9: "amber",
    10: "violet", 11: "orange", 12: "magenta", 13: "pink",
}  # fmt: skip
COLOUR_PATTERNS = {1: "horizontal", 2: "vertical", 3: "diagonal", 4: "squared", 5: "stripes", 6: "border"}
# uavcore.buoy_world.Appearance's words where it has them (cone, can, pillar, spar)
BUOY_SHAPES = {1: "cone", 2: "can", 3: "sphere", 4: "pillar", 5: "spar", 6: "barrel", 7: "super_buoy", 8: "ice_buoy"}
BEACON_SHAPES = {1: "stake", 2: "withy", 3: "tower", 4: "lattice", 5: "pile", 6: "cairn", 7: "buoyant"}
# CATLIT of lights that are not the mark's navigation light: aero, air obstruction, fog detector, flood, strip,
# subsidiary, spotlight, emergency
_SECONDARY_CATLIT = frozenset({5, 6, 7, 8, 9, 10, 11, 17})
_DAY_OR_FOG_EXCLIT = frozenset({2, 3})  # EXCLIT: shown by day, or in fog only


class ChartError(BuoyFileError):
    """A file that gives no buoys: not an S-57 cell, a damaged one, a cell without buoys or beacons, an area
    holding none. The message names the cell and what is wrong (HTTP 422, CLI exit 2)."""


class NothingInAreaError(ChartError):
    """The cell has buoys or beacons, but none in the area asked for (the message says where they are)."""


def object_label(object_class: str, attributes: Mapping[str, Any]) -> str:
    """How a warning names an object of the cell: class, name and id."""
    name = _text(attributes.get("OBJNAM"))
    ident = _text(attributes.get("LNAM")) or f"RCID {attributes.get('RCID')}"
    return f"{object_class} {name!r} ({ident})" if name else f"{object_class} ({ident})"


@dataclass(frozen=True)
class S57Object:
    """A point object of a cell as the reader hands it over: its class, its attributes (absent ones left out or
    None; list attributes such as COLOUR as lists) and its position."""

    object_class: str
    attributes: Mapping[str, Any]
    lat: float
    lon: float

    def get(self, name: str) -> Any:
        return self.attributes.get(name)

    @property
    def lnam(self) -> str | None:
        return _text(self.get("LNAM"))

    @property
    def label(self) -> str:
        return object_label(self.object_class, self.attributes)


@dataclass(frozen=True)
class SystemArea:
    """An M_NSYS object: the area where one system of marks (MARSYS) applies."""

    area: BaseGeometry
    marsys: int | None


@dataclass(frozen=True)
class ChartedMark:
    """A buoy or beacon as charted: what POST /missions takes (as_buoy) and the chart's own description."""

    id: str  # the object's LNAM (agency, feature id and subdivision: stable across the cell's editions), else RCID
    lat: float
    lon: float
    object_class: str  # BOYLAT, BCNSPP, ...
    name: str | None = None  # OBJNAM
    kind: str | None = None  # uavcore.buoy_world.KINDS; None: the chart does not say (a warning tells why)
    preferred_channel: str | None = None  # CATLAM 3/4: "starboard" or "port"
    shape: str | None = None  # BOYSHP / BCNSHP
    colours: tuple[str, ...] = ()  # COLOUR, top to bottom as charted
    colour_pattern: str | None = None  # COLPAT; "solid" for one colour
    region: Region | None = None  # the IALA region its colours are read in
    light: str | None = None  # the main light's chart text (uavcore.light_character.parse reads it); None: unlit
    other_lights: tuple[str, ...] = ()  # the others on the same structure

    @property
    def beacon(self) -> bool:
        return self.object_class in BEACON_CLASSES

    @property
    def label(self) -> str:
        return object_label(self.object_class, {"OBJNAM": self.name, "LNAM": self.id})

    @property
    def swing_radius_m(self) -> float | None:
        """0 for a beacon (fixed); None for a buoy: the chart gives no mooring, the mission takes its default."""
        return 0.0 if self.beacon else None

    def as_buoy(self) -> dict[str, Any]:
        """The buoy as POST /missions takes it (BuoyIn)."""
        return {
            "id": self.id,
            "lat": self.lat,
            "lon": self.lon,
            "kind": self.kind,
            "light": self.light,
            "swing_radius_m": self.swing_radius_m,
            "region": self.region,
        }

    def as_dict(self) -> dict[str, Any]:
        """Everything the chart says of the mark (ChartedMarkOut)."""
        return self.as_buoy() | {
            "name": self.name,
            "object_class": self.object_class,
            "beacon": self.beacon,
            "preferred_channel": self.preferred_channel,
            "shape": self.shape,
            "colours": list(self.colours),
            "colour_pattern": self.colour_pattern,
            "region": self.region,
            "other_lights": list(self.other_lights),
        }


@dataclass(frozen=True)
class CellInfo:
    """The cell's identity from its DSID record."""

    name: str  # DSNM without .000, e.g. US4MD81M
    edition: str | None = None
    update: str | None = None
    issued: str | None = None  # ISDT, YYYYMMDD


@dataclass(frozen=True)
class ChartContents:
    """What the reader found in a cell, before any mapping."""

    cell: CellInfo
    marks: Sequence[S57Object]
    lights: Sequence[S57Object] = ()
    systems: Sequence[SystemArea] = ()
    coverage: BaseGeometry | None = None  # M_COVR's covered area (CATCOV 1)
    warnings: Sequence[str] = ()  # the reader's own (objects it could not place)
    basemap: Sequence[BasemapFeature] = ()  # land, coastline, piers, depth contours (gcs.domain.chart_basemap)


@dataclass(frozen=True)
class ChartImport:
    """The marks an import gives (in the cell's order), the region the chart was read in, and what could not be
    mapped."""

    cell: CellInfo
    marks: tuple[ChartedMark, ...]
    region: Region  # the cell's own (its M_NSYS), else the fallback the caller gave
    region_source: Literal["chart", "default"]
    warnings: tuple[str, ...] = field(default=())
    basemap: tuple[BasemapFeature, ...] = field(default=())  # the whole cell's, whatever the area


# ----- attribute values
def _text(value: Any) -> str | None:
    if value is None:
        return None
    text = str(value).strip()
    return text or None


def _number(value: Any) -> float | None:
    """A finite number, None for anything else (GDAL gives NaN for an absent real attribute)."""
    if isinstance(value, bool) or value is None:
        return None
    try:
        number = float(value)
    except (TypeError, ValueError):
        return None
    return number if math.isfinite(number) else None


def _codes(value: Any) -> tuple[list[int], list[str]]:
    """An enumerated or list attribute's codes, and the parts that are no code: "3,1", ["3", "1"], 3 or 3.0."""
    if value is None:
        return [], []
    parts = value.split(",") if isinstance(value, str) else list(value) if isinstance(value, Iterable) else [value]
    codes, unreadable = [], []
    for part in parts:
        number = _number(part.strip() if isinstance(part, str) else part)
        if number is not None and number.is_integer():
            codes.append(int(number))
        elif str(part).strip():
            unreadable.append(str(part).strip())
    return codes, unreadable


def _shown(obj: S57Object, attribute: str) -> str:
    """An attribute as a warning names it: "CATLAM 11", "COLOUR 3,4", "CATLAM missing"."""
    value = obj.get(attribute)
    if value is None:
        return f"{attribute} missing"
    shown = ",".join(map(str, value)) if isinstance(value, list | tuple) else str(value)
    return f"{attribute} {shown}"


def _code(value: Any) -> int | None:
    codes, _ = _codes(value)
    return codes[0] if len(codes) == 1 else None


class _Warnings:
    """The warnings of one import, each naming the object it is about."""

    def __init__(self) -> None:
        self.items: list[str] = []

    def add(self, obj: S57Object, what: str) -> None:
        self.items.append(f"{obj.label}: {what}")


def _words(obj: S57Object, attribute: str, table: Mapping[int, str], warn: _Warnings) -> list[str]:
    """A list attribute's codes as words; codes outside the table are left out with a warning."""
    codes, unreadable = _codes(obj.get(attribute))
    unknown = [str(code) for code in codes if code not in table] + unreadable
    if unknown:
        warn.add(obj, f"{attribute} {', '.join(unknown)} not an S-57 value this import knows: left out")
    return [table[code] for code in codes if code in table]


def _word(obj: S57Object, attribute: str, table: Mapping[int, str], warn: _Warnings) -> str | None:
    words = _words(obj, attribute, table, warn)
    return words[0] if words else None


# ----- the region
def _region(obj: S57Object, systems: Sequence[SystemArea], fallback: Region, warn: _Warnings) -> Region | None:
    """The mark's own MARSYS, else that of the M_NSYS area holding it, else the fallback. A system of marks that is
    no IALA region (MARSYS 9 none, 10 other, 11 CEVNI, ...) gives none: the colours then tell no side."""
    marsys = _code(obj.get("MARSYS"))
    if marsys is not None:
        if marsys not in _MARSYS:
            warn.add(obj, f"MARSYS {marsys} is no IALA region")
        return _MARSYS.get(marsys)
    point = Point(obj.lon, obj.lat)
    for system in systems:
        if system.marsys is not None and system.area.covers(point):
            return _MARSYS.get(system.marsys)
    return fallback


def _system_warnings(systems: Sequence[SystemArea]) -> list[str]:
    return [
        f"M_NSYS: MARSYS {s.marsys} is no IALA region: its marks' colours are read in none"
        for s in systems
        if s.marsys is not None and s.marsys not in _MARSYS
    ]


# ----- the kind
def _lateral_kind(
    obj: S57Object, colours: list[str], region: Region | None, warn: _Warnings
) -> tuple[str | None, str | None]:
    catlam = _code(obj.get("CATLAM"))
    if catlam in _CATLAM:
        return _CATLAM[catlam]
    why = _shown(obj, "CATLAM") + ("" if obj.get("CATLAM") is None else " not a side this maps")
    side = _LATERAL_COLOUR[region].get(colours[0]) if region and len(colours) == 1 else None
    if side is None:
        warn.add(obj, f"{why}, and its colours {'/'.join(colours) or 'not charted'} do not tell the side: kind unknown")
        return None, None
    warn.add(obj, f"{why}: kind {side} read from its colour {colours[0]} in IALA region {region}")
    return side, None


def _kind(obj: S57Object, colours: list[str], region: Region | None, warn: _Warnings) -> tuple[str | None, str | None]:
    """(kind, preferred channel) of a mark."""
    suffix = obj.object_class[3:]
    if suffix == "LAT":
        return _lateral_kind(obj, colours, region, warn)
    if suffix == "CAR":
        catcam = _code(obj.get("CATCAM"))
        if catcam not in _CATCAM:
            warn.add(obj, f"{_shown(obj, 'CATCAM')}, not a quadrant (1-4): kind unknown")
            return None, None
        return _CATCAM[catcam], None
    return _KIND_OF_CLASS[suffix], None


# ----- lights
def _light_text(light: S57Object) -> str:
    """The light's chart text (LightCharacterError if it is not one this project reads)."""
    litchr = _code(light.get("LITCHR"))
    if litchr is None:
        raise LightCharacterError(f"{_shown(light, 'LITCHR')} is no light character")
    colours, unreadable = _codes(light.get("COLOUR"))
    if unreadable:
        raise LightCharacterError(f"COLOUR {', '.join(unreadable)} is no colour code")
    period = _number(light.get("SIGPER"))
    group = _text(light.get("SIGGRP")) or ""
    text = from_s57(litchr, group, period if period and period > 0 else None, ",".join(map(str, colours)) or "1")
    abbreviation = text.abbreviation()
    if len(abbreviation) > MAX_LIGHT_TEXT:
        raise LightCharacterError(f"{abbreviation!r} is longer than {MAX_LIGHT_TEXT} characters")
    return abbreviation


def _raw_light(light: S57Object) -> str:
    """A light this project cannot read, as the cell gives it."""
    parts = [_shown(light, name) for name in ("LITCHR", "SIGGRP", "SIGPER", "COLOUR") if light.get(name)]
    return "S-57 " + ", ".join(parts) if parts else "S-57 light without attributes"


def _main_light_rank(light: S57Object) -> tuple[bool, bool, bool, float, float]:
    """Sorts a mark's lights, the main one first: a navigation light (not aero, obstruction, flood...), shown at
    night, all round (no sector), then the longest nominal range (VALNMR), then the highest."""
    catlit, _ = _codes(light.get("CATLIT"))
    return (
        bool(_SECONDARY_CATLIT.intersection(catlit)),
        _code(light.get("EXCLIT")) in _DAY_OR_FOG_EXCLIT,
        _number(light.get("SECTR1")) is not None,
        -(_number(light.get("VALNMR")) or 0.0),
        -(_number(light.get("HEIGHT")) or 0.0),
    )


def _lights_text(mark: S57Object, lights: list[S57Object], warn: _Warnings) -> tuple[str | None, tuple[str, ...]]:
    """(the main light's text, the others' text) of the lights on a mark: the main one is the first that reads in
    _main_light_rank's order; one that does not read is kept, as charted, among the others."""
    main: str | None = None
    others: list[str] = []
    for light in sorted(lights, key=_main_light_rank):  # stable: ties keep the cell's order
        try:
            text = _light_text(light)
        except LightCharacterError as error:
            warn.add(mark, f"light {_raw_light(light)} not read ({error}): kept as charted in other_lights")
            others.append(_raw_light(light))
            continue
        if main is None:
            main = text
        else:
            others.append(text)
    return main, tuple(others)


def _metres_apart(lat: np.ndarray, lon: np.ndarray, at_lat: float, at_lon: float) -> np.ndarray:
    """Distances from (at_lat, at_lon), equirectangular: exact to far under a millimetre over metres."""
    north = np.radians(lat - at_lat) * 6_371_000.0
    east = np.radians(lon - at_lon) * 6_371_000.0 * math.cos(math.radians(at_lat))
    return np.hypot(north, east)


def lights_by_mark(marks: Sequence[S57Object], lights: Sequence[S57Object]) -> list[list[S57Object]]:
    """Each mark's lights: those the cell links to it (its LNAM_REFS), and each unlinked light within COLOCATED_M
    of a mark, given to the nearest."""
    by_lnam = {light.lnam: light for light in lights if light.lnam}
    found: list[list[S57Object]] = []
    linked: set[str] = set()
    for mark in marks:
        refs = [_text(ref) for ref in mark.get("LNAM_REFS") or []]
        mine = [by_lnam[ref] for ref in refs if ref in by_lnam]
        linked.update(light.lnam for light in mine if light.lnam)
        found.append(mine)
    loose = [light for light in lights if light.lnam not in linked]
    if not loose or not marks:
        return found
    lat = np.array([m.lat for m in marks], dtype=float)
    lon = np.array([m.lon for m in marks], dtype=float)
    for light in loose:
        distances = _metres_apart(lat, lon, light.lat, light.lon)
        nearest = int(np.argmin(distances))
        if distances[nearest] <= COLOCATED_M:
            found[nearest].append(light)
    return found


# ----- marks
def charted_mark(
    obj: S57Object, lights: list[S57Object], systems: Sequence[SystemArea], fallback: Region, warn: _Warnings
) -> ChartedMark:
    """One mark as charted; what cannot be mapped is left out and warned of."""
    colours = _words(obj, "COLOUR", COLOURS, warn)
    pattern = _word(obj, "COLPAT", COLOUR_PATTERNS, warn)
    beacon = obj.object_class in BEACON_CLASSES
    region = _region(obj, systems, fallback, warn)
    kind, preferred = _kind(obj, colours, region, warn)
    light, others = _lights_text(obj, lights, warn)
    return ChartedMark(
        id=obj.lnam or f"RCID{obj.get('RCID')}",
        lat=obj.lat,
        lon=obj.lon,
        object_class=obj.object_class,
        name=_text(obj.get("OBJNAM")),
        kind=kind,
        preferred_channel=preferred,
        shape=_word(obj, "BCNSHP" if beacon else "BOYSHP", BEACON_SHAPES if beacon else BUOY_SHAPES, warn),
        colours=tuple(colours),
        colour_pattern=pattern or ("solid" if len(colours) == 1 else None),
        region=region,
        light=light,
        other_lights=others,
    )


def cell_region(systems: Sequence[SystemArea], fallback: Region) -> tuple[Region, Literal["chart", "default"]]:
    """The cell's region: its M_NSYS areas' when they name one region, else the fallback."""
    regions = {_MARSYS.get(s.marsys) for s in systems if s.marsys is not None}
    if len(regions) == 1 and (region := regions.pop()) is not None:
        return region, "chart"
    return fallback, "default"


def read_marks(contents: ChartContents, fallback_region: Region = "A", area: BaseGeometry | None = None) -> ChartImport:
    """The cell's buoys and beacons (those inside `area` when given), mapped. ChartError when there are none."""
    cell = contents.cell.name
    if not contents.marks:
        raise ChartError(f"{cell}: the cell has no buoys or beacons ({', '.join(MARK_CLASSES)})")
    chosen = list(contents.marks)
    if area is not None:
        shapely.prepare(area)
        chosen = [m for m in chosen if area.covers(Point(m.lon, m.lat))]
        if not chosen:
            raise NothingInAreaError(_nothing_in_area(contents, area))
    warn = _Warnings()
    lights = lights_by_mark(chosen, contents.lights)
    marks = tuple(
        charted_mark(m, mine, contents.systems, fallback_region, warn) for m, mine in zip(chosen, lights, strict=True)
    )
    region, source = cell_region(contents.systems, fallback_region)
    warnings = (*contents.warnings, *_system_warnings(contents.systems), *warn.items)
    return ChartImport(contents.cell, marks, region, source, warnings, tuple(contents.basemap))


def _nothing_in_area(contents: ChartContents, area: BaseGeometry) -> str:
    cell, where = contents.cell.name, bounds_text(area)
    if contents.coverage is not None and not area.intersects(contents.coverage):
        return f"{cell}: the area {where} lies outside the cell, which covers {bounds_text(contents.coverage)}"
    marks = bounds_text(shapely.multipoints([(m.lon, m.lat) for m in contents.marks]))
    return f"{cell}: no buoys or beacons in the area {where}; the cell's {len(contents.marks)} lie within {marks}"


# ----- the world file
def world_of(marks: Sequence[ChartedMark]) -> tuple[World, list[str]]:
    """The marks as a uavcore.buoy_world world (its file: what `sitl-quad --world` and POST /imports read), and why
    each mark left out of it is: a world buoy needs its kind, and a light with a period (the simulator flashes
    it). Beacons are buoys of swing radius 0; buoys take the world's default swing radius."""
    buoys, left_out = [], []
    for mark in marks:
        light = None if mark.light is None else parse(mark.light)
        if mark.kind is None or (light is not None and light.cycle_s is None):
            why = "its kind is unknown" if mark.kind is None else f"its light {mark.light} has no period"
            left_out.append(f"{mark.label}: not in the world file: {why}")
            continue
        radius = DEFAULT_SWING_RADIUS_M if mark.swing_radius_m is None else mark.swing_radius_m
        region = mark.region or "A"  # no IALA region (CEVNI, ...): the world draws region A's colours
        buoys.append(WorldBuoy(mark.id, mark.kind, (mark.lat, mark.lon), light, radius, light, region=region))
    return World(tuple(buoys)), left_out
