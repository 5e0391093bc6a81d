"""The simulated world's buoys: what each one is (IALA kind, look, charted light), where it really floats (its
mooring and its swing) and the faults it hides (off station, light out, another character). Pure computation.

A world file is a GeoJSON FeatureCollection of Point features at the buoys' CHARTED positions ([lon, lat]), with
these properties (the contract; any other property is an error, so that a typo cannot silently drop a fault):
- `id` (string, unique) and `kind` (one of KINDS) are required;
- `light`: the charted character as chart text, e.g. "Fl(2) G 6s"; absent or null: unlit;
- `swing_radius_m`: the radius of the circle the buoy swings in around its mooring (default DEFAULT_SWING_RADIUS_M;
  0 for a beacon, which stands fixed on the seabed: the charts' BCN* marks);
- `shows`: what the light really does, "dark" or another character; absent: as charted (a fault when it differs);
- `offset_m`: [north, east] metres from the charted position to the real mooring; absent: [0, 0];
- `mmsi`: the buoy's AIS identity, a 9-digit MMSI (an AtoN's is 99MIDxxxx, ITU-R M.585), unique in the world; absent
  or null: the buoy carries no AIS (sitl_quad.ais_station has those that do report themselves, message 21);
- `region`: the IALA buoyage region its lateral marks follow, "A" (port red, starboard green: Europe, Africa, most of
  Asia and Oceania) or "B" (port green, starboard red: the Americas, Japan, Korea, the Philippines); absent: "A".
The collection may carry a top-level integer `seed`: the buoys' wander in their swing circles (default 0).
IALA facts are data here: APPEARANCE, DEFAULT_LIGHT and _LIGHT_RULES give region A's; `appearance`,
`default_light` and `check_kind_light` turn a lateral mark's red and green round for region B (its shape and
topmark's shape stay: port is a can, starboard a cone, in both regions).
"""

from __future__ import annotations

import json
import math
import os
import zlib
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, replace
from functools import cached_property
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from uavcore.geodesy import CoordinateError, LocalFrame, check_lat_lon
from uavcore.light_character import LightCharacter, LightCharacterError, parse

KINDS = ("port", "starboard", "north", "east", "south", "west", "isolated_danger", "safe_water", "special")
CARDINALS = ("north", "east", "south", "west")
PROPERTIES = ("id", "kind", "light", "swing_radius_m", "shows", "offset_m", "mmsi", "region")
REGIONS = ("A", "B")
LATERAL = ("port", "starboard")
_REGION_B_SWAP = {"red": "green", "green": "red", "R": "G", "G": "R"}  # a lateral mark's colours in region B
MMSI_RANGE = range(100_000_000, 1_000_000_000)  # nine digits
DEFAULT_SWING_RADIUS_M = 5.0
DARK = "dark"  # `shows` of a light that is out


@dataclass(frozen=True)
class Appearance:
    """How a kind of buoy looks: body colours, shape, topmark and typical size (a harbour-approach buoy)."""

    colours: tuple[str, ...]  # body colours, top to bottom (left to right for vertical stripes); PAINT_RGB names
    pattern: str  # "solid", "horizontal" (bands) or "vertical" (stripes)
    shape: str  # "can", "cone", "pillar" or "spar" (S-57 BOYSHP)
    topmark: str  # "can", "cone", "cones_up", "cones_base_to_base", "cones_down", "cones_point_to_point", ...
    topmark_colour: str
    height_m: float  # body above the waterline, topmark excluded
    diameter_m: float  # at the waterline


def _banded_pillar(colours: tuple[str, ...], topmark: str) -> Appearance:
    """A cardinal or isolated danger mark: a pillar in horizontal bands, with a black topmark."""
    return Appearance(colours, "horizontal", "pillar", topmark, "black", 3.0, 1.8)


# Lateral buoys are the small ones (a 2 m can or cone); cardinal, isolated danger and safe water marks stand in
# open water and are pillars, taller and broader to be seen from further. IALA lets a special mark take any shape
# that does not conflict with the others: a small can here, told from a port can by its yellow and its X.
APPEARANCE: dict[str, Appearance] = {
    "port": Appearance(("red",), "solid", "can", "can", "red", 2.0, 1.5),
    "starboard": Appearance(("green",), "solid", "cone", "cone", "green", 2.0, 1.5),
    "north": _banded_pillar(("black", "yellow"), "cones_up"),
    "east": _banded_pillar(("black", "yellow", "black"), "cones_base_to_base"),
    "south": _banded_pillar(("yellow", "black"), "cones_down"),
    "west": _banded_pillar(("yellow", "black", "yellow"), "cones_point_to_point"),
    "isolated_danger": _banded_pillar(("black", "red", "black"), "two_spheres"),
    "safe_water": Appearance(("red", "white"), "vertical", "pillar", "sphere", "red", 3.0, 1.8),
    "special": Appearance(("yellow",), "solid", "can", "x", "yellow", 1.5, 1.2),
}

# sRGB of the paints (close to RAL 3020 traffic red, 6024 traffic green, 1023 traffic yellow) ...
PAINT_RGB: dict[str, tuple[int, int, int]] = {
    "red": (204, 6, 5),
    "green": (0, 131, 81),
    "yellow": (247, 181, 0),
    "black": (20, 20, 20),
    "white": (241, 240, 234),
}
# ... and of the lights as a camera sees them lit (the IALA signal colours: green is bluish, yellow amber)
LIGHT_RGB: dict[str, tuple[int, int, int]] = {
    "W": (255, 250, 235),
    "R": (255, 40, 25),
    "G": (40, 255, 160),
    "Y": (255, 190, 0),
    "Bu": (40, 110, 255),
}

# The typical charted light of each kind, for buoys given none (safe water: IALA's LFl 10s, one of its four).
DEFAULT_LIGHT: dict[str, str] = {
    "port": "Fl R 4s",
    "starboard": "Fl G 4s",
    "north": "Q W",
    "east": "Q(3) W 10s",
    "south": "Q(6)+LFl W 15s",
    "west": "Q(9) W 15s",
    "isolated_danger": "Fl(2) W 5s",
    "safe_water": "LFl W 10s",
    "special": "Fl Y 4s",
}

# What IALA gives each kind's light: its colour, and the rhythms it may show, each with the period it must have
# (None: any). A rhythm is the chart text before the colour, e.g. "Q(3)". None: any rhythm but the forbidden ones
# (Fl(2+1) marks a preferred channel, not a plain lateral buoy). A special mark's "any rhythm not used
# elsewhere" is left to its yellow.
_LIGHT_RULES: dict[str, tuple[str, dict[str, float | None] | None, frozenset[str]]] = {
    "port": ("R", None, frozenset({"Fl(2+1)"})),
    "starboard": ("G", None, frozenset({"Fl(2+1)"})),
    "north": ("W", {"Q": None, "VQ": None}, frozenset()),
    "east": ("W", {"Q(3)": 10.0, "VQ(3)": 5.0}, frozenset()),
    "south": ("W", {"Q(6)+LFl": 15.0, "VQ(6)+LFl": 10.0}, frozenset()),
    "west": ("W", {"Q(9)": 15.0, "VQ(9)": 10.0}, frozenset()),
    "isolated_danger": ("W", {"Fl(2)": None}, frozenset()),
    "safe_water": ("W", {"Iso": None, "Oc": None, "LFl": 10.0, "Mo(A)": None}, frozenset()),
    "special": ("Y", None, frozenset()),
}


def _in_region(kind: str, region: str, colour: str) -> str:
    """A colour of region A's `kind` as region `region` has it."""
    return _REGION_B_SWAP.get(colour, colour) if region == "B" and kind in LATERAL else colour


def appearance(kind: str, region: str = "A") -> Appearance:
    """How a kind of buoy looks in an IALA region (APPEARANCE is region A's)."""
    look = APPEARANCE[kind]
    if region == "A" or kind not in LATERAL:
        return look
    colours = tuple(_in_region(kind, region, c) for c in look.colours)
    return replace(look, colours=colours, topmark_colour=_in_region(kind, region, look.topmark_colour))


def default_light(kind: str, region: str = "A") -> LightCharacter:
    """The typical charted character of a kind of buoy in an IALA region (DEFAULT_LIGHT is region A's)."""
    text = DEFAULT_LIGHT[kind]
    if region == "B" and kind in LATERAL:
        text = " ".join(_in_region(kind, region, word) for word in text.split())
    return parse(text)


def check_kind_light(kind: str, light: LightCharacter | None, region: str = "A") -> list[str]:
    """Warnings where a charted light contradicts its buoy's kind (colour, rhythm, period) in its IALA region;
    [] when it fits."""
    if light is None:
        return []  # an unlit buoy is allowed for every kind
    colour, allowed, forbidden = _LIGHT_RULES[kind]
    colour = _in_region(kind, region, colour)
    text, rhythm = light.abbreviation(), light.abbreviation().split()[0]
    warnings = []
    if set(light.colours) != {colour}:
        warnings.append(f"{kind} buoy: light {text} is {''.join(light.colours)}, IALA gives it {colour}")
    if rhythm in forbidden or (allowed is not None and rhythm not in allowed):
        expected = "any rhythm but " + ", ".join(sorted(forbidden)) if allowed is None else ", ".join(allowed)
        warnings.append(f"{kind} buoy: light {text} has rhythm {rhythm}, IALA gives it {expected}")
    elif allowed and (period := allowed[rhythm]) is not None and light.period_s != period:
        warnings.append(f"{kind} buoy: light {text} has period {light.period_s} s, IALA gives {rhythm} {period:g} s")
    return warnings


@dataclass(frozen=True)
class WorldBuoy:
    """A buoy of the simulated world: as charted, and as it really is (actual_light, offset_m)."""

    id: str
    kind: str  # one of KINDS
    charted: tuple[float, float]  # (lat, lon) degrees: the chart's position, the centre of the charted swing circle
    light: LightCharacter | None = None  # as charted; None: unlit
    swing_radius_m: float = DEFAULT_SWING_RADIUS_M
    actual_light: LightCharacter | None = None  # what it really shows; None: dark
    offset_m: tuple[float, float] = (0.0, 0.0)  # (north, east) from the charted position to the real mooring
    mmsi: int | None = None  # its AIS transmitter's identity; None: no AIS
    region: str = "A"  # its IALA buoyage region (REGIONS): a lateral mark's colours

    @property
    def appearance(self) -> Appearance:
        """How the buoy looks (its kind's, in its region)."""
        return appearance(self.kind, self.region)

    @cached_property
    def _light_phase_s(self) -> float:
        # lanterns are not synchronised: each starts its cycle at its own time (fixed by the id, so reproducible)
        return zlib.crc32(self.id.encode()) / 2**32 * 3600.0

    def light_on(self, t_s: float) -> bool:
        """Whether the light really shows at simulated time t_s (faults applied)."""
        return self.actual_light is not None and self.actual_light.is_on(t_s + self._light_phase_s)

    def light_colour(self, t_s: float) -> str | None:
        """The colour the light really shows at t_s (W, R, G, Y, Bu), None while dark."""
        return None if self.actual_light is None else self.actual_light.colour_at(t_s + self._light_phase_s)

    @property
    def faults(self) -> list[str]:
        """The injected faults, the inspection's ground truth: "off_station" (the real mooring outside the charted
        swing circle, so the buoy mostly is too), "light_out", "wrong_character" (rhythm, period or colour)."""
        faults = []
        if math.hypot(*self.offset_m) > self.swing_radius_m:
            faults.append("off_station")
        if self.actual_light != self.light:
            faults.append("light_out" if self.actual_light is None else "wrong_character")
        return faults


class WorldFileError(ValueError):
    """A world file that is not the contract's GeoJSON (the message names the feature, the field and why)."""


def _number(value: Any) -> float | None:
    """value as a finite float, None if it is not one (JSON's booleans are not numbers here)."""
    if isinstance(value, bool) or not isinstance(value, int | float) or not math.isfinite(value):
        return None
    return float(value)


def _numbers(value: Any) -> list[float]:
    """A JSON array of finite numbers as floats; [] if value is anything else."""
    numbers = [_number(v) for v in value] if isinstance(value, list) else []
    return [] if None in numbers else [n for n in numbers if n is not None]


def _buoy_from_feature(index: int, feature: Any) -> WorldBuoy:
    """One feature of the collection as a buoy, or WorldFileError naming the feature and the field."""
    props = feature.get("properties") if isinstance(feature, dict) else None
    buoy_id = props.get("id") if isinstance(props, dict) else None
    where = f"feature {index}" + (f" ({buoy_id})" if isinstance(buoy_id, str) else "")

    def fail(field: str, why: str) -> WorldFileError:
        return WorldFileError(f"{where}: {field} {why}")

    if not isinstance(feature, dict) or feature.get("type") != "Feature":
        raise fail("type", "must be 'Feature'")
    geometry = feature.get("geometry")
    if not isinstance(geometry, dict) or geometry.get("type") != "Point":
        raise fail("geometry", "must be a Point (the buoy's charted position)")
    coordinates = geometry.get("coordinates")
    lon_lat = _numbers(coordinates)  # GeoJSON's order; a third number, an altitude, is ignored
    if len(lon_lat) not in (2, 3):
        raise fail("coordinates", f"must be [lon, lat] as finite numbers, got {coordinates!r}")
    lon, lat = lon_lat[:2]
    try:
        check_lat_lon(lat, lon, "position")
    except CoordinateError as error:
        raise fail("coordinates", f"[lon, lat] = {coordinates}: {error}") from None
    if not isinstance(props, dict):
        raise fail("properties", "must be an object with at least id and kind")
    if unknown := sorted(set(props) - set(PROPERTIES)):
        raise fail("properties", f"{', '.join(unknown)} unknown: expected among {', '.join(PROPERTIES)}")
    if not isinstance(buoy_id, str) or not buoy_id.strip():
        raise fail("id", f"must be a non-empty string, got {buoy_id!r}")
    kind = props.get("kind")
    if kind not in KINDS:
        raise fail("kind", f"{kind!r} is not one of {', '.join(KINDS)}")

    def character(field: str, text: Any) -> LightCharacter:
        if not isinstance(text, str):
            raise fail(field, f"must be a light character's chart text, got {text!r}")
        try:
            light = parse(text)
        except LightCharacterError as error:
            raise fail(field, f"{text!r}: {error}") from None
        if light.cycle_s is None:  # e.g. "Q(3) W": a group needs its period before it can be simulated
            raise fail(field, f"{text!r} has no period: give one, e.g. {text} 10s")
        return light

    light = None if props.get("light") is None else character("light", props["light"])
    radius = _number(props.get("swing_radius_m", DEFAULT_SWING_RADIUS_M))
    if radius is None or radius < 0:
        raise fail("swing_radius_m", f"must be a finite number >= 0 (0: a beacon), got {props['swing_radius_m']!r}")
    shows = props.get("shows")
    if shows is None:
        actual = light
    else:
        actual = None if isinstance(shows, str) and shows.strip().lower() == DARK else character("shows", shows)
    offset = props.get("offset_m", [0.0, 0.0])
    north_east = _numbers(offset)
    if len(north_east) != 2:
        raise fail("offset_m", f"must be [north, east] as two finite numbers (metres), got {offset!r}")
    north, east = north_east
    mmsi = props.get("mmsi")
    if mmsi is not None and (isinstance(mmsi, bool) or not isinstance(mmsi, int) or mmsi not in MMSI_RANGE):
        raise fail("mmsi", f"must be a 9-digit integer (an AtoN's is 99MIDxxxx), got {mmsi!r}")
    region = props.get("region", "A")
    if region not in REGIONS:
        raise fail("region", f"must be one of {', '.join(REGIONS)} (IALA buoyage regions), got {region!r}")
    return WorldBuoy(buoy_id, kind, (lat, lon), light, radius, actual, (north, east), mmsi, region)


# The swing model. The drag of water and wind on a buoy, 0.5 rho Cd A v^2 with Cd ~ 1, for a typical buoy
# (1.5 m wide, 1 m under water, 2 m above): the current's coefficient is ~400 times the wind's, so the current
# dominates (1 m/s of current pulls as hard as 20 m/s of wind). The chain lifts off the seabed as the pull grows:
# the buoy's distance from its mooring approaches the swing radius as 1 - exp(-F / CHAIN_LIFT_N).
CURRENT_DRAG_N_S2_M2 = 0.5 * 1025.0 * 1.0 * 1.5
WIND_DRAG_N_S2_M2 = 0.5 * 1.225 * 1.0 * 3.0
CHAIN_LIFT_N = 500.0  # the pull that takes a buoy to 63 % of its swing radius (a 0.8 m/s current)
WANDER_SHARE = 0.3  # gusts and waves: the wander's share of the slack the pull leaves
WANDER_PERIODS_S = (20.0, 120.0)
WANDER_TERMS = 3  # sinusoids per axis


@dataclass(frozen=True)
class World:
    """The simulated world's buoys; seed fixes each buoy's wander in its swing circle."""

    buoys: tuple[WorldBuoy, ...]
    seed: int = 0

    @classmethod
    def from_geojson(cls, obj: Any, seed: int | None = None) -> World:
        """The world a GeoJSON FeatureCollection describes (module docstring); WorldFileError if it is not one.
        Features are numbered from 0 in the messages. seed: the wander's, else the collection's "seed", else 0."""
        if (
            not isinstance(obj, dict)
            or obj.get("type") != "FeatureCollection"
            or not isinstance(obj.get("features"), list)
        ):
            raise WorldFileError(
                "a world file is a GeoJSON FeatureCollection: {'type': 'FeatureCollection', 'features': [...]}"
            )
        buoys: list[WorldBuoy] = []
        seen: dict[str, int] = {}
        seen_mmsi: dict[int, int] = {}
        for index, feature in enumerate(obj["features"]):
            buoy = _buoy_from_feature(index, feature)
            if buoy.id in seen:
                raise WorldFileError(
                    f"feature {index} ({buoy.id}): id {buoy.id!r} is already feature {seen[buoy.id]}'s"
                )
            if buoy.mmsi is not None and buoy.mmsi in seen_mmsi:
                raise WorldFileError(
                    f"feature {index} ({buoy.id}): mmsi {buoy.mmsi} is already feature {seen_mmsi[buoy.mmsi]}'s"
                )
            seen[buoy.id] = index
            if buoy.mmsi is not None:
                seen_mmsi[buoy.mmsi] = index
            buoys.append(buoy)
        file_seed = obj.get("seed", 0)
        if isinstance(file_seed, bool) or not isinstance(file_seed, int):
            raise WorldFileError(f"seed must be an integer, got {file_seed!r}")
        return cls(tuple(buoys), file_seed if seed is None else seed)

    def to_geojson(self) -> dict[str, Any]:
        """The world as its file's GeoJSON (load_world(w.to_geojson()) == w); faults and an MMSI written only where
        present."""
        features = []
        for b in self.buoys:
            light = None if b.light is None else b.light.abbreviation()
            props: dict[str, Any] = {"id": b.id, "kind": b.kind, "light": light, "swing_radius_m": b.swing_radius_m}
            if b.actual_light != b.light:
                props["shows"] = DARK if b.actual_light is None else b.actual_light.abbreviation()
            if b.offset_m != (0.0, 0.0):
                props["offset_m"] = list(b.offset_m)
            if b.mmsi is not None:
                props["mmsi"] = b.mmsi
            if b.region != "A":
                props["region"] = b.region
            point = {"type": "Point", "coordinates": [b.charted[1], b.charted[0]]}
            features.append({"type": "Feature", "geometry": point, "properties": props})
        return {"type": "FeatureCollection", "seed": self.seed, "features": features}

    @classmethod
    def default(cls, buoys_lat_lon: ArrayLike, ids: Sequence[str]) -> World:
        """A world without faults for the demo's buoys: the first safe water, then starboard and port by turns,
        every sixth a cardinal (north, east, south, west in turn); each with its kind's default light."""
        lat_lons = _lat_lons(buoys_lat_lon, ids)
        return cls(tuple(_lit_buoy(buoy_id, _default_kind(i), lat_lons[i]) for i, buoy_id in enumerate(ids)))

    @classmethod
    def random(
        cls,
        seed: int,
        buoys_lat_lon: ArrayLike,
        ids: Sequence[str],
        fault_probability: float = 0.2,
        swing_radius_m: float = DEFAULT_SWING_RADIUS_M,
    ) -> World:
        """A seeded world for the benchmark: kinds mostly lateral, some cardinal or special, one safe water and one
        isolated danger (two buoys or more); each with its default light, and with probability fault_probability
        one fault: off station by 2-5 swing radii in any direction, light out, or another character."""
        rng = np.random.default_rng(seed)
        names, weights = zip(*_RANDOM_KIND_WEIGHTS.items(), strict=True)
        kinds = [str(kind) for kind in rng.choice(names, size=len(ids), p=weights)]
        for index, kind in zip(rng.permutation(len(ids)), ("safe_water", "isolated_danger"), strict=False):
            kinds[index] = kind
        buoys = []
        for buoy_id, kind, lat_lon in zip(ids, kinds, _lat_lons(buoys_lat_lon, ids), strict=True):
            buoy = _lit_buoy(buoy_id, kind, lat_lon, swing_radius_m)
            if rng.random() < fault_probability:
                buoy = _with_fault(buoy, rng)
            buoys.append(buoy)
        return cls(tuple(buoys), seed)

    @cached_property
    def _wander(self) -> tuple[np.ndarray, np.ndarray]:
        """Each buoy's wander sinusoids: angular rates and phases, (n, 2, WANDER_TERMS) arrays."""
        rates, phases = [], []
        for b in self.buoys:
            # seeded by the world's seed and the buoy's id: a buoy wanders the same wherever it is in the list
            rng = np.random.default_rng([self.seed, zlib.crc32(b.id.encode())])
            rates.append(2 * np.pi / rng.uniform(*WANDER_PERIODS_S, size=(2, WANDER_TERMS)))
            phases.append(rng.uniform(0, 2 * np.pi, size=(2, WANDER_TERMS)))
        return np.reshape(rates, (-1, 2, WANDER_TERMS)), np.reshape(phases, (-1, 2, WANDER_TERMS))

    @cached_property
    def _moorings(self) -> tuple[np.ndarray, np.ndarray]:
        """Swing radii (n,) and real moorings (n, 2) north, east of the charted positions."""
        return np.array([b.swing_radius_m for b in self.buoys]), np.reshape([b.offset_m for b in self.buoys], (-1, 2))

    def positions(
        self,
        t_s: float,
        wind_from_deg: float = 0.0,
        wind_speed_m_s: float = 0.0,
        current_to_deg: float = 0.0,
        current_speed_m_s: float = 0.0,
    ) -> np.ndarray:
        """Where the buoys float at t_s: (n, 2) [north, east] metres from each one's charted position.

        Each sits in its swing circle around its real mooring: pulled by the combined drag of current (towards
        current_to_deg) and wind (from wind_from_deg) out to radius * (1 - exp(-F / CHAIN_LIFT_N)), and wandering
        about that in the slack left (WANDER_SHARE of it; a few seeded sinusoids of 20-120 s per axis, their
        amplitudes summing to at most 1 / sqrt 2 each), so it never leaves the circle. Depends on t_s alone.
        """
        wind_to = math.radians(wind_from_deg + 180.0)
        current_to = math.radians(current_to_deg)
        wind_pull = WIND_DRAG_N_S2_M2 * wind_speed_m_s**2
        current_pull = CURRENT_DRAG_N_S2_M2 * current_speed_m_s**2
        pull = wind_pull * np.array([math.cos(wind_to), math.sin(wind_to)])  # (north, east) newtons
        pull += current_pull * np.array([math.cos(current_to), math.sin(current_to)])
        force = float(np.hypot(*pull))
        reach = 1.0 - math.exp(-force / CHAIN_LIFT_N)  # share of the radius the pull takes the buoy to
        direction = pull / force if force > 0 else np.zeros(2)
        rates, phases = self._wander
        wander = np.sin(rates * t_s + phases).sum(axis=2) / (WANDER_TERMS * math.sqrt(2))  # |wander| <= 1
        radii, moorings = self._moorings
        swing = reach * direction + WANDER_SHARE * (1.0 - reach) * wander
        return moorings + radii[:, None] * swing

    def positions_lat_lon(self, t_s: float, *environment: float) -> np.ndarray:
        """positions() as (n, 2) [lat, lon] degrees (same environment arguments after t_s)."""
        if not self.buoys:
            return np.empty((0, 2))
        frame, charted_en = self._frame
        north_east = self.positions(t_s, *environment)
        return frame.unproject(charted_en + north_east[:, ::-1])

    @cached_property
    def _frame(self) -> tuple[LocalFrame, np.ndarray]:
        # one tangent plane at the first buoy: over a harbour's few km it bends metre offsets by far under a mm
        frame = LocalFrame(*self.buoys[0].charted)
        return frame, frame.project(np.array([b.charted for b in self.buoys]))


def load_world(source: str | os.PathLike[str] | Mapping[str, Any], seed: int | None = None) -> World:
    """The world of a GeoJSON file: a path, the text itself (it starts with "{"), or the parsed object."""
    if isinstance(source, Mapping):
        return World.from_geojson(dict(source), seed)
    if isinstance(source, str) and source.lstrip().startswith("{"):
        text = source
    else:
        text = Path(source).read_text(encoding="utf-8")
    try:
        obj = json.loads(text)
    except json.JSONDecodeError as error:
        raise WorldFileError(f"not JSON: {error}") from None
    return World.from_geojson(obj, seed)


# The kinds of a random world, by weight: mostly lateral, some of each cardinal and special mark.
_RANDOM_KIND_WEIGHTS = {"port": 0.35, "starboard": 0.35, **dict.fromkeys(CARDINALS, 0.06), "special": 0.06}
OFF_STATION_RADII = (2.0, 5.0)
FAULTS = ("off_station", "light_out", "wrong_character")
_QUICK_SWAP = {"Q": "VQ", "VQ": "Q", "Q+LFl": "VQ+LFl", "VQ+LFl": "Q+LFl"}


def _lat_lons(buoys_lat_lon: ArrayLike, ids: Sequence[str]) -> list[tuple[float, float]]:
    lat_lons = np.asarray(buoys_lat_lon, dtype=float).reshape(-1, 2)
    if len(lat_lons) != len(ids) or len(set(ids)) != len(ids):
        raise ValueError(f"{len(lat_lons)} positions for {len(ids)} ids, which must be as many and unique")
    return [(float(lat), float(lon)) for lat, lon in lat_lons]


def _default_kind(index: int) -> str:
    if index == 0:
        return "safe_water"
    return CARDINALS[(index // 6) % 4] if index % 6 == 5 else ("port" if index % 2 else "starboard")


def _lit_buoy(
    buoy_id: str, kind: str, lat_lon: tuple[float, float], radius: float = DEFAULT_SWING_RADIUS_M
) -> WorldBuoy:
    light = default_light(kind)
    return WorldBuoy(buoy_id, kind, lat_lon, light, radius, light)


def _other_characters(light: LightCharacter) -> list[LightCharacter]:
    """Characters a faulty lantern may show instead: one more flash per group, twice the period, or quick for very
    quick (and back); only those that can be shown."""
    candidates = []
    groups = (light.groups[0] + 1,) if len(light.groups) == 1 else (2,) if light.period_s else None
    period = None if light.period_s is None else 2 * light.period_s
    changes: list[dict[str, Any]] = [{"groups": groups}, {"period_s": period}, {"kind": _QUICK_SWAP.get(light.kind)}]
    for change in changes:
        if None in change.values():
            continue
        try:
            other = replace(light, **change)
        except LightCharacterError:
            continue
        if other.cycle_s is not None and other != light:
            candidates.append(other)
    return candidates


def _with_fault(buoy: WorldBuoy, rng: np.random.Generator) -> WorldBuoy:
    """The buoy with one fault of FAULTS, drawn at random."""
    others = _other_characters(buoy.light) if buoy.light else []
    possible = ["off_station", *(["light_out"] if buoy.light else []), *(["wrong_character"] if others else [])]
    fault = possible[rng.integers(len(possible))]
    if fault == "off_station":
        distance = rng.uniform(*OFF_STATION_RADII) * buoy.swing_radius_m
        bearing = rng.uniform(0, 2 * np.pi)
        return replace(buoy, offset_m=(distance * math.cos(bearing), distance * math.sin(bearing)))
    if fault == "light_out":
        return replace(buoy, actual_light=None)
    return replace(buoy, actual_light=others[rng.integers(len(others))])
