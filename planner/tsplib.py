"""TSPLIB instances: parsing `.tsp` / `.opt.tour` text and TSPLIB's own integer distance functions.

The distance functions follow Reinelt's TSPLIB 95 document exactly (nint rounding for EUC_2D, rounding up for
CEIL_2D, the pseudo-Euclidean ATT, and GEO on an idealised sphere with degrees.minutes coordinates), so tour
lengths compare exactly with the published optima.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from planner.errors import InputError

SUPPORTED_EDGE_WEIGHT_TYPES = ("EUC_2D", "CEIL_2D", "ATT", "GEO")


@dataclass(frozen=True)
class TsplibInstance:
    """A symmetric TSPLIB instance given by node coordinates."""

    name: str
    edge_weight_type: str
    coords: np.ndarray  # (n, 2) as written in the file (x, y; for GEO: latitude, longitude in DDD.MM)

    def distance_matrix(self) -> np.ndarray:
        return tsplib_distance_matrix(self.coords, self.edge_weight_type)


def _nint(x: np.ndarray) -> np.ndarray:
    return np.floor(x + 0.5)


def _geo_radians(coord: np.ndarray) -> np.ndarray:
    # DDD.MM: the integer part is degrees, the fraction is minutes / 100 (TSPLIB 95, section 2.4).
    pi = 3.141592  # TSPLIB's own value of pi, which the published GEO optima use
    degrees = np.trunc(coord)
    minutes = coord - degrees
    return pi * (degrees + 5.0 * minutes / 3.0) / 180.0


def tsplib_distance_matrix(coords: np.ndarray, edge_weight_type: str) -> np.ndarray:
    """The integer distance matrix (as floats) TSPLIB defines for these coordinates."""
    coords = np.asarray(coords, dtype=float)
    x, y = coords[:, 0], coords[:, 1]
    dx = x[:, None] - x[None, :]
    dy = y[:, None] - y[None, :]
    if edge_weight_type == "EUC_2D":
        dist = _nint(np.sqrt(dx**2 + dy**2))
    elif edge_weight_type == "CEIL_2D":
        dist = np.ceil(np.sqrt(dx**2 + dy**2))
    elif edge_weight_type == "ATT":
        r = np.sqrt((dx**2 + dy**2) / 10.0)
        t = _nint(r)
        dist = np.where(t < r, t + 1.0, t)
    elif edge_weight_type == "GEO":
        lat, lon = _geo_radians(x), _geo_radians(y)
        earth_radius = 6378.388
        q1 = np.cos(lon[:, None] - lon[None, :])
        q2 = np.cos(lat[:, None] - lat[None, :])
        q3 = np.cos(lat[:, None] + lat[None, :])
        arc = np.arccos(np.clip(0.5 * ((1.0 + q1) * q2 - (1.0 - q1) * q3), -1.0, 1.0))
        dist = np.trunc(earth_radius * arc + 1.0)
    else:
        raise InputError(
            f"EDGE_WEIGHT_TYPE {edge_weight_type} is not supported (use one of "
            f"{', '.join(SUPPORTED_EDGE_WEIGHT_TYPES)})"
        )
    np.fill_diagonal(dist, 0.0)
    return dist


def _split_header(line: str) -> tuple[str, str]:
    key, _, value = line.partition(":")
    return key.strip().upper(), value.strip()


def parse_tsp(text: str) -> TsplibInstance:
    """Parse a TSPLIB `.tsp` file's text (TYPE TSP, NODE_COORD_SECTION). Raises InputError if unusable."""
    header: dict[str, str] = {}
    coords: list[tuple[float, float]] = []
    in_coords = False
    for number, raw in enumerate(text.splitlines(), start=1):
        line = raw.strip()
        if not line:
            continue
        if line == "EOF":
            break
        if in_coords:
            fields = line.split()
            if len(fields) < 3:
                raise InputError(f"line {number}: expected 'index x y' in NODE_COORD_SECTION, got {line!r}")
            try:
                coords.append((float(fields[1]), float(fields[2])))
            except ValueError:
                raise InputError(f"line {number}: coordinates are not numbers: {line!r}") from None
            continue
        if line.upper().startswith("NODE_COORD_SECTION"):
            in_coords = True
            continue
        if line.upper().endswith("_SECTION"):
            raise InputError(f"line {number}: {line} is not supported (only NODE_COORD_SECTION)")
        key, value = _split_header(line)
        header[key] = value
    if header.get("TYPE", "TSP").split()[0].upper() != "TSP":
        raise InputError(f"TSPLIB TYPE {header['TYPE']} is not supported (only symmetric TSP)")
    weight_type = header.get("EDGE_WEIGHT_TYPE", "").upper()
    if weight_type not in SUPPORTED_EDGE_WEIGHT_TYPES:
        raise InputError(
            f"EDGE_WEIGHT_TYPE {weight_type or '(missing)'} is not supported (use one of "
            f"{', '.join(SUPPORTED_EDGE_WEIGHT_TYPES)})"
        )
    if not coords:
        raise InputError("the TSPLIB file has no NODE_COORD_SECTION entries")
    if "DIMENSION" in header and header["DIMENSION"].isdigit() and int(header["DIMENSION"]) != len(coords):
        raise InputError(f"DIMENSION says {header['DIMENSION']} nodes but {len(coords)} are listed")
    array = np.asarray(coords)
    if not np.all(np.isfinite(array)):
        raise InputError("the TSPLIB file has non-finite coordinates")
    return TsplibInstance(name=header.get("NAME", "unnamed"), edge_weight_type=weight_type, coords=array)


def parse_tour(text: str) -> list[int]:
    """Parse a TSPLIB `.tour` file's TOUR_SECTION into 0-based node indices."""
    order: list[int] = []
    in_tour = False
    for raw in text.splitlines():
        line = raw.strip()
        if line.upper().startswith("TOUR_SECTION"):
            in_tour = True
            continue
        if not in_tour or not line:
            continue
        for field in line.split():
            node = int(field)
            if node == -1:
                return order
            order.append(node - 1)
    return order
