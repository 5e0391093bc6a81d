"""WGS84 <-> local tangent plane conversions, the one place the project does geodesy.

Everything inside the system works in metres on a local tangent plane at an origin (the depot, which is
also the vehicle's home). pymap3d does the ellipsoid maths; this module only fixes the conventions:
ENU (x east, y north, z up) for planning and maps, NED (x north, y east, z down) for MAVLink's
LOCAL_POSITION_NED and the vehicle's physics.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import pymap3d
from numpy.typing import ArrayLike

# Default home: the depot, on a pier in the approaches to Dalian harbour (the paper's authors' port).
DEFAULT_HOME = (38.9210, 121.6630, 0.0)  # lat deg, lon deg, alt m AMSL


class CoordinateError(ValueError):
    """A latitude/longitude that is not a place on the ellipsoid (the message names the point)."""


def check_lat_lon(lat: float, lon: float, where: str = "point") -> None:
    """Raise CoordinateError unless lat/lon are finite and in range."""
    if not (math.isfinite(lat) and math.isfinite(lon)):
        raise CoordinateError(f"{where}: latitude and longitude must be finite numbers, got ({lat}, {lon})")
    if not -90.0 <= lat <= 90.0:
        raise CoordinateError(f"{where}: latitude {lat} is outside [-90, 90]")
    if not -180.0 <= lon <= 180.0:
        raise CoordinateError(f"{where}: longitude {lon} is outside [-180, 180]")


@dataclass(frozen=True)
class LocalFrame:
    """A local tangent plane at (lat0, lon0, alt0) on the WGS84 ellipsoid."""

    lat0: float
    lon0: float
    alt0: float = 0.0

    def __post_init__(self) -> None:
        check_lat_lon(self.lat0, self.lon0, "origin")

    def to_enu(self, lat, lon, alt=0.0):
        """Geodetic degrees/metres -> (east, north, up) metres. Accepts scalars or arrays."""
        return pymap3d.geodetic2enu(lat, lon, alt, self.lat0, self.lon0, self.alt0)

    def from_enu(self, east, north, up=0.0):
        """(east, north, up) metres -> (lat, lon, alt)."""
        return pymap3d.enu2geodetic(east, north, up, self.lat0, self.lon0, self.alt0)

    def to_ned(self, lat, lon, alt=0.0):
        """Geodetic -> (north, east, down) metres, MAVLink's LOCAL_POSITION_NED frame."""
        e, n, u = self.to_enu(lat, lon, alt)
        return n, e, -u

    def from_ned(self, north, east, down=0.0):
        """(north, east, down) metres -> (lat, lon, alt)."""
        return self.from_enu(east, north, -down)

    def project(self, lat_lon: ArrayLike) -> np.ndarray:
        """An (n, 2) array of [lat, lon] -> an (n, 2) array of [east, north] metres."""
        lat_lon = np.asarray(lat_lon, dtype=float)
        e, n, _ = self.to_enu(lat_lon[:, 0], lat_lon[:, 1], np.full(len(lat_lon), self.alt0))
        return np.column_stack([e, n])

    def unproject(self, east_north: ArrayLike) -> np.ndarray:
        """An (n, 2) array of [east, north] metres -> an (n, 2) array of [lat, lon]."""
        east_north = np.asarray(east_north, dtype=float)
        lat, lon, _ = self.from_enu(east_north[:, 0], east_north[:, 1], np.zeros(len(east_north)))
        return np.column_stack([lat, lon])
