"""Where a camera frame's pixels lie on the sea, and where sea points land in the frame. Pure computation.

The pinhole model of MAVLink's camera protocol: CAMERA_INFORMATION gives the lens and the sensor
(focal_length, sensor_size_h/v in mm, resolution_h/v in px), CAMERA_IMAGE_CAPTURED each frame's geotag
(position, the camera's height above home, and its attitude q, camera frame -> NED).

Conventions (those of the simulator's renderer, which the tests use as the oracle):
- camera frame FRD: x forward along the optical axis, y right, z down; q = (w, x, y, z) rotates it into NED,
  so the identity looks level to the north;
- pixels (u, v) = (column, row), integers at pixel centres, the principal point at the image centre: a
  camera-frame direction (x, y, z), x > 0, lands at u = cx + fx y / x, v = cy + fy z / x (no distortion);
- the sea is the plane at the home's altitude: a ray from height h with unit down-component d meets it h / d
  away. Near the horizon that plane is wrong (the Earth curves away): a ray at or above the dipped horizon,
  acos(R / (R + h)) below level, has no sea point.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from uavcore.geodesy import LocalFrame
from uavcore.rotation import matrix_from_quat

EARTH_RADIUS_M = 6_371_000.0


@dataclass(frozen=True)
class CameraModel:
    """A pinhole camera from CAMERA_INFORMATION's figures; focal lengths and principal point in pixels."""

    width_px: int
    height_px: int
    focal_length_mm: float
    sensor_width_mm: float  # of the area read out at this resolution
    sensor_height_mm: float

    @property
    def fx(self) -> float:
        return self.focal_length_mm / self.sensor_width_mm * self.width_px

    @property
    def fy(self) -> float:
        return self.focal_length_mm / self.sensor_height_mm * self.height_px

    @property
    def cx(self) -> float:
        return (self.width_px - 1) / 2  # the centre of the middle pixel: pixel centres are integers

    @property
    def cy(self) -> float:
        return (self.height_px - 1) / 2

    def contains(self, u: float, v: float) -> bool:
        """Whether pixel (u, v) lies inside the frame (pixel centres run 0 .. width - 1)."""
        return -0.5 <= u < self.width_px - 0.5 and -0.5 <= v < self.height_px - 0.5


@dataclass(frozen=True)
class FrameGeotag:
    """Where a frame was taken: the camera's position, height above the sea, attitude and capture time."""

    lat: float  # degrees
    lon: float
    height_m: float  # above the sea surface (CAMERA_IMAGE_CAPTURED.relative_alt: the home is at sea level)
    attitude: tuple[float, float, float, float]  # (w, x, y, z), camera FRD -> NED
    t_s: float  # capture time (time_boot_ms / 1000)
    image_index: int = 0

    @classmethod
    def from_capture(
        cls, lat_e7: int, lon_e7: int, relative_alt_mm: int, q: Sequence[float], time_boot_ms: int, image_index: int
    ) -> FrameGeotag:
        """From CAMERA_IMAGE_CAPTURED's fields."""
        w, x, y, z = (float(c) for c in q)
        return cls(lat_e7 / 1e7, lon_e7 / 1e7, relative_alt_mm / 1000, (w, x, y, z), time_boot_ms / 1000, image_index)

    def rotation(self) -> np.ndarray:
        """The 3x3 matrix taking camera-frame vectors to NED (of the normalised quaternion)."""
        return matrix_from_quat(self.attitude)

    def local_frame(self) -> LocalFrame:
        """The tangent plane at the camera's foot: geolocation works in metres from there."""
        return LocalFrame(self.lat, self.lon)


def sin_horizon_dip(height_m: float) -> float:
    """Sine of the angle the sea horizon lies below level from height_m over a spherical Earth."""
    return math.sqrt(max(0.0, 1 - (EARTH_RADIUS_M / (EARTH_RADIUS_M + height_m)) ** 2))


def pixel_ray_ned(model: CameraModel, geotag: FrameGeotag, u: float, v: float) -> np.ndarray:
    """The unit NED direction of the ray through pixel (u, v): R (1, (u - cx)/fx, (v - cy)/fy), normalised."""
    ray = geotag.rotation() @ np.array([1.0, (u - model.cx) / model.fx, (v - model.cy) / model.fy])
    return ray / np.linalg.norm(ray)


def pixel_to_sea_ne(model: CameraModel, geotag: FrameGeotag, u: float, v: float) -> np.ndarray | None:
    """[north, east] metres from the camera's foot where the pixel's ray meets the sea; None at or above the
    horizon (the ray's down-component no more than the dip's sine) or for a camera not above the sea."""
    north, east, down = pixel_ray_ned(model, geotag, u, v)
    if geotag.height_m <= 0 or down <= sin_horizon_dip(geotag.height_m):
        return None
    return np.array([north, east]) * (geotag.height_m / down)


def pixel_to_sea(model: CameraModel, geotag: FrameGeotag, u: float, v: float) -> tuple[float, float] | None:
    """(lat, lon) where the pixel's ray meets the sea, None for a pixel showing sky (pixel_to_sea_ne)."""
    north_east = pixel_to_sea_ne(model, geotag, u, v)
    if north_east is None:
        return None
    lat, lon = geotag.local_frame().unproject(north_east[None, ::-1])[0]
    return float(lat), float(lon)


def ned_to_pixel(
    model: CameraModel, geotag: FrameGeotag, north_east_down: Sequence[float]
) -> tuple[float, float] | None:
    """The pixel of a point given in NED metres from the camera's foot on the sea (down = -height above the
    sea); None behind the camera. The pixel may lie outside the frame (CameraModel.contains says)."""
    relative = np.asarray(north_east_down, dtype=float) + np.array([0.0, 0.0, geotag.height_m])
    x, y, z = geotag.rotation().T @ relative  # R is orthonormal: its transpose takes NED to the camera frame
    if x <= 1e-9:
        return None
    return model.cx + model.fx * y / x, model.cy + model.fy * z / x


def sea_to_pixel(
    model: CameraModel, geotag: FrameGeotag, lat: float, lon: float, height_m: float = 0.0
) -> tuple[float, float] | None:
    """The pixel of the point height_m above the sea at (lat, lon); None behind the camera."""
    north, east = lat_lon_to_ne(geotag, lat, lon)
    return ned_to_pixel(model, geotag, (north, east, -height_m))


def lat_lon_to_ne(geotag: FrameGeotag, lat: float, lon: float) -> np.ndarray:
    """[north, east] metres of (lat, lon) from the camera's foot."""
    east, north = geotag.local_frame().project(np.array([[lat, lon]]))[0]
    return np.array([north, east])


def ne_to_lat_lon(geotag: FrameGeotag, north_east: Sequence[float] | np.ndarray) -> tuple[float, float]:
    """(lat, lon) of a point [north, east] metres from the camera's foot."""
    lat, lon = geotag.local_frame().unproject(np.array([[north_east[1], north_east[0]]]))[0]
    return float(lat), float(lon)
