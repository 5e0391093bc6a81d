"""Finding one charted buoy in a camera frame: where it floats, what colours its body shows, and its lantern's spot.
Pure computation (numpy, scipy.ndimage, scikit-image).

The buoy is looked for where it can be: within its swing circle, or off station by up to
SearchTolerance.swing_radii of them, plus the chart's and the camera's position errors; the window is that sea
circle's image widened by the attitude error. In it, regions of the kind's paints (paint_segmentation) that hold
one of its saturated colours are the candidates; the one whose waterline lies nearest the charted position wins.

Its waterline pixel is the bottom centre of its region: the near edge of the body's base circle, which is on the
sea. That pixel's ray meets the sea (camera_geometry.pixel_to_sea_ne) at the near edge, a radius short of the
buoy's centre along the line of sight: the centre is that point pushed one base radius further away.

A body cut by the frame's left or right edge (a buoy far off station lies at the edge of a frame aimed at its
charted position) has no bottom centre in view, but its lowest row and the side still in view fix it: the base
circle (its known diameter) is placed on the sea where it would show that lowest row and that side
(_placed_from_uncut_side), to a few tenths of a metre while half its width is in view (with less, the lowest row
in view is no longer the near edge's, and it is not placed); its colours are not read (a band
cut short reads as missing), its light only while the lantern is in the frame. One cut by the bottom edge, or by
both sides, has no waterline; nor are its colours or its light read, since neither where its body ends nor where
its lantern is can be told.
"""

from __future__ import annotations

import itertools
import math
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np
from scipy import ndimage

from gcs.domain.camera_geometry import (
    CameraModel,
    FrameGeotag,
    lat_lon_to_ne,
    ne_to_lat_lon,
    ned_to_pixel,
    pixel_to_sea_ne,
)
from gcs.domain.light_reading import LightSpot, measure_spot
from gcs.domain.paint_segmentation import SATURATED, paint_boxes, paint_labels, to_lab
from uavcore.buoy_world import Appearance, appearance

SEAM_ROWS = 5  # rows of a band seam closed (JPEG's 8 x 8 blocks, chroma at half resolution)
MIN_REGION_PX = 15  # a buoy 1.2 m wide at 60 m is still ~12 x 15 px at the default camera's 960 px
BOTTOM_ROW_SHARE = 0.5  # the waterline row: the lowest whose width is at least this share of the widest
BAND_MIN_SHARE = 0.12  # a colour band: at least this share of the body's rows (JPEG blurs the edges between)
LANTERN_ABOVE_BODY_M = 0.1  # the renderer's (and a typical buoy's) lantern centre above the body's top
LANTERN_RADIUS_M = 0.1
MIN_LANTERN_PX = 2.5


class ChartedBuoy(NamedTuple):
    """A buoy as the chart gives it: position (deg), IALA kind, light (chart text, None: unlit), swing radius, and
    the IALA region its lateral colours follow."""

    lat: float
    lon: float
    kind: str
    light: str | None
    swing_radius_m: float
    region: str = "A"


@dataclass(frozen=True)
class SearchTolerance:
    """How far from its charted position a buoy is looked for, and the camera's errors that widen the window."""

    swing_radii: float = 6.0  # off station by up to this many swing radii is still found (and reported)
    position_m: float = 3.0  # chart and camera position errors together
    attitude_deg: float = 2.0  # the gimbal's reported attitude

    def radius_m(self, charted: ChartedBuoy) -> float:
        return self.swing_radii * charted.swing_radius_m + self.position_m


@dataclass(frozen=True)
class BuoyDetection:
    """One frame's finding of the buoy. `why` says what was found or why not; a buoy cut by the frame's edge is
    found (colours, light) but has no waterline (its bottom centre is not seen)."""

    found: bool
    why: str
    waterline_px: tuple[float, float] | None = None
    position: tuple[float, float] | None = None  # (lat, lon) of the waterline centre
    distance_m: float | None = None  # of the waterline centre from the charted position
    colours: tuple[str, ...] = ()  # body colours seen, top to bottom (vertical stripes: the kind's order)
    light: LightSpot | None = None
    cut: bool = False  # cut by the frame's side: placed from the side in view (module docstring)


@dataclass(frozen=True)
class _Candidate:
    mask: np.ndarray  # the region within its box
    box: tuple[slice, slice]  # frame rows, columns
    labels: np.ndarray  # paint_labels within the box
    bottom_centre: tuple[float, float]  # (u, v) frame pixels (of the part in view, for a body cut by the edge)
    cut: bool  # cut by the frame's left or right edge
    clipped: bool  # cut by the frame's bottom edge or by both sides, or not placed from its side: no waterline
    near_edge_ne: np.ndarray | None  # the base circle's near edge on the sea, NE m from the camera's foot


def search_window(
    model: CameraModel, geotag: FrameGeotag, charted: ChartedBuoy, tolerance: SearchTolerance
) -> tuple[slice, slice] | None:
    """Frame rows and columns where the buoy may show (module docstring); None when none is in the frame."""
    look = appearance(charted.kind, charted.region)
    centre = lat_lon_to_ne(geotag, charted.lat, charted.lon)
    radius = tolerance.radius_m(charted)
    if np.hypot(*centre) <= radius:
        return slice(0, model.height_px), slice(0, model.width_px)  # the camera is inside the circle
    angles = np.linspace(0.0, 2 * math.pi, 24, endpoint=False)
    ring = centre + radius * np.column_stack((np.cos(angles), np.sin(angles)))
    projected = [
        ned_to_pixel(model, geotag, (*point, -height)) for point in ring for height in (0.0, 2 * look.height_m)
    ]
    pixels = [p for p in projected if p is not None]  # the body, its topmark and its light
    if not pixels:
        return None  # the whole area is behind the camera
    if len(pixels) < len(projected):  # partly behind: its image is unbounded, it may show anywhere
        return slice(0, model.height_px), slice(0, model.width_px)
    u, v = np.array(pixels).T
    margin = model.fx * math.tan(math.radians(tolerance.attitude_deg))
    left, right = max(0, int(u.min() - margin)), min(model.width_px, math.ceil(u.max() + margin) + 1)
    top, bottom = max(0, int(v.min() - margin)), min(model.height_px, math.ceil(v.max() + margin) + 1)
    return (slice(top, bottom), slice(left, right)) if left < right and top < bottom else None


def _bottom_centre(mask: np.ndarray, lab: np.ndarray) -> tuple[float, float]:
    """(u, v) within the mask's box of its waterline (module docstring): the lowest row at least BOTTOM_ROW_SHARE
    as wide as the widest (a speck of sea stuck below does not count), the mean centre of the rows a sixth of the
    height above it, and the edge placed to a fraction of a pixel (_edge_row)."""
    widths = mask.sum(axis=1)
    rows = np.flatnonzero(widths >= BOTTOM_ROW_SHARE * widths.max())
    bottom = int(rows[-1])
    span = rows[rows >= bottom - max(1, len(widths) // 6)]
    u = float(np.mean([np.flatnonzero(mask[r]).mean() for r in span]))
    return u, _edge_row(lab, round(u), bottom)


def _edge_row(lab: np.ndarray, column: int, bottom: int) -> float:
    """Where, between paint and sea, the body's lower edge crosses column (lab: the box's CIELAB with rows below).

    A row the edge crosses shows paint and sea mixed in proportion to its coverage (and JPEG spreads the mix over
    a row or two): the edge lies where the colour is halfway from the paint (two rows above the last paint row) to
    the sea (three below), read along the paint-to-sea colour difference and interpolated between rows."""
    columns = slice(max(0, column - 1), column + 2)
    if bottom < 2 or bottom + 3 >= lab.shape[0]:
        return bottom + 0.5  # no sea below in view: the last row's lower edge
    paint, sea = lab[bottom - 2, columns].mean(axis=0), lab[bottom + 3, columns].mean(axis=0)
    step = sea - paint
    if float(step @ step) < 100.0:  # paint and sea alike (under 10 CIELAB units apart): nothing to interpolate
        return bottom + 0.5
    rows = np.arange(bottom - 2, bottom + 4)
    share = (lab[rows, columns].mean(axis=1) - paint) @ step / float(step @ step)  # 0 paint .. 1 sea
    share = np.maximum.accumulate(share)  # monotone, so that np.interp is defined
    return float(np.interp(0.5, share, rows)) if share[-1] > share[0] else bottom + 0.5


def _placed_from_uncut_side(
    model: CameraModel, geotag: FrameGeotag, radius_m: float, side: int, inner_u: float, bottom_v: float
) -> np.ndarray | None:
    """The near edge (NE m from the camera's foot) of a body cut by the frame's left (side -1) or right (+1) edge.

    Two things are seen: inner_u, the column of its silhouette's side in view (the base circle is the body's
    widest part for every shape here), and bottom_v, its lowest row in view. The base circle's centre on the sea is
    the point whose projected circle shows both (its lowest point among those in the frame, its extreme column on
    the side in view): two equations in two unknowns, solved by Newton's method from the guess one radius beyond
    the ray through (inner_u, bottom_v). None if the body is not in front of the camera, the solution fails, or
    less than half its width is in view (bottom_v, measured as for a whole body, then misleads)."""
    start = pixel_to_sea_ne(model, geotag, inner_u + side * 0.5, bottom_v)
    if start is None:
        return None
    angles = np.linspace(0.0, 2 * math.pi, 72, endpoint=False)
    circle = radius_m * np.column_stack((np.cos(angles), np.sin(angles)))
    measured = np.array([inner_u, bottom_v])

    def outline(centre: np.ndarray) -> np.ndarray | None:
        """The base circle's pixels (N x 2), None if part of it is behind the camera."""
        pixels = [ned_to_pixel(model, geotag, (*point, 0.0)) for point in centre + circle]
        return None if any(p is None for p in pixels) else np.array(pixels)

    def seen(centre: np.ndarray) -> np.ndarray | None:
        pixels = outline(centre)
        if pixels is None:
            return None
        u, v = pixels.T
        in_view = (u >= -0.5) & (u < model.width_px - 0.5)
        lowest = v[in_view].max() if in_view.any() else v.max()
        return np.array([u.min() if side > 0 else u.max(), lowest])

    centre = centre_from_near_edge(start, radius_m)
    step_m = 0.01
    for _ in range(6):
        predicted = seen(centre)
        columns = [seen(centre + step_m * axis) for axis in np.eye(2)]
        if predicted is None or columns[0] is None or columns[1] is None:
            return None
        jacobian = np.column_stack([(columns[0] - predicted) / step_m, (columns[1] - predicted) / step_m])
        try:
            move = np.linalg.solve(jacobian, measured - predicted)
        except np.linalg.LinAlgError:
            return None
        centre = centre + np.clip(move, -2 * radius_m, 2 * radius_m)  # a bad guess far off does not run away
        if np.hypot(*move) < 0.005:
            break
    distance = float(np.hypot(*centre))
    pixels = outline(centre)
    if distance <= radius_m or pixels is None:
        return None
    in_view = inner_u + 0.5 if side < 0 else model.width_px - 0.5 - inner_u
    if in_view < 0.5 * float(np.ptp(pixels[:, 0])):
        return None  # less than half of it in view: its lowest row in view is no longer its near edge's
    return centre * (1 - radius_m / distance)


def _candidates(
    image: np.ndarray, model: CameraModel, geotag: FrameGeotag, look: Appearance, window: tuple[slice, slice]
) -> list[_Candidate]:
    """Regions of the kind's paints holding one of its saturated colours, in the window."""
    colours = look.colours
    anchors = [k + 1 for k, name in enumerate(colours) if name in SATURATED]
    found = []
    for top, bottom, left, right in _merged(_widened(paint_boxes(image[window], MIN_REGION_PX // 3), model, window)):
        lab = to_lab(image[top:bottom, left:right])
        labels = paint_labels(lab, colours)
        # JPEG blends the edge between two bands into a row or two of neither colour: close such seams
        painted = ndimage.binary_closing(labels > 0, structure=np.ones((SEAM_ROWS, 1)), border_value=0) | (labels > 0)
        regions, _ = ndimage.label(painted, structure=np.ones((3, 3)))
        for index, (sub_box) in enumerate(ndimage.find_objects(regions), start=1):
            mask = regions[sub_box] == index
            if mask.sum() < MIN_REGION_PX or not np.isin(labels[sub_box][mask], anchors).any():
                continue
            frame_box = (
                slice(top + sub_box[0].start, top + sub_box[0].stop),
                slice(left + sub_box[1].start, left + sub_box[1].stop),
            )
            below = slice(sub_box[0].start, min(lab.shape[0], sub_box[0].stop + 4))
            u, v = _bottom_centre(mask, lab[below, sub_box[1]])
            u, v = u + frame_box[1].start, v + frame_box[0].start
            cut_left, cut_right = frame_box[1].start == 0, frame_box[1].stop == model.width_px
            clipped = frame_box[0].stop == model.height_px or (cut_left and cut_right)
            near_edge = pixel_to_sea_ne(model, geotag, u, v)
            if not clipped and (cut_left or cut_right):
                in_view = np.flatnonzero(mask.any(axis=0)) + frame_box[1].start
                inner_u = in_view.max() + 0.5 if cut_left else in_view.min() - 0.5  # the pixel's outer side
                side = -1 if cut_left else 1
                placed = _placed_from_uncut_side(model, geotag, look.diameter_m / 2, side, inner_u, v)
                clipped = placed is None  # then the part in view still ranks it (its near edge is roughly right)
                near_edge = near_edge if placed is None else placed
            cut = cut_left or cut_right
            found.append(_Candidate(mask, frame_box, labels[sub_box], (u, v), cut, clipped, near_edge))
    return _unique(found)


def _widened(
    boxes: list[tuple[slice, slice]], model: CameraModel, window: tuple[slice, slice]
) -> list[tuple[int, int, int, int]]:
    """Each blob's box (window coordinates) widened by its size, in frame (top, bottom, left, right): a neutral band
    (black, white) as tall as the saturated one may lie beside it."""
    rows, columns = window
    widened = []
    for box in boxes:
        reach = int(1.3 * max(box[0].stop - box[0].start, box[1].stop - box[1].start)) + 3
        widened.append((
            max(0, rows.start + box[0].start - reach),
            min(model.height_px, rows.start + box[0].stop + reach),
            max(0, columns.start + box[1].start - reach),
            min(model.width_px, columns.start + box[1].stop + reach),
        ))  # fmt: skip
    return widened


def _merged(boxes: list[tuple[int, int, int, int]]) -> list[tuple[int, int, int, int]]:
    """Overlapping boxes joined into their bounding box, until none overlap: a buoy's bands are blobs of their
    own, and each region is then segmented once, not once per blob that reaches it."""
    merged = list(boxes)
    joined = True
    while joined:
        joined = False
        for i, j in itertools.combinations(range(len(merged)), 2):
            a, b = merged[i], merged[j]
            if a[0] < b[1] and b[0] < a[1] and a[2] < b[3] and b[2] < a[3]:
                merged[i] = (min(a[0], b[0]), max(a[1], b[1]), min(a[2], b[2]), max(a[3], b[3]))
                del merged[j]
                joined = True
                break
    return merged


def _unique(candidates: list[_Candidate]) -> list[_Candidate]:
    """One candidate per region (the boxes of neighbouring blobs overlap, and find the same region twice)."""
    seen: set[tuple[int, int]] = set()
    unique = []
    for candidate in candidates:
        key = (round(candidate.bottom_centre[0]), round(candidate.bottom_centre[1]))
        if key not in seen:
            seen.add(key)
            unique.append(candidate)
    return unique


def centre_from_near_edge(near_edge_ne: np.ndarray, radius_m: float) -> np.ndarray:
    """The base circle's centre: one radius beyond its near edge, along the horizontal line of sight."""
    return near_edge_ne * (1 + radius_m / np.hypot(*near_edge_ne))


def _band_colours(candidate: _Candidate, look: Appearance, body_top_v: float) -> tuple[str, ...]:
    """The body's colours top to bottom: each row's most common paint, in runs of BAND_MIN_SHARE of the rows or
    more (the topmark, above the body's top, left out); for vertical stripes the kind's colours that show."""
    first_row = max(0, round(body_top_v) - candidate.box[0].start)
    labels = np.where(candidate.mask, candidate.labels, 0)[first_row:]
    painted = labels[(labels > 0).any(axis=1)]
    if not len(painted):
        return ()
    counts = np.stack([(painted == k + 1).sum(axis=1) for k in range(len(look.colours))], axis=1)
    if look.pattern == "vertical":
        share = counts.sum(axis=0) / counts.sum()
        return tuple(name for name, s in zip(look.colours, share, strict=True) if s >= BAND_MIN_SHARE)
    row_colour = counts.argmax(axis=1)
    change = np.flatnonzero(np.diff(row_colour)) + 1
    runs = [
        (int(row_colour[start]), end - start)
        for start, end in zip((0, *change), (*change, len(row_colour)), strict=True)
    ]
    bands: list[int] = []
    for colour, length in runs:
        if length >= BAND_MIN_SHARE * len(row_colour) and (not bands or bands[-1] != colour):
            bands.append(colour)
    return tuple(look.colours[k] for k in bands)


def detect_buoy(
    image: np.ndarray,
    model: CameraModel,
    geotag: FrameGeotag,
    charted: ChartedBuoy,
    tolerance: SearchTolerance | None = None,
) -> BuoyDetection:
    """The charted buoy in one frame (H, W, 3 sRGB uint8): BuoyDetection, found or not and why."""
    tolerance = tolerance or SearchTolerance()
    look = appearance(charted.kind, charted.region)
    window = search_window(model, geotag, charted, tolerance)
    on_station = SearchTolerance(1.0, tolerance.position_m, tolerance.attitude_deg)
    if window is None or search_window(model, geotag, charted, on_station) is None:  # not even its swing circle
        return BuoyDetection(False, "out_of_view: the buoy's swing circle is outside the frame")
    candidates = _candidates(image, model, geotag, look, window)
    if not candidates:
        return BuoyDetection(False, f"no_candidate: no region of {'/'.join(look.colours)} paint in the search area")
    charted_ne = lat_lon_to_ne(geotag, charted.lat, charted.lon)
    radius = look.diameter_m / 2

    def distance(candidate: _Candidate) -> float:
        if candidate.near_edge_ne is None:
            return math.inf
        return float(np.hypot(*(centre_from_near_edge(candidate.near_edge_ne, radius) - charted_ne)))

    best = min(candidates, key=distance)
    if distance(best) > tolerance.radius_m(charted):
        return BuoyDetection(
            False, f"too_far: the nearest {'/'.join(look.colours)} region is {distance(best):.0f} m from the chart"
        )
    if best.clipped or best.near_edge_ne is None:
        return BuoyDetection(True, "clipped: the frame's edge cuts the body: no waterline")
    centre = centre_from_near_edge(best.near_edge_ne, radius)
    light = None
    body_top = ned_to_pixel(model, geotag, (*centre, -look.height_m))
    lantern = ned_to_pixel(model, geotag, (*centre, -(look.height_m + LANTERN_ABOVE_BODY_M)))
    if lantern is not None and body_top is not None:
        core = max(MIN_LANTERN_PX, model.fx * LANTERN_RADIUS_M / float(np.hypot(*centre)))
        spot = 2 * core + 3
        if spot - 0.5 <= lantern[0] <= model.width_px - 0.5 - spot:  # a lamp cut by the frame's side may read dark
            light = measure_spot(image, lantern, spot, body_top[1])
    if best.cut:
        return BuoyDetection(
            True, "found: cut by the frame's side, placed from the side in view", None,
            ne_to_lat_lon(geotag, centre), distance(best), (), light, cut=True,
        )  # fmt: skip
    colours = _band_colours(best, look, body_top[1] if body_top else best.box[0].start)
    return BuoyDetection(
        True,
        "found",
        best.bottom_centre,
        ne_to_lat_lon(geotag, centre),
        distance(best),
        colours,
        light,
    )
