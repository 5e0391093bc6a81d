"""Camera bursts of one buoy, as the ground station would receive them: frames rendered by the simulator's camera
from a `uavcore.buoy_world` world, JPEG-encoded and decoded, each with its CAMERA_IMAGE_CAPTURED-style geotag.
Shared by tests/test_inspection_analysis.py and bench/inspection_analysis.py.

The camera hovers `height_m` above the sea, `range_m` from the buoy's CHARTED position on `bearing_deg` (from
the buoy to the camera), aimed at that charted position as a region-of-interest command would aim it. The burst
runs at burst_for(charted light)'s rate and duration (or a given number of frames); the buoy swings per
World.positions and its light follows WorldBuoy.light_on / light_colour.
"""

from __future__ import annotations

import io
import math
from dataclasses import dataclass, field

import numpy as np
from PIL import Image

from gcs.domain.camera_geometry import CameraModel, FrameGeotag
from sitl_quad.camera_render import CameraPose, Intrinsics, RenderedBuoy, Scene, encode_jpeg, render
from uavcore.buoy_world import LIGHT_RGB, PAINT_RGB, World, WorldBuoy
from uavcore.geodesy import DEFAULT_HOME, LocalFrame
from uavcore.light_character import burst_for

HOME = LocalFrame(DEFAULT_HOME[0], DEFAULT_HOME[1])
SENSOR_WIDTH_MM, FOCAL_LENGTH_MM = 6.17, 4.5  # the simulator's default 1/2.3" camera


def camera_model(width_px: int = 960, height_px: int = 540) -> CameraModel:
    """The default camera's lens and sensor width read out at this resolution (square pixels)."""
    return CameraModel(width_px, height_px, FOCAL_LENGTH_MM, SENSOR_WIDTH_MM, SENSOR_WIDTH_MM * height_px / width_px)


def rendered_buoy(buoy: WorldBuoy, north_east: np.ndarray, t_s: float) -> RenderedBuoy:
    """The world buoy as the renderer draws it at t_s, its waterline centre at north_east (HOME's NED)."""
    look = buoy.appearance
    colour = buoy.light_colour(t_s)
    return RenderedBuoy(
        (float(north_east[0]), float(north_east[1])),
        tuple(PAINT_RGB[c] for c in look.colours),
        look.shape,
        look.height_m,
        look.diameter_m,
        look.pattern == "vertical",
        look.topmark,
        PAINT_RGB[look.topmark_colour],
        LIGHT_RGB[colour] if colour is not None and buoy.light_on(t_s) else None,
    )


@dataclass(frozen=True)
class Shot:
    """One received frame: the decoded JPEG, its geotag, and the truth (the target's waterline centre, HOME NED)."""

    image: np.ndarray
    geotag: FrameGeotag
    true_north_east: np.ndarray | None  # None: the target is not in the world drawn (a frame with no buoy)


@dataclass(frozen=True)
class Burst:
    """The camera's burst of one buoy and what the station knows of the camera."""

    model: CameraModel
    shots: list[Shot] = field(default_factory=list)


def charted_ne(buoy: WorldBuoy) -> np.ndarray:
    """The buoy's charted position, HOME NED metres [north, east]."""
    east, north = HOME.project(np.array([buoy.charted]))[0]
    return np.array([north, east])


def capture_burst(
    world: World,
    target: int,
    range_m: float,
    bearing_deg: float,
    *,
    height_m: float = 5.0,
    resolution: tuple[int, int] = (960, 540),
    frames: int | None = None,
    t0_s: float = 100.0,
    sea_seed: int = 1,
    jpeg_quality: int = 85,
    hide_target: bool = False,
    yaw_offset_deg: float = 0.0,
    pitch_offset_deg: float = 0.0,
) -> Burst:
    """The burst of world.buoys[target] (module docstring); frames: that many at the burst's rate instead of its
    full duration; hide_target: the target is not drawn (the other buoys are); yaw_offset_deg: the camera turned
    that far right of the buoy (the buoy at the frame's edge, or out of it); pitch_offset_deg: the camera raised
    that far above it (the buoy at the frame's bottom edge)."""
    buoy = world.buoys[target]
    duration_s, rate_hz = burst_for(buoy.light)
    count = frames if frames is not None else math.ceil(duration_s * rate_hz)
    aim = charted_ne(buoy)
    bearing = math.radians(bearing_deg)
    camera_ne = aim + range_m * np.array([math.cos(bearing), math.sin(bearing)])
    look = aim - camera_ne
    pose = CameraPose.from_euler(
        (camera_ne[0], camera_ne[1], -height_m),
        0.0,
        -math.atan2(height_m, range_m) + math.radians(pitch_offset_deg),
        math.atan2(look[1], look[0]) + math.radians(yaw_offset_deg),
    )
    intrinsics = Intrinsics.from_sensor(
        *resolution, FOCAL_LENGTH_MM, SENSOR_WIDTH_MM, SENSOR_WIDTH_MM * resolution[1] / resolution[0]
    )
    lat, lon, _ = HOME.from_ned(camera_ne[0], camera_ne[1])
    charted = np.array([charted_ne(b) for b in world.buoys])
    burst = Burst(camera_model(*resolution))
    for k in range(count):
        t_s = t0_s + k / rate_hz
        positions = charted + world.positions(t_s)
        drawn = [
            rendered_buoy(b, positions[i], t_s) for i, b in enumerate(world.buoys) if not (hide_target and i == target)
        ]
        frame = render(pose, intrinsics, Scene(drawn, sea_seed=sea_seed, t_s=t_s))
        image = np.asarray(Image.open(io.BytesIO(encode_jpeg(frame, jpeg_quality))).convert("RGB"))
        geotag = FrameGeotag(float(lat), float(lon), height_m, pose.attitude, t_s, k)
        burst.shots.append(Shot(image, geotag, None if hide_target else positions[target]))
    return burst
