"""A gimbal camera's frames rendered from the true pose: sky, sea with moving clutter, buoys with their bands,
topmarks and lights; and the pinhole projection (`project`, `pixel_to_sea`) the ground station's
geolocation is tested against. Pure computation: numpy for the per-pixel work, Pillow for polygon filling.

Conventions
- World: local NED in metres with the sea surface at down = 0 (a camera 5 m above the sea has down = -5).
- Camera body: FRD, x forward along the optical axis, y right, z down. `CameraPose.attitude` is the unit
  quaternion (w, x, y, z) rotating camera-body vectors into NED, v_ned = R(q) v_cam (uavcore.rotation's
  convention for the vehicle body): (1, 0, 0, 0) looks level to the north; ZYX Euler pitch -15 deg looks 15 deg
  down; roll +10 deg turns the right of the frame down, so the horizon rises on the right.
- Pixels: (u, v) = (column, row), u right and v down, integers at pixel centres; a camera-frame point
  (x, y, z) with x > 0 lands at u = cx + fx y / x, v = cy + fy z / x (no lens distortion).
- Sea: a plane for projection and geolocation. The Earth's curvature only where it shows: the horizon is
  drawn dipped by acos(R / (R + h)) below level (1.3 mrad at 5 m, 5.6 mrad at 100 m: pixels at fx ~ 1000),
  buoys sink by d^2 / 2R (0.8 mm at 100 m, so `project` of the plane point agrees with the drawing), their
  part below the horizon is cut away and buoys past it altogether, sqrt(2Rh) + sqrt(2R h_top), are not drawn.
"""

from __future__ import annotations

import functools
import io
import itertools
import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np
from PIL import Image, ImageDraw

from uavcore.rotation import matrix_from_quat, quat_from_euler

RGB = tuple[int, int, int]
Outline = tuple[Sequence[float], Sequence[float]]  # knots of a solid of revolution: heights (m), radii (m)
EARTH_RADIUS_M = 6_371_000.0
GRAVITY_M_S2 = 9.81
SHAPES = ("can", "cone", "pillar", "spar", "sphere")
TOPMARKS = (
    "none", "can", "cone", "cones_up", "cones_down", "cones_base_to_base", "cones_point_to_point",
    "two_spheres", "sphere", "x",
)  # fmt: skip
LANTERN_RADIUS_M = 0.1  # the glow's core at full size; never smaller than MIN_LIGHT_RADIUS_PX
MIN_LIGHT_RADIUS_PX = 2.5  # so a light stays a few pixels across at 100 m
RING_ERROR_PX = 0.3  # a horizontal circle is drawn as the polygon whose sides stray at most this far from it
CLUTTER_DOWNSCALE = 4  # the sea's texture is computed on a 1/4 grid and upscaled (it is smooth anyway)
SKY_LUT_BINS = 4096  # colour table bins per unit of sin(elevation); the horizon falls on a bin edge
MAST_RGB: RGB = (55, 55, 55)
# Wave components of the clutter: direction (rad from north), wavelength (m), crest length / wavelength,
# weight. Each moves at its deep-water phase speed sqrt(g L / 2 pi), so the pattern evolves, not just slides.
WAVES = ((0.3, 2.5, 3.0, 0.5), (1.1, 1.1, 2.5, 0.3), (-0.6, 0.5, 2.0, 0.2))


@dataclass(frozen=True)
class Intrinsics:
    """Pinhole camera: image size (px), focal lengths (px) and principal point (px, pixel-centre integers)."""

    width: int
    height: int
    fx: float
    fy: float
    cx: float
    cy: float

    @classmethod
    def from_sensor(
        cls, width_px: int, height_px: int, focal_length_mm: float, sensor_width_mm: float, sensor_height_mm: float
    ) -> Intrinsics:
        """From MAVLink CAMERA_INFORMATION's figures (resolution_h/v, focal_length, sensor_size_h/v), the
        principal point at the image centre. The sensor size is that of the area read out for this resolution."""
        fx = focal_length_mm / sensor_width_mm * width_px
        fy = focal_length_mm / sensor_height_mm * height_px
        return cls(width_px, height_px, fx, fy, (width_px - 1) / 2, (height_px - 1) / 2)

    @property
    def horizontal_fov_rad(self) -> float:
        return 2 * math.atan(self.width / 2 / self.fx)


# A 1/2.3" sensor (6.17 x 4.55 mm) behind a 4.5 mm lens, read out 16:9 (the sensor's full width, 9/16 of it
# high, so pixels stay square): 68.9 deg horizontal, 42.2 deg vertical field of view.
DEFAULT_CAMERA = Intrinsics.from_sensor(1280, 720, 4.5, 6.17, 6.17 * 9 / 16)


@dataclass(frozen=True)
class CameraPose:
    """Camera position (NED m, sea surface at down = 0) and attitude (w, x, y, z), camera FRD -> NED."""

    position_ned: tuple[float, float, float]
    attitude: tuple[float, float, float, float]

    @classmethod
    def from_euler(cls, position_ned: Sequence[float], roll: float, pitch: float, yaw: float) -> CameraPose:
        """From ZYX Euler angles (rad): yaw from north toward east, pitch up positive, roll right-down positive."""
        w, x, y, z = (float(c) for c in quat_from_euler(roll, pitch, yaw))
        north, east, down = (float(c) for c in position_ned)
        return cls((north, east, down), (w, x, y, z))

    @property
    def height_m(self) -> float:
        return -self.position_ned[2]

    def rotation(self) -> np.ndarray:
        """The 3x3 matrix taking camera-FRD vectors to NED."""
        return matrix_from_quat(self.attitude)


@dataclass(frozen=True)
class RenderedBuoy:
    """A buoy as drawn. `bands` top to bottom, each an sRGB triple, share the body's height equally; with
    `vertical_stripes` they alternate round it in 8 sectors instead (safe water). `height_m` is the body's
    height above the waterline, the topmark and its mast standing above; `light_rgb` is None while dark."""

    position_ne: tuple[float, float]  # waterline centre, local NED m
    bands: Sequence[RGB]
    shape: str = "pillar"
    height_m: float = 2.5
    diameter_m: float = 1.2
    vertical_stripes: bool = False
    topmark: str = "none"
    topmark_rgb: RGB = (20, 20, 20)
    light_rgb: RGB | None = None

    def __post_init__(self) -> None:
        if self.shape not in SHAPES or self.topmark not in TOPMARKS or not self.bands:
            raise ValueError(f"buoy: shape {self.shape!r} or topmark {self.topmark!r} unknown, or no bands")


@dataclass(frozen=True)
class Scene:
    """What the camera sees besides its own pose: buoys, the sea's seed and time (the clutter moves with t_s,
    the sensor noise is drawn from both), sky and sea colours, haze, and the camera's imperfections."""

    buoys: Sequence[RenderedBuoy] = ()
    sea_seed: int = 0
    t_s: float = 0.0
    sky_zenith_rgb: RGB = (70, 116, 180)
    sky_horizon_rgb: RGB = (198, 211, 224)
    sea_near_rgb: RGB = (24, 54, 68)
    sea_far_rgb: RGB = (126, 144, 160)  # darker than the sky's horizon colour: the horizon stays a line
    visibility_m: float = 4000.0  # e-folding distance of the haze over sea and buoys
    sea_state: float = 0.6  # clutter strength: 0 glassy, 1 rough with whitecaps
    vignetting: float = 0.2  # brightness lost in the frame's corners
    sensor_noise: float = 2.0  # standard deviation, 8-bit levels


class _Solid(NamedTuple):
    """A frustum on a buoy's vertical axis: heights (m above the waterline), radii (m), colour; `stripes` the
    colours round it by sector (safe water), else empty."""

    z0: float
    z1: float
    r0: float
    r1: float
    rgb: RGB
    stripes: tuple[RGB, ...] = ()


def project(pose: CameraPose, intrinsics: Intrinsics, points_ned: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Pixels (N, 2) of NED points (N, 3), NaN behind the camera, and a mask: in front and inside the frame."""
    camera = (np.asarray(points_ned, dtype=float).reshape(-1, 3) - pose.position_ned) @ pose.rotation()
    ahead = camera[:, 0] > 1e-9
    depth = np.where(ahead, camera[:, 0], np.nan)
    pixels = np.column_stack(
        (intrinsics.cx + intrinsics.fx * camera[:, 1] / depth, intrinsics.cy + intrinsics.fy * camera[:, 2] / depth)
    )
    with np.errstate(invalid="ignore"):
        inside = (
            (pixels[:, 0] >= -0.5)
            & (pixels[:, 0] < intrinsics.width - 0.5)
            & (pixels[:, 1] >= -0.5)
            & (pixels[:, 1] < intrinsics.height - 0.5)
        )
    return pixels, ahead & inside


def pixel_to_sea(pose: CameraPose, intrinsics: Intrinsics, u: float, v: float) -> np.ndarray | None:
    """The [north, east] where the pixel's ray meets the sea plane, or None for a pixel at or above the
    (dipped) horizon, i.e. one the renderer paints as sky."""
    north, east, down = (c[0, 0] for c in _rays(pose.rotation(), intrinsics, np.array([u]), np.array([v])))
    length = math.sqrt(north * north + east * east + down * down)
    if pose.height_m <= 0 or down / length <= _sin_horizon_dip(pose.height_m):
        return None
    reach = pose.height_m / down
    return np.array([pose.position_ned[0] + reach * north, pose.position_ned[1] + reach * east])


def render(pose: CameraPose, intrinsics: Intrinsics, scene: Scene) -> np.ndarray:
    """The camera's frame (H, W, 3) uint8 sRGB: sky, sea, then the buoys far to near, then vignetting and noise."""
    if pose.height_m <= 0:
        raise ValueError(f"camera at down = {pose.position_ned[2]} m: it must be above the sea (down < 0)")
    rotation = pose.rotation()
    image = Image.fromarray(_background(pose, rotation, intrinsics, scene))
    draw = ImageDraw.Draw(image, "RGBA")  # RGBA fills blend: the light's halo
    camera_ne = np.array(pose.position_ned[:2])
    ranges = [float(np.hypot(*(np.array(b.position_ne) - camera_ne))) for b in scene.buoys]
    for index in np.argsort(ranges)[::-1]:  # painter's order: the nearest buoy last, over the others
        _draw_buoy(draw, pose, intrinsics, scene, scene.buoys[index], ranges[index])
    gain = 1 - scene.vignetting * _radius_squared(intrinsics)
    if scene.sensor_noise > 0:
        frame_id = round(scene.t_s * 1000) % 2**63  # the same seed and instant give the same frame
        rng = np.random.default_rng((scene.sea_seed % 2**63, frame_id))
        # Uniform noise of the stated standard deviation: 5x cheaper to draw than Gaussian, alike to a detector.
        noise = (rng.random(gain.shape, dtype=np.float32) - 0.5) * np.float32(scene.sensor_noise * math.sqrt(12))
    else:
        noise = np.zeros_like(gain)
    frame = np.asarray(image, dtype=np.float32) * gain[..., None] + noise[..., None]
    return np.clip(frame, 0, 255).astype(np.uint8)


def encode_jpeg(image: np.ndarray, quality: int = 85) -> bytes:
    """The frame as a baseline JPEG (what a camera would stream or store)."""
    buffer = io.BytesIO()
    Image.fromarray(image).save(buffer, format="JPEG", quality=quality)
    return buffer.getvalue()


# ------------------------------------------------------------------------------------------------ background
def _sin_horizon_dip(height_m: float) -> float:
    """Sine of the angle the sea horizon lies below level, seen from height_m above a spherical Earth."""
    return math.sqrt(max(0.0, 1 - (EARTH_RADIUS_M / (EARTH_RADIUS_M + height_m)) ** 2))


def _rays(
    rotation: np.ndarray, intrinsics: Intrinsics, u: np.ndarray, v: np.ndarray, dtype: type = np.float64
) -> list[np.ndarray]:
    """NED components (north, east, down) of the rays through columns u x rows v, each (len(v), len(u)):
    R (1, (u - cx)/fx, (v - cy)/fy), an outer sum, so a full frame costs one array addition per row of R."""
    y = (u - intrinsics.cx) / intrinsics.fx
    z = (v - intrinsics.cy) / intrinsics.fy
    return [(row[0] + row[1] * y)[None, :].astype(dtype) + (row[2] * z)[:, None].astype(dtype) for row in rotation]


@functools.lru_cache(maxsize=8)
def _inverse_ray_lengths(intrinsics: Intrinsics) -> np.ndarray:
    y = (np.arange(intrinsics.width) - intrinsics.cx) / intrinsics.fx
    z = (np.arange(intrinsics.height) - intrinsics.cy) / intrinsics.fy
    return (1 / np.sqrt(1 + y[None, :] ** 2 + z[:, None] ** 2)).astype(np.float32)


@functools.lru_cache(maxsize=8)
def _radius_squared(intrinsics: Intrinsics) -> np.ndarray:
    """Squared distance from the image centre, 1 in the corners (the vignetting's shape)."""
    u = (np.arange(intrinsics.width) - intrinsics.cx) / (intrinsics.width / 2)
    v = (np.arange(intrinsics.height) - intrinsics.cy) / (intrinsics.height / 2)
    return ((u[None, :] ** 2 + v[:, None] ** 2) / 2).astype(np.float32)


def _blend(a: RGB, b: RGB, weight: np.ndarray) -> np.ndarray:
    """Colours (N, 3) from a (weight 0) to b (weight 1)."""
    start = np.asarray(a, dtype=np.float32)
    return start + (np.asarray(b, dtype=np.float32) - start) * weight[:, None].astype(np.float32)


def _colour_table(scene: Scene, height_m: float, sin_dip: float) -> np.ndarray:
    """Sky and sea colour against q = sin(elevation) + sin(dip), binned SKY_LUT_BINS per unit from q = -1;
    bins below index SKY_LUT_BINS are sea. Both depend on the ray's elevation only: the sky's gradient, and
    the sea's blend toward the haze colour by distance (haze) and by grazing angle (Fresnel: sky reflected)."""
    bins = int((2 + sin_dip) * SKY_LUT_BINS) + 2
    sin_elevation = (np.arange(bins) + 0.5) / SKY_LUT_BINS - 1 - sin_dip
    sin_depression = np.clip(-sin_elevation, 1e-9, 1.0)
    distance = height_m * np.sqrt(1 - sin_depression**2) / sin_depression
    seen_through = np.exp(-distance / scene.visibility_m) * (1 - (1 - sin_depression) ** 5)
    sea = _blend(scene.sea_near_rgb, scene.sea_far_rgb, 1 - seen_through)
    elevation = np.arcsin(np.clip(sin_elevation, 0.0, 1.0))
    sky = _blend(scene.sky_horizon_rgb, scene.sky_zenith_rgb, 1 - np.exp(-elevation / 0.35))
    return np.where((np.arange(bins) < SKY_LUT_BINS)[:, None], sea, sky)


def _value_noise(x: np.ndarray, y: np.ndarray, seed: int) -> np.ndarray:
    """Smooth noise in [0, 1]: hashed random values on the integer lattice, smoothstep-interpolated."""
    x0, y0 = np.floor(x), np.floor(y)
    fx, fy = x - x0, y - y0
    fx, fy = fx * fx * (3 - 2 * fx), fy * fy * (3 - 2 * fy)
    i, j = x0.astype(np.int64), y0.astype(np.int64)
    salt = (seed * 2246822519) & 0xFFFFFFFF

    def lattice(di: int, dj: int) -> np.ndarray:
        h = (((i + di) * 374761393 + (j + dj) * 668265263) ^ salt) & 0xFFFFFFFF
        h = ((h ^ (h >> 13)) * 1274126177) & 0xFFFFFFFF
        return ((h ^ (h >> 16)) & 0xFFFFFF) / float(1 << 24)

    top = lattice(0, 0) + (lattice(1, 0) - lattice(0, 0)) * fx
    bottom = lattice(0, 1) + (lattice(1, 1) - lattice(0, 1)) * fx
    return top + (bottom - top) * fy


def _sea_clutter(pose: CameraPose, rotation: np.ndarray, intrinsics: Intrinsics, scene: Scene) -> np.ndarray:
    """Brightness gain and additive whitecaps (2, H/4, W/4) of the sea: wave streaks (value noise stretched
    along the crests, advected at each wave's speed) where the rays meet the sea, fading with distance (a
    wave's texture is finer than a pixel there). Grey changes only: nothing saturated that could pass for a
    buoy. Zero effect on the sky."""
    columns, rows = -(-intrinsics.width // CLUTTER_DOWNSCALE), -(-intrinsics.height // CLUTTER_DOWNSCALE)
    u = (np.arange(columns) + 0.5) * intrinsics.width / columns - 0.5  # low-res pixel centres, full-res units
    v = (np.arange(rows) + 0.5) * intrinsics.height / rows - 0.5
    north, east, down = _rays(rotation, intrinsics, u, v)
    on_sea = down > 1e-6
    reach = np.where(on_sea, pose.height_m / np.where(on_sea, down, 1.0), 0.0)
    north, east = reach * north, reach * east  # from the camera's foot
    fade = np.where(on_sea, np.exp(-np.hypot(north, east) / 80.0), 0.0) * scene.sea_state
    north, east = north + pose.position_ned[0], east + pose.position_ned[1]
    texture = np.zeros_like(north)
    for k, (direction, wavelength, crest_ratio, weight) in enumerate(WAVES):
        along = north * math.cos(direction) + east * math.sin(direction)
        across = east * math.cos(direction) - north * math.sin(direction)
        speed = math.sqrt(GRAVITY_M_S2 * wavelength / (2 * math.pi))
        field = _value_noise(
            (along - speed * scene.t_s) / wavelength, across / (crest_ratio * wavelength), scene.sea_seed + 7919 * k
        )
        texture += weight * (2 * field - 1)
    whitecaps = 220 * np.clip((texture - 0.35) / 0.3, 0, 1) ** 2 * fade
    return np.stack((1 + 0.45 * texture * fade, whitecaps)).astype(np.float32)


def _background(pose: CameraPose, rotation: np.ndarray, intrinsics: Intrinsics, scene: Scene) -> np.ndarray:
    """Sky and sea (H, W, 3) uint8: a colour-table lookup by each ray's elevation, the clutter on top."""
    sin_dip = _sin_horizon_dip(pose.height_m)
    columns, rows = np.arange(intrinsics.width), np.arange(intrinsics.height)
    down = _rays(rotation[2:], intrinsics, columns, rows, np.float32)[0]
    sin_elevation = -down * _inverse_ray_lengths(intrinsics)
    # (q + 1) >= 0 always, so truncation is floor; q < 0 (below the dipped horizon) lands in a sea bin.
    index = ((sin_elevation + np.float32(sin_dip + 1)) * np.float32(SKY_LUT_BINS)).astype(np.int32)
    colours = np.take(_colour_table(scene, pose.height_m, sin_dip), index, axis=0)  # 3x faster than [index]
    size = (intrinsics.width, intrinsics.height)
    gain, whitecaps = (
        np.asarray(Image.fromarray(layer).resize(size, Image.Resampling.BILINEAR))
        for layer in _sea_clutter(pose, rotation, intrinsics, scene)
    )
    colours *= gain[..., None]
    colours += whitecaps[..., None]
    return np.clip(colours, 0, 255).astype(np.uint8)


# ----------------------------------------------------------------------------------------------------- buoys
def _profile_solids(outline: Outline, rgb: RGB, base: float = 0.0) -> list[_Solid]:
    """Frusta between consecutive knots of an outline, raised by base."""
    knots = zip(*outline, strict=True)
    return [_Solid(base + z0, base + z1, r0, r1, rgb) for (z0, r0), (z1, r1) in itertools.pairwise(knots)]


def _sphere_outline(diameter: float, top: float | None = None) -> Outline:
    """Knots of a sphere's outline from height 0, its top at `top` (a floating sphere is partly under water)."""
    top = diameter if top is None else top
    heights = np.linspace(0.0, top, 7)
    centre = top - diameter / 2
    return heights.tolist(), np.sqrt(np.clip((diameter / 2) ** 2 - (heights - centre) ** 2, 0.0, None)).tolist()


def _body_solids(buoy: RenderedBuoy) -> list[_Solid]:
    """The body in its colour bands; stripes round it for `vertical_stripes`."""
    h, r = buoy.height_m, buoy.diameter_m / 2
    outlines: dict[str, Outline] = {
        "can": ([0.0, h], [r, r]),
        "spar": ([0.0, h], [r, 0.7 * r]),
        "cone": ([0.0, h], [r, 0.05 * r]),
        "pillar": ([0.0, 0.3 * h, 0.42 * h, h], [r, r, 0.4 * r, 0.3 * r]),  # a float, then a tapering tower
    }
    heights, radii = outlines[buoy.shape] if buoy.shape != "sphere" else _sphere_outline(2 * r, h)
    bands = list(buoy.bands)[::-1]  # bottom first
    if buoy.vertical_stripes:
        return [s._replace(stripes=tuple(bands)) for s in _profile_solids((heights, radii), bands[0])]
    edges = np.linspace(0.0, h, len(bands) + 1)
    solids = []
    for rgb, (low, high) in zip(bands, itertools.pairwise(edges.tolist()), strict=True):
        knots = [low, *(z for z in heights if low < z < high), high]
        solids += _profile_solids((knots, np.interp(knots, heights, radii).tolist()), rgb)
    return solids


def _topmark_solids(buoy: RenderedBuoy, base: float, size: float) -> list[_Solid]:
    """The topmark's shapes stacked from `base` (m above the waterline), each `size` or so across."""
    up: Outline = ([0.0, 0.85 * size], [size / 2, 0.0])
    down: Outline = ([0.0, 0.85 * size], [0.0, size / 2])
    can: Outline = ([0.0, 0.8 * size], [0.4 * size, 0.4 * size])
    stacks: dict[str, list[Outline]] = {
        "can": [can],
        "cone": [up],
        "cones_up": [up, up],
        "cones_down": [down, down],
        "cones_base_to_base": [down, up],
        "cones_point_to_point": [up, down],
        "sphere": [_sphere_outline(size)],
        "two_spheres": [_sphere_outline(0.8 * size)] * 2,
    }
    solids: list[_Solid] = []
    for outline in stacks.get(buoy.topmark, []):
        solids += _profile_solids(outline, buoy.topmark_rgb, base)
        base += outline[0][-1] + 0.12 * size
    return solids


def _clip_below(solid: _Solid, hidden: float) -> _Solid | None:
    """The part of a frustum above height `hidden` (what the Earth's curvature leaves in view), or None."""
    if solid.z1 <= hidden:
        return None
    if solid.z0 >= hidden:
        return solid
    radius = solid.r0 + (solid.r1 - solid.r0) * (hidden - solid.z0) / (solid.z1 - solid.z0)
    return solid._replace(z0=hidden, r0=radius)


def _convex_hull(points: np.ndarray) -> list[tuple[float, float]]:
    """Andrew's monotone chain. A frustum is the convex hull of its end circles, and so is its image."""
    ordered = sorted(map(tuple, points.tolist()))

    def half(chain_points: Sequence[tuple[float, float]]) -> list[tuple[float, float]]:
        chain: list[tuple[float, float]] = []
        for p in chain_points:
            while len(chain) >= 2 and (
                (chain[-1][0] - chain[-2][0]) * (p[1] - chain[-2][1])
                - (chain[-1][1] - chain[-2][1]) * (p[0] - chain[-2][0])
                <= 0
            ):
                chain.pop()
            chain.append(p)
        return chain[:-1]

    return half(ordered) + half(ordered[::-1])


def _draw_buoy(
    draw: ImageDraw.ImageDraw, pose: CameraPose, intrinsics: Intrinsics, scene: Scene, buoy: RenderedBuoy, rng_m: float
) -> None:
    """Body, stripes, mast, topmark and light of one buoy, each part's polygon the image of its 3-D outline."""
    camera_height = pose.height_m
    size = max(0.25, 0.45 * buoy.diameter_m)  # topmark
    lantern = buoy.height_m + LANTERN_RADIUS_M
    topmark_base = buoy.height_m + 0.3 + 0.3 * size
    solids = _body_solids(buoy) + _topmark_solids(buoy, topmark_base, size)
    if buoy.topmark != "none":
        mast = max(0.03, 0.04 * buoy.diameter_m)
        solids.append(_Solid(buoy.height_m, topmark_base, mast, mast, MAST_RGB))
    top = max([s.z1 for s in solids] + [topmark_base + size])
    horizon = math.sqrt(2 * EARTH_RADIUS_M * camera_height)
    if rng_m > horizon + math.sqrt(2 * EARTH_RADIUS_M * top):
        return
    hidden = max(0.0, rng_m - horizon) ** 2 / (2 * EARTH_RADIUS_M)  # height of the buoy below the horizon
    sink = rng_m**2 / (2 * EARTH_RADIUS_M)  # the sea surface's drop below the camera's tangent plane
    haze = 1 - math.exp(-rng_m / scene.visibility_m)

    def hazy(rgb: RGB) -> RGB:
        r, g, b = (round(c + (f - c) * haze) for c, f in zip(rgb, scene.sea_far_rgb, strict=True))
        return r, g, b

    centre = np.array(buoy.position_ne, dtype=float)
    to_camera = np.array(pose.position_ned[:2]) - centre
    bearing = math.atan2(to_camera[1], to_camera[0])

    def pixels(heights: np.ndarray, radii: np.ndarray, ring_angles: np.ndarray) -> np.ndarray | None:
        """Images of the points at (height, radius, angle) round the axis; None if any is behind the camera."""
        points = np.column_stack(
            (
                centre[0] + radii * np.cos(ring_angles),
                centre[1] + radii * np.sin(ring_angles),
                sink - heights,
            )
        )
        image, _ = project(pose, intrinsics, points)
        return None if np.isnan(image).any() else image

    # Along the stack, the part nearer the camera's height hides the others' end faces: paint it last.
    visible = [s for s in (_clip_below(s, hidden) for s in solids) if s is not None]
    for solid in sorted(visible, key=lambda s: -abs((s.z0 + s.z1) / 2 - camera_height)):
        sides = _polygon_sides(intrinsics.fx * max(solid.r0, solid.r1) / max(rng_m, 1e-3))
        angles = np.linspace(0.0, 2 * math.pi, sides, endpoint=False)
        ends = np.repeat([[solid.z0, solid.r0], [solid.z1, solid.r1]], sides, axis=0)
        outline = pixels(ends[:, 0], ends[:, 1], np.tile(angles, 2))
        if outline is None:
            continue
        draw.polygon(_convex_hull(outline), fill=hazy(solid.rgb))
        for sector in range(8 if solid.stripes else 0):
            rgb = solid.stripes[sector % len(solid.stripes)]
            arc = np.linspace(sector, sector + 1, 6) * (2 * math.pi / 8)
            # The side faces the camera where its normal points within the tangent angle of the camera.
            arc = arc[np.cos(arc - bearing) * rng_m > max(solid.r0, solid.r1)]
            if rgb == solid.rgb or len(arc) < 2:
                continue
            n = len(arc)
            heights = np.repeat([solid.z0, solid.z1], n)
            quad = pixels(heights, np.repeat([solid.r0, solid.r1], n), np.concatenate((arc, arc[::-1])))
            if quad is not None:
                draw.polygon([tuple(p) for p in quad.tolist()], fill=hazy(rgb))
    if buoy.topmark == "x" and topmark_base + size / 2 > hidden:
        across = np.array([-math.sin(bearing), math.cos(bearing)])  # horizontal, square to the line of sight
        for slope in (1.0, -1.0):
            # A bar from corner to corner of the size x size square, 0.15 size thick, in the picture plane.
            s, t = size / 2, 0.075 * size
            corners = np.array([[-s - t, -s * slope], [-s + t, -s * slope], [s + t, s * slope], [s - t, s * slope]])
            ne = centre + corners[:, :1] * across
            down = sink - (topmark_base + s + corners[:, 1])
            bar, _ = project(pose, intrinsics, np.column_stack((ne, down)))
            if not np.isnan(bar).any():
                draw.polygon([tuple(p) for p in bar.tolist()], fill=hazy(buoy.topmark_rgb))
    if buoy.light_rgb is not None and lantern > hidden:
        light = pixels(np.array([lantern]), np.zeros(1), np.zeros(1))
        if light is not None:
            core = max(MIN_LIGHT_RADIUS_PX, intrinsics.fx * LANTERN_RADIUS_M / max(rng_m, 1e-3))
            _draw_light(draw, light[0], core, buoy.light_rgb)


def _polygon_sides(radius_px: float) -> int:
    """Sides of the regular polygon drawn for a circle: they stray r (1 - cos(pi / n)) from it, <= RING_ERROR_PX."""
    return min(32, max(8, math.ceil(math.pi / math.acos(max(0.0, 1 - RING_ERROR_PX / max(radius_px, 1e-9))))))


def _draw_light(draw: ImageDraw.ImageDraw, centre: np.ndarray, core: float, rgb: RGB) -> None:
    """A lit lamp: a halo of translucent discs, a saturated core of `core` px radius, a white-hot centre."""
    u, v = centre
    for scale, alpha in ((3.0, 70), (2.2, 70), (1.6, 70), (1.0, 255), (1 / 3, 255)):
        # The lamp itself saturates the sensor: the white centre tells it from paint of its colour.
        fill = (255, 255, 255, 255) if scale < 1 else (*rgb, alpha)
        draw.ellipse((u - scale * core, v - scale * core, u + scale * core, v + scale * core), fill=fill)
